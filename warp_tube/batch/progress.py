"""Progress of a batch: on a terminal, bars (tqdm): reading the variants, then variant-frames
simulated, with the variants written so far; elsewhere (a log file), a plain line every
:data:`~warp_tube.runtime.progress.PLAIN_INTERVAL` seconds with the time left, as ``warp-tube run``
writes (:class:`~warp_tube.runtime.progress.PlainProgress`)."""

from __future__ import annotations

__all__ = ["Progress", "LINES"]

#: ``Progress(LINES)``: plain lines, not bars
LINES = "lines"


class Progress:
    """A batch's progress.

    Args:
        on: True for bars on a terminal, :data:`LINES` (``"lines"``) for a plain line every
            ``interval`` seconds (``warp-tube: batch: 1,200 of 6,000 variant-frames (20%), 3 of 16
            variants written, 1.0 min so far, about 4.0 min left``), False for nothing.
        interval: seconds between two lines [s] (default
            :data:`~warp_tube.runtime.progress.PLAIN_INTERVAL`).
        stream: where lines go (default: ``sys.stderr``).
        clock: the time [s] for lines (default ``time.monotonic``; a test may give its own).
    """

    def __init__(self, on, interval: float | None = None, stream=None, clock=None):
        self.on = bool(on) and on != LINES
        self.lines = None
        if on == LINES:
            import time

            from ..runtime.progress import PlainProgress

            self.lines = PlainProgress(interval, stream, clock or time.monotonic, what="batch", unit="variant-frames")
        self.bar = None
        self.read_bar = None
        self.total_variants = 0
        self.done_variants = 0
        self.total_frames = 0
        self.done_frames = 0

    def reading(self, n: int):
        if not self.on:
            return
        if self.read_bar is None:
            from tqdm import tqdm

            self.read_bar = tqdm(desc="reading variants", unit="variant", leave=False)
        self.read_bar.update(n - self.read_bar.n)

    def close_reading(self):
        if self.read_bar is not None:
            self.read_bar.close()
            self.read_bar = None

    def start(self, frames_total: int, variants: int, done: int):
        """The batch's variant-frames to simulate in this run, its variants and those done before."""
        self.total_variants, self.done_variants = variants, done
        self.total_frames, self.done_frames = frames_total, 0
        if self.on:
            from tqdm import tqdm

            self.bar = tqdm(total=frames_total, desc="simulating", unit="frame", unit_scale=True, leave=False)
            self._postfix()
        self._line()  # (the lines' clock starts)

    def frames(self, n: int):
        self.done_frames += n
        if self.bar is not None:
            self.bar.update(n)
        self._line()

    def variants_done(self, n: int):
        self.done_variants += n
        self._postfix()
        self._line()

    def _postfix(self):
        if self.bar is not None:
            self.bar.set_postfix_str(f"variants written {self.done_variants}/{self.total_variants}")

    def _line(self):
        if self.lines is not None and self.total_frames:
            self.lines(self.done_frames, self.total_frames, f"{self.done_variants:,} of {self.total_variants:,} variants written")

    def close(self):
        self.close_reading()
        if self.bar is not None:
            self.bar.close()
            self.bar = None
