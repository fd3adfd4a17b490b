"""Signs of life for phases that can take long: a status line on a terminal, refreshed every second.

:class:`Phase` writes ``<what> ... 12 s`` on stderr while a block runs, starting only after
``after`` seconds so that quick phases print nothing, and clears the line when the block ends.
:class:`Heartbeat` calls a function every second from a background thread (used to keep a progress
bar's clock moving while one long frame runs). Where stderr is not a terminal (a log file, a job
scheduler), :class:`PlainProgress` writes a plain line with the estimate of the time left every
:data:`PLAIN_INTERVAL` seconds instead of a bar. Kernel launches and NumPy release Python's lock, and
Python code yields it every few milliseconds, so the thread runs during every phase.
"""

from __future__ import annotations

import os
import sys
import threading
import time

#: seconds [s] between two lines of :class:`PlainProgress`.
PLAIN_INTERVAL = 30.0

__all__ = ["Phase", "Heartbeat", "PlainProgress", "frame_bar", "format_seconds", "stderr_is_terminal"]


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


def frame_bar(total: int):
    """A tqdm bar on stderr over ``total`` frames, counting the first as done (started after it: its
    rate and estimate leave the start-up out), and a started :class:`Heartbeat` that keeps its clock
    moving through long frames; returns ``(bar, heartbeat)``."""
    from tqdm import tqdm

    try:  # a terminal that reports no size (some consoles and ptys): tqdm would draw nothing
        size = os.get_terminal_size(sys.stderr.fileno())
        known = size.columns > 0 and size.lines > 0
    except (OSError, ValueError, AttributeError):
        known = False
    bar = tqdm(total=total, initial=1, unit="frame", desc="simulating", leave=False, file=sys.stderr,
               **({} if known else {"ncols": 80, "nrows": 20}))  # fmt: skip
    beat = Heartbeat(bar.refresh)
    beat.__enter__()
    return bar, beat


class PlainProgress:
    """Progress of a run as plain lines, for a stderr that is not a terminal: called as
    ``progress(done, total)`` after each frame (see :meth:`Simulation.run
    <warp_tube.sim.simulation.Simulation.run>`), it writes ``warp-tube: simulating: 600 of 2,000
    frames (30%), 1.0 min so far, about 2.3 min left`` at most every ``interval`` seconds [s]. The
    estimate is taken from the first call on (the start-up, kernel compilation, left out).

    Args:
        interval: seconds between two lines [s] (default :data:`PLAIN_INTERVAL`).
        stream: where to write (default: ``sys.stderr`` at each line).
        clock: the time [s] (``time.monotonic``; a test may give its own).
        what: what is counted, after ``warp-tube:`` (a batch: ``batch``).
        unit: what ``done`` and ``total`` count (a batch: ``variant-frames``).
    """

    def __init__(self, interval: float | None = None, stream=None, clock=time.monotonic, what: str = "simulating",
                 unit: str = "frames"):  # fmt: skip
        self.interval = PLAIN_INTERVAL if interval is None else interval
        self.stream, self.clock = stream, clock
        self.what, self.unit = what, unit
        self._t0 = self._first = self._last = None

    def __call__(self, done: int, total: int, note: str = "") -> None:
        """Count ``done`` of ``total``; ``note`` (e.g. ``3 of 16 variants written``) follows the
        percentage in a line."""
        now = self.clock()
        if self._t0 is None:
            self._t0, self._first, self._last = now, done, now
            return
        if now - self._last < self.interval or done >= total:
            return
        self._last = now
        rate = (done - self._first) / (now - self._t0) if now > self._t0 else 0.0
        left = f", about {format_seconds((total - done) / rate)} left" if rate > 0 else ""
        note = f", {note}" if note else ""
        print(f"warp-tube: {self.what}: {done:,} of {total:,} {self.unit} ({100 * done // max(total, 1)}%){note}, "
              f"{format_seconds(now - self._t0)} so far{left}", file=self.stream or sys.stderr, flush=True)  # fmt: skip
