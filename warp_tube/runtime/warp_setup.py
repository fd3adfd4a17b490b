"""Warp started quietly: no banner, no module-load lines, no missing-CUDA-driver line unless asked.

Warp prints a banner and a line per module load at its default log level, and its native library
prints "Warp CUDA warning: Could not find or load the NVIDIA CUDA driver" on every machine without
a GPU. :func:`init_warp` initialises Warp once with its log level at warnings and that one native
line dropped (other native output of the start-up is passed on). It is called wherever warp_tube
first needs Warp (``Simulation``, extraction, preview).

Asking for the messages: ``warp-tube -v``, :func:`set_verbose`, or ``WARP_TUBE_VERBOSE=1`` in the
environment. A program that initialises Warp itself before using warp_tube keeps Warp's own
settings, and a log level set in ``warp.config`` other than Warp's default is left alone.

Every call also flushes subnormal floats to zero on the calling thread (:mod:`.float_mode`): Warp
runs CPU kernels on the thread that launches them, and a settled tube's subnormal velocities would
otherwise slow them down several times.
"""

from __future__ import annotations

import os
import sys

__all__ = ["init_warp", "set_verbose", "env_verbose", "VERBOSE_ENV"]

VERBOSE_ENV = "WARP_TUBE_VERBOSE"
#: the native start-up line that :func:`init_warp` drops unless verbose.
MISSING_DRIVER = "Could not find or load the NVIDIA CUDA driver"

_verbose: bool | None = None


def set_verbose(flag: bool) -> None:
    """Show (True) or hide (False) Warp's start-up and module-load messages from now on."""
    global _verbose
    _verbose = bool(flag)
    if "warp" in sys.modules and _warp_started():
        wp = sys.modules["warp"]
        wp.config.log_level = wp.LOG_INFO if flag else wp.LOG_WARNING


def env_verbose() -> bool:
    """Whether the environment asks for Warp's messages (:data:`VERBOSE_ENV` set, not 0/false/no)."""
    return os.environ.get(VERBOSE_ENV, "").strip().lower() not in ("", "0", "false", "no")


def _is_verbose() -> bool:
    if _verbose is not None:
        return _verbose
    return env_verbose()


def _warp_started() -> bool:
    """Whether Warp's runtime exists (initialised by us, by the user, or by a first Warp call)."""
    try:
        from warp._src import context
    except ImportError:  # another Warp layout: assume not started; init is idempotent anyway
        return False
    return getattr(context, "runtime", None) is not None


def init_warp() -> None:
    """Initialise Warp if it is not yet, quietly unless verbose (see the module docstring), and
    flush subnormals to zero on the calling thread (:mod:`.float_mode`; once per thread)."""
    from .float_mode import flush_subnormals_on_this_thread

    if not _warp_started():
        _start_warp()
    flush_subnormals_on_this_thread()


def _start_warp() -> None:
    import warp as wp

    if _is_verbose():
        wp.config.log_level = wp.LOG_INFO
        wp.init()
        return
    if wp.config.log_level == wp.LOG_INFO:  # Warp's default: nobody asked for its messages
        wp.config.log_level = wp.LOG_WARNING
    _init_without_driver_line(wp)


def _init_without_driver_line(wp) -> None:
    """``wp.init()`` with its native stderr caught; passed on less the missing-driver line."""
    from .native_output import native_stderr

    with native_stderr() as caught:
        wp.init()
    kept = [line for line in caught.lines() if MISSING_DRIVER not in line]
    if kept:
        print("\n".join(kept), file=sys.stderr)
