"""A chunk's output frames, gathered on the device and copied to the host in blocks.

Each written frame's centerline, surface points, normals and extents are stored by a kernel
(:func:`warp_tube.kernels.frame_store.store_scaled_kernel`, dividing by the stage's metres per
unit as ``Simulation`` does on the host) into a device buffer of frames. On a CUDA device the
buffer holds a window of frames and is copied to the host arrays when full (no per-frame copies,
no per-frame host arithmetic): in pieces through a page-locked staging buffer, at the bus's
speed, and from there into the host arrays by several threads (a copy from the device straight
into pageable memory ran at 1.5-3 GB/s). On the CPU the buffer is the host arrays themselves.

Host arrays (float32, stage units), for ``F`` written frames and ``W`` worlds, as
:func:`warp_tube.batch.engine.chunk_shapes` gives them: ``centerline`` (F, W, N, 3); ``points``,
``normals`` (F, W, V, 3); ``extent`` (F, W, prims, 2, 3).
"""

from __future__ import annotations

import concurrent.futures as cf
import os

import numpy as np
import warp as wp

from ..kernels.frame_store import store_scaled_kernel

__all__ = ["FrameStore", "WINDOW_BYTES", "STAGING_BYTES"]

#: device memory a window of frames may take on a CUDA device [bytes]
WINDOW_BYTES = 2 << 30
#: page-locked host memory for copying windows back [bytes] (one buffer per process, reused)
STAGING_BYTES = 256 << 20
#: threads copying from the staging buffer into the host arrays
COPY_THREADS = max(1, min(8, (os.cpu_count() or 2) // 2))
#: elements below which a copy is done on one thread
PARALLEL_COPY_MIN = 1 << 20

_staging: dict = {}  # device name -> (Warp host array, its NumPy view)
_copiers = None


def _staging_buffer(device, nbytes: int) -> np.ndarray:
    """This process's staging buffer for ``device`` (page-locked for a CUDA device), at least
    ``nbytes`` long, as uint8."""
    held = _staging.get(str(device))
    if held is None or held[1].size < nbytes:
        _staging.pop(str(device), None)
        arr = wp.empty(nbytes, dtype=wp.uint8, device="cpu", pinned=device.is_cuda)
        held = _staging[str(device)] = (arr, arr.numpy())
    return held[1]


def _parallel_copy(dst: np.ndarray, src: np.ndarray) -> None:
    """``dst[...] = src`` for C-contiguous arrays of one shape, in slices on several threads
    (NumPy releases the GIL for the copy)."""
    global _copiers
    d, s = dst.reshape(-1), src.reshape(-1)
    n = len(d)
    if n < PARALLEL_COPY_MIN or COPY_THREADS == 1:
        d[:] = s
        return
    if _copiers is None:
        _copiers = cf.ThreadPoolExecutor(COPY_THREADS, thread_name_prefix="frame-copy")
    bounds = np.linspace(0, n, COPY_THREADS + 1).astype(np.int64)
    list(_copiers.map(lambda ab: d.__setitem__(slice(ab[0], ab[1]), s[ab[0] : ab[1]]), zip(bounds[:-1], bounds[1:])))


class FrameStore:
    """Output frames of a chunk.

    Args:
        arrays: the host arrays by name (see the module docstring), float32, C-contiguous.
        device: the Warp device the chunk runs on.
        window_bytes: on CUDA, device memory for frames [bytes] (at least one frame is kept).
        staged: keep frames in buffers of their own and copy them back in windows (default: on
            CUDA devices only; on the CPU for tests of the copying).
    """

    def __init__(self, arrays: dict, device, window_bytes: int = WINDOW_BYTES, staged: bool | None = None):
        self.device = wp.get_device(device)
        self.frames = next(iter(arrays.values())).shape[0]
        self.host = {}
        for name, a in arrays.items():
            if a.dtype != np.float32 or not a.flags.c_contiguous or a.shape[-1] != 3:
                raise ValueError(f"output array {name}: expected C-contiguous float32 (..., 3), got {a.dtype} {a.shape}")
            self.host[name] = wp.array(a, dtype=wp.vec3, device="cpu", copy=False)  # a view: no copy
        self._keep = arrays  # the views hold no reference of their own
        if not (self.device.is_cuda if staged is None else staged):
            self.window = self.frames
            self.buffers = self.host
        else:
            per_frame = sum(a[0].nbytes for a in arrays.values())
            self.window = int(max(1, min(self.frames, window_bytes // max(per_frame, 1))))
            self.buffers = {name: wp.empty((self.window,) + h.shape[1:], dtype=wp.vec3, device=self.device)
                            for name, h in self.host.items()}  # fmt: skip
        self.start = 0  # first frame in the window
        self.count = 0  # frames stored in the window

    def _slot(self, frame: int) -> int:
        if frame != self.start + self.count and frame != self.start + self.count - 1:
            raise ValueError(f"frame {frame}: frames are stored in order (next is {self.start + self.count})")
        if frame == self.start + self.count:
            if self.count == self.window:
                self.flush()
            self.count += 1
        return frame - self.start

    def store(self, frame: int, name: str, src: wp.array, unit: float = 1.0, columns: slice | None = None,
              prim: int | None = None) -> None:  # fmt: skip
        """Store ``src / unit`` as frame ``frame`` (written frames in order, 0, 1, ...) of output ``name``.

        Args:
            src: (W, n) vec3 on the device [m, or unitless for normals].
            unit: metres per stage unit (1 for normals).
            columns: the columns of the output this fills (a prim's vertices), or all.
            prim: for ``extent``, the prim whose bounds ``src`` (W, 2) holds.
        """
        out = self.buffers[name][self._slot(frame)]
        if prim is not None:
            out = out[:, prim]
        if columns is not None:
            out = out[:, columns]
        wp.launch(store_scaled_kernel, dim=src.shape, inputs=[src, float(unit), out], device=self.device)

    def flush(self) -> None:
        """Copy the window's stored frames to the host arrays (CUDA; nothing to do on the CPU)."""
        if self.buffers is not self.host and self.count:
            wp.synchronize_device(self.device)
            for name, buf in self.buffers.items():
                frame_bytes = 12 * int(np.prod(buf.shape[1:]))
                step = max(1, STAGING_BYTES // frame_bytes)  # frames per piece
                stage = _staging_buffer(self.device, min(step, self.count) * frame_bytes)
                dst = self._keep[name]
                for a in range(0, self.count, step):
                    b = min(a + step, self.count)
                    view = stage[: (b - a) * frame_bytes].view(np.float32).reshape((b - a,) + dst.shape[1:])
                    wp.copy(wp.array(view, dtype=wp.vec3, device="cpu", copy=False), buf[a:b])
                    wp.synchronize_device(self.device)
                    _parallel_copy(dst[self.start + a : self.start + b], view)
        self.start += self.count
        self.count = 0
