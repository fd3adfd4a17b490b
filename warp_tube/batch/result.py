"""What a batch did: :class:`BatchResult`, returned by :func:`warp_tube.batch.run.run_batch` and
printed by ``warp-tube batch``."""

from __future__ import annotations

from dataclasses import dataclass, field

from ..sim.notes import STRAIN_FACTOR
from .engine import TIMERS

__all__ = ["BatchResult"]


@dataclass
class BatchResult:
    """What a batch did.

    Attributes:
        out_dir: the batch folder.
        variants: variants in the batch.
        ok, failed: variants finished in this run (or before, when resuming), by status.
        resumed: variants finished by an earlier run and skipped.
        pending: variants not finished (an interrupted batch).
        groups, chunks: how the variants were run.
        devices: where the chunks ran ("dask" for a cluster).
        wall_s: the whole command [s]; prepare_s: reading and checking the variants and planning;
        simulate_s: simulating (wall, in this process; the sum over workers otherwise);
        write_s: the writer tasks' time, summed over writers; write_wait_s: waiting for writers
            (and for frames to be copied back from the device for them);
        books_s: recording the finished chunks (journal records, summary lines);
        frames: frames written per variant (with ``every``: every K-th of those simulated);
        timings: the simulation's own split (build, kernels, launch, readback, control, checks, copy, rerun), summed.
        failures: (variant name, reason) of the failed variants.
        contacts: (variant name, frame) of the variants where distant parts of their tubes came
            closer than the sum of their radii, at the first such frame (contact is not modelled).
        strained: (variant name, max_stretch) of the variants that had a segment strained, at some
            frame, beyond :data:`~warp_tube.sim.notes.STRAIN_FACTOR` (the springs are linear).
    """

    out_dir: str
    variants: int = 0
    ok: int = 0
    failed: int = 0
    resumed: int = 0
    pending: int = 0
    groups: int = 0
    chunks: int = 0
    devices: list = field(default_factory=list)
    wall_s: float = 0.0
    prepare_s: float = 0.0
    simulate_s: float = 0.0
    write_s: float = 0.0
    write_wait_s: float = 0.0
    books_s: float = 0.0
    frames: int = 0
    timings: dict = field(default_factory=lambda: dict.fromkeys(TIMERS, 0.0))
    failures: list = field(default_factory=list)
    contacts: list = field(default_factory=list)
    strained: list = field(default_factory=list)

    def text(self) -> str:
        t = self.timings
        lines = [
            f"variants     {self.variants} in {self.groups} group(s), {self.chunks} chunk(s) on {_device_list(self.devices)}",
            f"finished     {self.ok} ok, {self.failed} failed" + (f" ({self.resumed} from before)" if self.resumed else ""),
            f"frames       {self.frames} per variant",
            f"wall time    {self.wall_s:.2f} s: reading {self.prepare_s:.2f} s, simulating {self.simulate_s:.2f} s "
            f"(kernels {t['kernels_s']:.2f} s, checks {t['checks_s']:.2f} s), waiting for writers {self.write_wait_s:.2f} s",
            f"output       {self.out_dir}",
        ]  # fmt: skip
        if self.pending:
            lines.append(f"unfinished   {self.pending} variant(s): warp-tube batch ... --resume goes on")
        lines += [f"failed       {name}: {reason}" for name, reason in self.failures[:10]]
        if len(self.failures) > 10:
            lines.append(f"failed       ... and {len(self.failures) - 10} more (summary.csv)")
        if self.contacts:
            name, frame = self.contacts[0]
            lines.append(f"contact      {len(self.contacts)} variant(s): distant parts of their tubes touched (first {name} at "
                         f"frame {frame}); contact is not modelled, they pass through each other (summary.csv: contact_frame)")  # fmt: skip
        if self.strained:
            lines.append(f"strain       {len(self.strained)} variant(s) had a segment beyond {STRAIN_FACTOR:g}x its rest "
                         f"length (first {self.strained[0][0]}: {self.strained[0][1]:.3g}x); the springs are linear, such strains "
                         "are not physical (summary.csv: max_stretch)")  # fmt: skip
        return "\n".join(lines)


def _device_list(devices: list[str]) -> str:
    """``cuda:0, cuda:1`` or, for workers sharing a device, ``cpu x 4``."""
    if len(devices) > 1 and len(set(devices)) == 1:
        return f"{devices[0]} x {len(devices)}"
    return ", ".join(devices) or "-"


def _strained(names, status, stretch) -> list:
    """(name, max_stretch) of the ok variants whose max_stretch passes STRAIN_FACTOR."""
    return [(n, float(x)) for n, s, x in zip(names, status, stretch) if s == "ok" and x not in ("", None) and float(x) > STRAIN_FACTOR]
