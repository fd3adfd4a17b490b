"""Ctrl-C that is not lost.

Python raises ``KeyboardInterrupt`` wherever the main thread happens to be when SIGINT arrives.
Inside a finalizer (``__del__``, e.g. of a Warp array being freed) the exception is printed as
"Exception ignored in ..." and dropped, and a run would go on as if nothing happened. While
:func:`kept_interrupts` is active, SIGINT also sets a flag, and :func:`raise_if_interrupted`,
called between frames and between a batch's chunks, raises the interrupt that was dropped.

SIGTERM and SIGHUP (``timeout``, a job scheduler, a closed terminal) stop a command the same way
while :func:`terminate_as_interrupt` is active: they raise :class:`Terminated`, a
``KeyboardInterrupt``, so a run keeps its finished frames and removes its temporary file as after
Ctrl-C; :func:`exit_status` gives 128 + the signal's number.

A save that is under way is not thrown away by Ctrl-C: usd-core's save is native code, so the
interrupt is raised when it returns, in the middle of putting the file in place, and the finished
file would be removed. :func:`deferred_interrupts` holds these signals back over such a block.
:func:`held_interrupts` does the same for the short blocks a run enters each frame (counting a
frame and handing it to the writer), at a fraction of the cost.
"""

from __future__ import annotations

import contextlib
import signal
import threading

__all__ = ["kept_interrupts", "raise_if_interrupted", "terminate_as_interrupt", "deferred_interrupts", "held_interrupts",
           "import_whole", "Terminated", "exit_status", "stopped_by", "interrupt_received", "interrupt_for"]  # fmt: skip

_pending = None  # the signal (SIGINT, SIGTERM, SIGHUP) that arrived and may not have been delivered
_received = None  # the last signal that arrived since kept_interrupts began, delivered or not
_holding = 0  # held_interrupts blocks open in the main thread: this module's handlers only note the signal


class Terminated(KeyboardInterrupt):
    """SIGTERM or SIGHUP, raised where the main thread is, as Ctrl-C is.

    Attributes:
        signum: the signal's number.
    """

    def __init__(self, signum: int):
        super().__init__(signal.Signals(signum).name)
        self.signum = int(signum)


def exit_status(e: BaseException) -> int:
    """The exit status of a command stopped by ``e``: 128 + the signal's number (130 for Ctrl-C)."""
    return 128 + int(getattr(e, "signum", signal.SIGINT))


def stopped_by(e: BaseException) -> str:
    """How a command stopped by ``e`` (an interrupt carrying ``signum``, or Ctrl-C) says it
    stopped: ``interrupted`` or ``terminated (SIGTERM)``."""
    signum = int(getattr(e, "signum", signal.SIGINT))
    return "interrupted" if signum == signal.SIGINT else f"terminated ({signal.Signals(signum).name})"


def interrupt_for(signum: int) -> KeyboardInterrupt:
    """The exception a command stops by for ``signum``: KeyboardInterrupt for SIGINT, else :class:`Terminated`."""
    return KeyboardInterrupt() if signum == signal.SIGINT else Terminated(signum)


def _on_sigint(signum, frame):
    global _pending, _received
    _pending = _received = signum
    if not _holding:
        raise KeyboardInterrupt


def _on_terminate(signum, frame):
    global _pending, _received
    _pending = _received = signum
    if not _holding:
        raise Terminated(signum)


_TERMINATING = tuple(getattr(signal, name) for name in ("SIGTERM", "SIGHUP") if hasattr(signal, name))


@contextlib.contextmanager
def terminate_as_interrupt():
    """SIGTERM and SIGHUP raise :class:`Terminated` in the main thread (where their handlers are
    the default; a program with its own keeps them)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = {}
    for sig in _TERMINATING:
        if signal.getsignal(sig) is signal.SIG_DFL:
            old[sig] = signal.signal(sig, _on_terminate)
    try:
        yield
    finally:
        for sig, handler in old.items():
            signal.signal(sig, handler)


@contextlib.contextmanager
def kept_interrupts():
    """SIGINT remembered until :func:`raise_if_interrupted` (in the main thread, and only where
    Python's own handler is installed: a program with its own handler keeps it)."""
    global _pending, _received
    if threading.current_thread() is not threading.main_thread() or signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
        yield
        return
    _pending = _received = None
    signal.signal(signal.SIGINT, _on_sigint)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, signal.default_int_handler)
        _pending = None


def raise_if_interrupted() -> None:
    """Raise ``KeyboardInterrupt`` (:class:`Terminated` for SIGTERM or SIGHUP) if the signal arrived
    since the last call (or since :func:`kept_interrupts` began) and may have been dropped."""
    global _pending
    if _pending is not None:
        signum, _pending = _pending, None
        raise interrupt_for(signum)


def interrupt_received() -> int | None:
    """The signal (SIGINT, SIGTERM, SIGHUP) that arrived since :func:`kept_interrupts` last began,
    raised or not, or None: a command whose worker processes fail after it (the signal reached them
    too) tells the user's stop from a failure by it. It stays after the block, for the caller that
    reports how the command ended."""
    return _received


def _defer(signum, frame):
    global _pending, _received
    _pending = _received = signum


@contextlib.contextmanager
def deferred_interrupts():
    """SIGINT (and SIGTERM and SIGHUP where :func:`terminate_as_interrupt` handles them) remembered
    but not raised in the block, in the main thread, where Python's or this module's handler is
    installed (a program's own handler is left alone).

    Yields:
        a list that, after the block, holds the number of the signal that arrived in it (empty if none).
    """
    global _pending
    got = []
    if threading.current_thread() is not threading.main_thread():
        yield got
        return
    old = {}
    for sig in (signal.SIGINT, *_TERMINATING):
        if signal.getsignal(sig) in (signal.default_int_handler, _on_sigint, _on_terminate):
            old[sig] = signal.signal(sig, _defer)
    before, _pending = _pending, None
    try:
        yield got
    finally:
        for sig, handler in old.items():
            signal.signal(sig, handler)
        if _pending is not None:
            got.append(_pending)
        _pending = before


class held_interrupts:
    """SIGINT, SIGTERM and SIGHUP noted but not raised inside the block, and raised at its end (a
    block left by an exception leaves it pending for :func:`raise_if_interrupted`).

    Only where this module's handlers are installed (:func:`kept_interrupts`,
    :func:`terminate_as_interrupt`), in the main thread. Entering costs well under a microsecond,
    where :func:`deferred_interrupts` swaps the handlers (~35 us): a run holds each frame's counting
    and writing, so that a frame is in the summary and the output both or in neither.
    """

    def __enter__(self):
        global _holding
        self._main = threading.current_thread() is threading.main_thread()
        if self._main:
            _holding += 1
        return self

    def __exit__(self, exc_type, exc, tb):
        global _holding
        if self._main:
            _holding -= 1
            if exc_type is None and not _holding:
                raise_if_interrupted()
        return False


def import_whole(*modules: str) -> None:
    """Import ``modules`` with interrupts held back until they are in: a Ctrl-C in the middle of
    usd-core's import left its Python bindings half registered (later calls failed with "No
    to_python converter", or the command ran on and exited 0), so the interrupt is raised after the
    import, as if it had come just then."""
    import importlib

    with deferred_interrupts() as got:
        for name in modules:
            importlib.import_module(name)
    if got:
        raise interrupt_for(got[0])
