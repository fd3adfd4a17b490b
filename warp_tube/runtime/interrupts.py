"""Ctrl-C that is not lost.

Python raises ``KeyboardInterrupt`` wherever the main thread happens to be when SIGINT arrives.
Inside a finalizer (``__del__``, e.g. of a Warp array being freed) the exception is printed as
"Exception ignored in ..." and dropped, and a run would go on as if nothing happened. While
:func:`kept_interrupts` is active, SIGINT also sets a flag, and :func:`raise_if_interrupted`,
called between frames and between a batch's chunks, raises the interrupt that was dropped.
"""

from __future__ import annotations

import contextlib
import signal
import threading

__all__ = ["kept_interrupts", "raise_if_interrupted"]

_pending = False  # a SIGINT arrived that may not have been delivered


def _on_sigint(signum, frame):
    global _pending
    _pending = True
    raise KeyboardInterrupt


@contextlib.contextmanager
def kept_interrupts():
    """SIGINT remembered until :func:`raise_if_interrupted` (in the main thread, and only where
    Python's own handler is installed: a program with its own handler keeps it)."""
    global _pending
    if threading.current_thread() is not threading.main_thread() or signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
        yield
        return
    _pending = False
    signal.signal(signal.SIGINT, _on_sigint)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, signal.default_int_handler)
        _pending = False


def raise_if_interrupted() -> None:
    """Raise ``KeyboardInterrupt`` if a SIGINT arrived since the last call (or since
    :func:`kept_interrupts` began) and may have been dropped."""
    global _pending
    if _pending:
        _pending = False
        raise KeyboardInterrupt
