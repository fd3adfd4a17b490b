"""A chunk's output frames, gathered on the device and copied to the host in blocks.

Each written frame's centerline, surface points, normals and extents are stored by a kernel
(:func:`warp_tube.kernels.frame_store.store_scaled_kernel`, dividing by the stage's metres per
unit as ``Simulation`` does on the host) into a device buffer of frames. On a CUDA device the
buffer holds a window of frames and is copied to the host arrays in one transfer when full (no
per-frame copies, no per-frame host arithmetic); on the CPU the buffer is the host arrays
themselves.

Host arrays (float32, stage units), for ``F`` written frames and ``W`` worlds, as
:func:`warp_tube.batch.engine.chunk_shapes` gives them: ``centerline`` (F, W, N, 3); ``points``,
``normals`` (F, W, V, 3); ``extent`` (F, W, prims, 2, 3).
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ..kernels.frame_store import store_scaled_kernel

__all__ = ["FrameStore", "WINDOW_BYTES"]

#: device memory a window of frames may take on a CUDA device [bytes]
WINDOW_BYTES = 2 << 30


class FrameStore:
    """Output frames of a chunk.

    Args:
        arrays: the host arrays by name (see the module docstring), float32, C-contiguous.
        device: the Warp device the chunk runs on.
        window_bytes: on CUDA, device memory for frames [bytes] (at least one frame is kept).
    """

    def __init__(self, arrays: dict, device, window_bytes: int = WINDOW_BYTES):
        self.device = wp.get_device(device)
        self.frames = next(iter(arrays.values())).shape[0]
        self.host = {}
        for name, a in arrays.items():
            if a.dtype != np.float32 or not a.flags.c_contiguous or a.shape[-1] != 3:
                raise ValueError(f"output array {name}: expected C-contiguous float32 (..., 3), got {a.dtype} {a.shape}")
            self.host[name] = wp.array(a, dtype=wp.vec3, device="cpu", copy=False)  # a view: no copy
        self._keep = arrays  # the views hold no reference of their own
        if self.device.is_cpu:
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
            for name, buf in self.buffers.items():
                wp.copy(self.host[name][self.start : self.start + self.count], buf[: self.count])
            wp.synchronize_device(self.device)
        self.start += self.count
        self.count = 0
