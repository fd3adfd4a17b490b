"""A chunk's output frames, gathered on the device and copied to the host in blocks.

Each written frame's centerline, surface points, normals and extents are stored by a kernel
(:func:`warp_tube.kernels.frame_store.store_scaled_kernel`, dividing by the stage's metres per
unit as ``Simulation`` does on the host) into a device buffer of frames. On a CUDA device the
buffer holds a window of frames and is copied to the host arrays when full (no per-frame copies,
no per-frame host arithmetic): in pieces through a page-locked staging buffer, at the bus's
speed, and from there into the host arrays by several threads (a copy from the device straight
into pageable memory ran at 1.5-3 GB/s). On the CPU the buffer is the host arrays themselves.

The copy back runs on a thread of its own, on a CUDA stream of its own, while the simulation
goes on: a full window is handed over and the frames that follow go into fresh device buffers
(at most :data:`MAX_WINDOWS_IN_FLIGHT` windows of a process wait, over the chunks, and no more
than fit with the window being filled in a quarter of the device's memory; where not even two
fit, the frames wait for each window's copy and go on in the same buffers).
:meth:`FrameStore.finish` returns a future that is done once every frame is in the host arrays;
whoever reads them waits for it.

Host arrays (float32, stage units), for ``F`` written frames and ``W`` worlds, as
:func:`warp_tube.batch.engine.chunk_shapes` gives them: ``centerline`` (F, W, N, 3); ``points``,
``normals`` (F, W, V, 3); ``extent`` (F, W, prims, 2, 3).
"""

from __future__ import annotations

import collections
import concurrent.futures as cf
import os
import threading
import time

import numpy as np
import warp as wp

from ..kernels.frame_store import store_scaled_kernel
from ..runtime.replay import CAPTURE_LOCK

__all__ = ["FrameStore", "WINDOW_BYTES", "STAGING_BYTES", "done_future", "release_windows", "prepare_copies"]

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
_flusher = None  # the thread that copies windows back, one per process (it owns the staging buffers)
_flush_streams: dict = {}  # device name -> the CUDA stream the copies back run on
#: windows handed over and not yet copied back, at most (a quarter of the device's memory at most:
#: on an 80 GB GPU 9 windows of 2 GB). With 3 the simulation of 16,384 variants waited 0.4-0.9 s for
#: the copies back on an H100 while USD writers shared the host's memory; with 8, not at all.
MAX_WINDOWS_IN_FLIGHT = 8
_in_flight: collections.deque = collections.deque()  # their futures, oldest first (one copying thread: in order)
#: windows' device buffers kept, once copied back, for the windows that follow (per device and
#: shapes, at most this many sets each): a fresh 2 GB window took 3-18 ms to allocate on an H200,
#: 0.03-0.14 s of a 16,384-variant batch's host time
FREE_WINDOWS_KEPT = 2
_free_windows: dict = {}  # (device name, ((output, shape), ...)) -> [buffers by output, ...]
_free_lock = threading.Lock()


def _flush_thread() -> cf.ThreadPoolExecutor:
    global _flusher
    if _flusher is None:
        _flusher = cf.ThreadPoolExecutor(1, thread_name_prefix="frame-flush")
    return _flusher


def _copy_stream(device) -> wp.Stream:
    """A CUDA stream for copying frames back that does not block the legacy default stream:
    ``wp.array.numpy()`` copies on that stream, which waits for every blocking stream, so the
    simulation's small per-frame reads would otherwise wait for pieces of a window being copied.
    Created through the driver (Warp's own streams are blocking); a Warp stream where that fails."""
    import ctypes

    try:
        lib = ctypes.CDLL("libcuda.so.1")
        handle, popped = ctypes.c_void_p(), ctypes.c_void_p()
        if lib.cuCtxPushCurrent_v2(ctypes.c_void_p(device.context)) != 0:
            raise OSError("cuCtxPushCurrent failed")
        try:
            rc = lib.cuStreamCreate(ctypes.byref(handle), ctypes.c_uint(1))  # CU_STREAM_NON_BLOCKING
        finally:
            lib.cuCtxPopCurrent_v2(ctypes.byref(popped))
        if rc != 0 or not handle.value:
            raise OSError(f"cuStreamCreate returned {rc}")
        return wp.Stream(device, cuda_stream=handle.value)
    except (OSError, AttributeError):
        return wp.Stream(device)


def _window_key(device, shapes: dict) -> tuple:
    return str(device), tuple((name, tuple(shape)) for name, shape in shapes.items())


