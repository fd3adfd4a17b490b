"""Replaying a fixed sequence of launches as one captured graph.

A frame launches the same kernels on the same arrays every time. Captured once, it replays with one
call: on CUDA as a CUDA graph (when the device's memory pool makes capture safe), on the CPU through
Warp's recorded-operation replay, which runs the kernels from a native loop without re-packing
their arguments in Python (on the paper's 20-point tube that halves a frame's cost, see
``benchmarks/bench_frame.py``). Where capture is not available the sequence simply runs.
"""

from __future__ import annotations

import contextlib
import functools
import threading

import warp as wp

__all__ = ["GraphCache", "can_capture", "cpu_blocks", "CAPTURE_LOCK", "SIM_LOCK", "holding"]

#: held while a graph is captured: other threads of the process that call into Warp on a device
#: (copying frames back beside the simulation) take it around those calls, since Warp refuses to
#: synchronize with a device while a capture on it is active
CAPTURE_LOCK = threading.Lock()

#: held by a Simulation while it is built and steps, and by a batch while it runs: a capture
#: records every launch and copy on its device, from any thread, so two simulations of one process
#: stepping in two threads corrupted each other's graphs (Warp errors, crashes); they take turns
SIM_LOCK = threading.RLock()


def holding(lock):
    """Decorator: the function runs holding ``lock``."""

    def wrap(fn):
        @functools.wraps(fn)
        def held(*args, **kwargs):
            with lock:
                return fn(*args, **kwargs)

        return held

    return wrap


_cpu_capture = None


def can_capture(device) -> bool:
    """Whether launches on ``device`` can be captured into a replayable graph."""
    global _cpu_capture
    device = wp.get_device(device)
    if device.is_cuda:
        return bool(wp.is_mempool_enabled(device))
    if _cpu_capture is None:
        try:  # CPU capture arrived with Warp's recorded-operation replay; older versions refuse it
            wp.capture_begin(device=device)
            wp.capture_end(device=device)
            _cpu_capture = True
        except Exception:
            _cpu_capture = False
    return _cpu_capture


@contextlib.contextmanager
def cpu_blocks():
    """Launches inside run block kernels (``wp.launch_tiled``) on the CPU with a block's threads as
    Warp's cooperative fibers, an opt-in (``wp.config.enable_cpu_blocks``) that this turns on and
    back to what it was. Slow: for running the GPU's block kernels on the CPU in tests."""
    enabled = wp.config.enable_cpu_blocks
    wp.config.enable_cpu_blocks = True
    try:
        yield
    finally:
        wp.config.enable_cpu_blocks = enabled


class GraphCache:
    """Captured graphs of a launch sequence, one per key (the arrays and values it was captured
    with), at most ``size`` of them.

    The key must name everything the captured launches depend on (array identities, scalar
    arguments); ``hold`` keeps the objects whose ids are in the key alive while their graph is
    cached, so that no new object can take an id over.
    """

    def __init__(self, device, size: int = 16):
        self.device = wp.get_device(device)
        self.size = int(size)
        self.enabled = can_capture(self.device)
        self._graphs = {}
        self._seen = set()

    def run(self, key, launch, hold=()) -> None:
        """Replay the graph for ``key``. The first time a key is seen ``launch()`` (a callable
        issuing the launches) just runs; the second time it is captured, then replayed. Where
        capture is unavailable it always just runs."""
        cached = self._graphs.get(key)
        if cached is not None:
            wp.capture_launch(cached[1])
            return
        if not self.enabled or key not in self._seen:
            # Captured from the second use on: a key used once (a one-off array) costs no capture.
            if len(self._seen) >= 4 * self.size:
                self._seen.clear()
            self._seen.add(key)
            launch()
            return
        with CAPTURE_LOCK, wp.ScopedCapture(device=self.device) as cap:
            launch()
        if len(self._graphs) >= self.size:
            self._graphs.clear()
        self._graphs[key] = (tuple(hold), cap.graph)
        wp.capture_launch(cap.graph)

    def clear(self) -> None:
        """Drop every captured graph (for instance after arrays were reallocated)."""
        self._graphs.clear()
        self._seen.clear()
