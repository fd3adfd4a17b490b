"""Progress bars of a batch on a terminal (tqdm): reading the variants, then variant-frames
simulated, with the variants written so far."""

from __future__ import annotations

__all__ = ["Progress"]


class Progress:
    """Progress bars on a terminal: reading the variants, then variant-frames simulated."""

    def __init__(self, on: bool):
        self.on = on
        self.bar = None
        self.read_bar = None
        self.total_variants = 0
        self.done_variants = 0

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
        self.total_variants, self.done_variants = variants, done
        if self.on:
            from tqdm import tqdm

            self.bar = tqdm(total=frames_total, desc="simulating", unit="frame", unit_scale=True, leave=False)
            self._postfix()

    def frames(self, n: int):
        if self.bar is not None:
            self.bar.update(n)

    def variants_done(self, n: int):
        self.done_variants += n
        self._postfix()

    def _postfix(self):
        if self.bar is not None:
            self.bar.set_postfix_str(f"variants written {self.done_variants}/{self.total_variants}")

    def close(self):
        self.close_reading()
        if self.bar is not None:
            self.bar.close()
            self.bar = None