def _window_buffers(device, shapes: dict) -> dict:
    """Device buffers of a window, by output (``shapes``: output -> (window, W, n)): a set kept
    from an earlier window of these shapes, or new ones."""
    with _free_lock:
        free = _free_windows.get(_window_key(device, shapes))
        if free:
            return free.pop()
    return {name: wp.empty(shape, dtype=wp.vec3, device=device) for name, shape in shapes.items()}


def _keep_window(device, buffers: dict) -> None:
    """Keep ``buffers``, a window copied back and no longer written, for a later window."""
    with _free_lock:
        free = _free_windows.setdefault(_window_key(device, {n: b.shape for n, b in buffers.items()}), [])
        if len(free) < FREE_WINDOWS_KEPT:
            free.append(buffers)


def release_windows() -> None:
    """Drop the windows' buffers kept for reuse (:data:`FREE_WINDOWS_KEPT`), once every window
    handed over is copied back: their device memory goes back to Warp's pool (at a batch's end)."""
    while _in_flight:
        _in_flight.popleft().exception()
    with _free_lock:
        _free_windows.clear()


def _window_memory(device) -> float:
    """Device memory the windows of frames may take [bytes]: a quarter of the device's."""
    return 0.25 * (device.total_memory or 0)


def done_future(value=None) -> cf.Future:
    """A future that is already done (with ``value``)."""
    f = cf.Future()
    f.set_result(value)
    return f


