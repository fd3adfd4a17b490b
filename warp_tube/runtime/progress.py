"""Signs of life for phases that can take long: a status line on a terminal, refreshed every second.

:class:`Phase` writes ``<what> ... 12 s`` on stderr while a block runs, starting only after
``after`` seconds so that quick phases print nothing, and clears the line when the block ends.
:class:`Heartbeat` calls a function every second from a background thread (used to keep a progress
bar's clock moving while one long frame runs). Kernel launches and NumPy release Python's lock, and
Python code yields it every few milliseconds, so the thread runs during every phase.
"""

from __future__ import annotations

import sys
import threading
import time

__all__ = ["Phase", "Heartbeat", "format_seconds", "stderr_is_terminal"]


def stderr_is_terminal() -> bool:
    """Whether stderr is a terminal (where status lines and progress bars are shown)."""
    try:
        return sys.stderr.isatty()
    except (AttributeError, ValueError):
        return False


def format_seconds(seconds: float) -> str:
    """``42 s``, ``3.5 min``, ``2.1 h``, ``3.0 days``."""
    if seconds < 90:
        return f"{seconds:.0f} s" if seconds >= 10 else f"{seconds:.1f} s"
    if seconds < 5400:
        return f"{seconds / 60:.1f} min"
    if seconds < 172800:
        return f"{seconds / 3600:.1f} h"
    return f"{seconds / 86400:.1f} days"


class Heartbeat:
    """Call ``beat()`` every ``interval`` seconds [s] from a daemon thread while the block runs."""

    def __init__(self, beat, interval: float = 1.0):
        self._beat = beat
        self._interval = interval
        self._stop = threading.Event()
        self._thread = None

    def _loop(self):
        while not self._stop.wait(self._interval):
            try:
                self._beat()
            except Exception:  # a display problem must never stop the work
                return

    def __enter__(self):
        self._thread = threading.Thread(target=self._loop, name="warp_tube-heartbeat", daemon=True)
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join()
        return False


class Phase:
    """A status line ``what ... elapsed`` on stderr while the block runs (see the module docstring).

    Args:
        what: the phase, e.g. "building the model (1,000,000 points)".
        enabled: show it (default: when stderr is a terminal).
        after: seconds [s] before the line first appears.
    """

    def __init__(self, what: str, enabled: bool | None = None, after: float = 1.0):
        self.what = what
        self.enabled = stderr_is_terminal() if enabled is None else bool(enabled)
        self.after = after
        self._t0 = 0.0
        self._shown = False
        self._lock = threading.Lock()
        self._heartbeat = None

    def _draw(self):
        elapsed = time.perf_counter() - self._t0
        if elapsed < self.after:
            return
        with self._lock:
            sys.stderr.write(f"\r{self.what} ... {format_seconds(elapsed)}\033[K")
            sys.stderr.flush()
            self._shown = True

    def __enter__(self):
        self._t0 = time.perf_counter()
        if self.enabled:
            self._heartbeat = Heartbeat(self._draw, interval=min(self.after, 1.0) if self.after > 0 else 1.0)
            self._heartbeat.__enter__()
        return self

    def __exit__(self, *exc):
        if self._heartbeat is not None:
            self._heartbeat.__exit__(*exc)
            self._heartbeat = None
            with self._lock:
                if self._shown:
                    sys.stderr.write("\r\033[K")
                    sys.stderr.flush()
        return False
