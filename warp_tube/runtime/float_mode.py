"""Subnormal results flushed to zero on the threads that run Warp's CPU kernels.

A damped tube coming to rest drives its velocities, and position components that rest at 0,
down through the subnormal range of float32 (below 1.18e-38). On x86 every operation on a
subnormal takes a microcode assist, about a hundred times the normal cost, so a long CPU run slows
down several times once the tube has settled (the default scene: 0.15 s per 500 frames while it
moves, 1.8 s once at rest). Values that small are zero for a tube simulation, so
:func:`flush_subnormals_on_this_thread` turns on flush-to-zero for the calling thread on x86-64
(:mod:`warp_tube.kernels.float_mode` says why denormals-are-zero stays off).
:func:`warp_tube.runtime.warp_setup.init_warp` calls it, so every thread that starts Warp through
warp_tube (the main thread of a run, a batch's simulating processes, a Dask worker's thread) runs
its CPU kernels that way.

The mode belongs to the thread: it also applies to NumPy and any other floating-point code that
thread runs afterwards (a result below 1.18e-38 in float32, 2.2e-308 in float64, is 0), threads
started from it afterwards inherit it on Linux, and other threads keep theirs. CUDA kernels are
not affected.
"""

from __future__ import annotations

import logging
import threading

__all__ = ["flush_subnormals_on_this_thread"]

log = logging.getLogger(__name__)


class _ThreadMode(threading.local):
    """Per thread: None until tried, then whether subnormals are flushed on it."""

    flushed: bool | None = None


_mode = _ThreadMode()


def flush_subnormals_on_this_thread() -> bool:
    """Flush subnormal float32/float64 results to zero on the calling thread (x86-64).

    Launches a one-thread Warp kernel on the CPU once per thread (compiled once and cached, a
    few tens of milliseconds the first time); later calls on the same thread return at once.
    Warp must be initialised. Where the mode cannot be set (Warp without its CPU compiler, an
    architecture other than x86-64, a failed compile), nothing changes and a debug line is
    logged.

    Returns:
        Whether subnormals are flushed on this thread.
    """
    if _mode.flushed is None:
        _mode.flushed = _set_mode()
    return _mode.flushed


def _set_mode() -> bool:
    import warp as wp

    if not wp.is_cpu_available():
        log.debug("subnormals not flushed: Warp has no CPU compiler")
        return False
    try:
        from ..kernels.float_mode import flush_subnormals_kernel

        applied = wp.zeros(1, dtype=wp.int32, device="cpu")
        wp.launch(flush_subnormals_kernel, dim=1, inputs=[applied], device="cpu")
        flushed = bool(applied.numpy()[0])
    except Exception as exc:  # Warp raises plain Exception/RuntimeError when a CPU build fails
        log.debug("subnormals not flushed: the mode kernel failed (%s)", exc)
        return False
    if not flushed:
        log.debug("subnormals not flushed: flush-to-zero is set on x86-64 CPUs only")
    return flushed