def prepare_copies(device) -> None:
    """Set up the copying thread for ``device`` ahead of the first window (a CUDA device; nothing
    on the CPU): its stream and its page-locked staging buffer, on that thread, while the caller
    goes on (reading the variants). Allocating the staging buffer took 0.13-0.16 s on an H200 host,
    and the simulating thread waited for it at the first window's hand-over."""
    device = wp.get_device(device)
    if not device.is_cuda:
        return

    def prepare() -> None:
        with CAPTURE_LOCK:
            if str(device) not in _flush_streams:
                _flush_streams[str(device)] = _copy_stream(device)
        _staging_buffer(device, STAGING_BYTES)

    _flush_thread().submit(prepare)  # (the windows' copies, on the same thread, come after it)


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
        window_bytes: on CUDA, device memory for a window of frames [bytes] (at least one frame is
            kept; default :data:`WINDOW_BYTES`).
        staged: keep frames in buffers of their own and copy them back in windows (default: on
            CUDA devices only; on the CPU for tests of the copying).
    """

    def __init__(self, arrays: dict, device, window_bytes: int | None = None, staged: bool | None = None):
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
            window_bytes = WINDOW_BYTES if window_bytes is None else window_bytes
            self.window = int(max(1, min(self.frames, window_bytes // max(per_frame, 1))))
            self.buffers = _window_buffers(self.device, {name: (self.window,) + h.shape[1:] for name, h in self.host.items()})
        self._launches: dict = {}  # recorded store launches (see store)
        #: seconds the frames waited for earlier windows' copies back (device memory held by them)
        self.waited_s = 0.0
        self.start = 0  # first frame in the window
        self.count = 0  # frames stored in the window
        self.pending = done_future()  # the copy back of the last window handed over

    def _slot(self, frame: int) -> int:
        if frame != self.start + self.count and frame != self.start + self.count - 1:
            raise ValueError(f"frame {frame}: frames are stored in order (next is {self.start + self.count})")
        if frame == self.start + self.count:
            if self.count == self.window:
                self.hand_over()
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
        slot = self._slot(frame)  # (first: it may start a new window, with new buffers)
        buf = self.buffers[name]
        # One recorded launch per output, source and window (the frame's slot a parameter of it);
        # the launch holds the arrays, so their addresses identify them while it is kept.
        key = (name, src.ptr, buf.ptr, columns.start if columns is not None else None, prim, float(unit))
        launch = self._launches.get(key)
        if launch is None:
            W = buf.shape[1]
            out = buf.reshape((buf.shape[0], W, -1))  # (window, W, columns) (extent: the prims' corners)
            first = 2 * prim if prim is not None else (columns.start or 0) if columns is not None else 0
            width = (columns.stop - first) if columns is not None and columns.stop is not None else src.shape[1]
            if src.shape[0] != W or src.shape[1] != width or first + width > out.shape[2]:
                raise ValueError(f"output {name}: {src.shape} does not fit columns {first}.. of {out.shape[1:]}")
            if len(self._launches) > 64:
                self._launches.clear()
            launch = self._launches[key] = wp.launch(store_scaled_kernel, dim=src.shape, device=self.device, record_cmd=True,
                                                     inputs=[src, float(unit), out, slot, first])  # fmt: skip
        launch.set_param_at_index(3, slot)
        launch.launch()

    def flush(self) -> None:
        """Copy the window's stored frames to the host arrays and wait until they are there."""
        self.hand_over()
        self.pending.result()

    def finish(self) -> cf.Future:
        """Hand the last window over; the returned future is done (or raises the copy's error)
        once every stored frame is in the host arrays."""
        self.hand_over()
        return self.pending

    def hand_over(self) -> None:
        """Give the window to the copying thread and start a new one (CUDA; on the CPU the
        frames are already in the host arrays)."""
        if self.buffers is self.host or not self.count:
            self.start += self.count
            self.count = 0
            return
        # Windows waiting to be copied back, besides the one being filled, within a quarter of the
        # device's memory; none (copied back before the frames go on, in the same buffers) where
        # even one does not fit.
        window_bytes = sum(b.capacity for b in self.buffers.values())
        fit = int(_window_memory(self.device) // max(window_bytes, 1)) - 1
        limit = max(1, min(MAX_WINDOWS_IN_FLIGHT, fit))
        t = time.perf_counter()
        while len(_in_flight) >= limit:  # device memory held by windows not yet copied back
            _in_flight.popleft().exception()  # waits; a failed copy is reported by its own chunk's future
        self.waited_s += time.perf_counter() - t
        # on the stream that stored the frames: this device's current one (not the default device's)
        event = wp.get_stream(self.device).record_event() if self.device.is_cuda else None
        more = self.start + self.count < self.frames  # frames to come
        # (the window is kept for others once copied back, unless its frames go on in it)
        job = (self.buffers, self.start, self.count, event, fit >= 1 or not more)
        self.pending = _flush_thread().submit(self._copy_back, *job)
        _in_flight.append(self.pending)
        self.start += self.count
        self.count = 0
        if more:
            if fit < 1:  # no room for a second window: the frames wait for this one's copy
                t = time.perf_counter()
                self.pending.exception()
                self.waited_s += time.perf_counter() - t
            else:  # other buffers (the handed-over ones are being read; the launches held them)
                self._launches.clear()
                self.buffers = _window_buffers(self.device, {name: buf.shape for name, buf in self.buffers.items()})

    def _copy_back(self, buffers: dict, start: int, count: int, event, keep: bool) -> None:
        """On the copying thread: ``count`` frames of ``buffers`` into the host arrays from frame
        ``start``, on this thread's stream, in pieces through the two halves of the staging
        buffer: while one piece is copied from the device into one half, the other half's piece
        goes on into the host arrays. ``keep``: then keep ``buffers`` for later windows."""
        stream = None
        if self.device.is_cuda:
            with CAPTURE_LOCK:  # (every call into Warp on the device: not while a graph is captured)
                stream = _flush_streams.get(str(self.device))
                if stream is None:
                    stream = _flush_streams[str(self.device)] = _copy_stream(self.device)
                stream.wait_event(event)
        half = STAGING_BYTES // 2
        pieces = []  # (output name, first frame, end frame) of each piece
        for name, buf in buffers.items():
            frame_bytes = 12 * int(np.prod(buf.shape[1:]))
            step = max(1, half // frame_bytes)  # frames per piece
            pieces += [(name, a, min(a + step, count)) for a in range(0, count, step)]
        size = max(12 * (b - a) * int(np.prod(buffers[name].shape[1:])) for name, a, b in pieces)
        stage = _staging_buffer(self.device, 2 * size)
        halves = (stage[:size], stage[size : 2 * size])

        def fetch(k: int):
            """Start copying piece ``k`` into its half; returns the half's view and an event (CUDA)."""
            name, a, b = pieces[k]
            dst = self._keep[name]
            view = halves[k % 2][: (b - a) * dst[0].nbytes].view(np.float32).reshape((b - a,) + dst.shape[1:])
            with CAPTURE_LOCK:
                wp.copy(wp.array(view, dtype=wp.vec3, device="cpu", copy=False), buffers[name][a:b], stream=stream)
                return view, (stream.record_event() if stream is not None else None)

        pending = fetch(0)
        for k, (name, a, b) in enumerate(pieces):
            view, done = pending
            if k + 1 < len(pieces):  # the other half is free: its last piece went on at step k - 1
                pending = fetch(k + 1)
            if done is not None:
                with CAPTURE_LOCK:
                    wp.synchronize_event(done)
            _parallel_copy(self._keep[name][start + a : start + b], view)
        if keep:  # (every piece is off the device: the buffers may be written again)
            _keep_window(self.device, buffers)
