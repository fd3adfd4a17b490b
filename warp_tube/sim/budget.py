"""What a run will cost and whether it can be done, decided before it starts; and the checks of
:meth:`Simulation.run <warp_tube.sim.simulation.Simulation.run>`'s and the constructor's arguments.

- Time: a run estimated to take longer than :data:`LONG_RUN_SECONDS` is announced with its
  estimate and why.
- Memory: usd-core holds a stage's samples until it is saved, so an output larger than the memory
  available (with :data:`OUTPUT_MEMORY_FACTOR`) is refused, as is one larger than the free space
  of the folder it goes to (it would run to its end and then fail to save, keeping nothing).
"""

from __future__ import annotations

import logging
import numbers
import os

from ..centerline.policy import IMPLICIT_COST_RATIO
from ..scene.spec import SceneError

log = logging.getLogger("warp_tube.sim.simulation")

__all__ = ["RunBudget", "CPU_SEMI_STEP_COST", "CPU_SUBSTEP_COST", "OUTPUT_MEMORY_FACTOR", "LARGE_OUTPUT_BYTES", "LONG_RUN_SECONDS",
           "OUTPUT_FIXED_BYTES", "OUTPUT_PRIM_BYTES", "OUTPUT_SAMPLE_BYTES", "TEXT_OUTPUT_FACTOR", "whole_number",
           "check_world_count"]  # fmt: skip

#: CPU cost of one semi-implicit substep [s]: :data:`CPU_SUBSTEP_COST` and this per centerline point,
#: for the up-front estimate of a long run only (implicit substeps cost IMPLICIT_COST_RATIO times
#: more); benchmarks/bench_estimates.py measures them (2-core CPU, 2026-11-27: a straight tube with
#: gravity 1.6 / 7.8 / 66 / 648 us a substep at 21 / 201 / 2,001 / 20,001 points, 32-40 ns a point
#: past 200; the default scene's 21 points with their assistant line 3.8 us). A single cost per
#: point, 0.15 us, had a 20,000-point run announced at 2.4 min that took 52 s.
CPU_SEMI_STEP_COST = 0.04e-6
#: CPU cost of a substep whatever its points [s] (its launch and the tube's loop): see above.
CPU_SUBSTEP_COST = 2e-6
#: a run's memory over its output's samples (usd-core's layer, the simulation, the frame being
#: written): measured 2.7-3.8x on the CPU for outputs of 0.5-2 GB, a 0.3 GB process included.
OUTPUT_MEMORY_FACTOR = 2.5
#: a run whose output is estimated to hold more than this [bytes] is announced before it starts.
LARGE_OUTPUT_BYTES = 4e9
#: a run estimated to take longer than this [s] is announced with its estimate before it starts.
LONG_RUN_SECONDS = 60.0
#: An output file's size is bounded by :meth:`RunBudget.output_file_bytes`: its arrays at their
#: uncompressed sizes (usd-core compresses the integer ones: the default scene's 34.6 kB of topology
#: and texture coordinates take ~22 kB), and these. Measured with usd-core 26.11 (crate files):
#: the layer's metadata and root [bytes] (a one-prim output without samples: ~1.1 kB) ...
OUTPUT_FIXED_BYTES = 4096
#: ... a tube prim's prims and attribute specs (200 prims without a Surface: ~27 kB; a Surface's
#: specs add ~0.3 kB) ...
OUTPUT_PRIM_BYTES = 1024
#: ... and a time sample's time and value reference beside its values (~20-28 bytes).
OUTPUT_SAMPLE_BYTES = 32
#: a text stage (.usda) over a crate file of the same content: measured 2.6-3.1x for the samples,
#: 1.5-2.1x for the topology.
TEXT_OUTPUT_FACTOR = 3.5


def whole_number(name: str, value) -> int:
    """``value`` as an int where it is a whole number (an int, a NumPy integer, or a float such as
    ``48.0``); a bool, a string, a fraction or anything else is a :class:`SceneError` naming ``name``."""
    if isinstance(value, numbers.Integral) and not isinstance(value, bool):
        return int(value)
    if isinstance(value, numbers.Real) and not isinstance(value, bool) and float(value).is_integer():
        return int(value)
    raise SceneError(f"{name} {value!r}: expected a whole number")


def check_world_count(world_count) -> int:
    """The ``world_count`` of a Simulation: a whole number of at least 1 (a :class:`ValueError` otherwise)."""
    n = whole_number("world_count", world_count)
    if n < 1:
        raise SceneError(f"world_count {n}: expected at least 1 (copies of the scene run side by side)")
    return n


class RunBudget:
    """Estimates and up-front checks of a :class:`~warp_tube.sim.simulation.Simulation`'s run (a mixin:
    reads ``scene``, ``model``, ``surfaces``, ``substeps``, ``integrator``, ``device`` and ``reason``)."""

    def estimated_seconds(self, frames: int) -> float:
        """Rough time [s] to simulate ``frames`` frames: substeps x (a cost per substep and one per
        point: :data:`CPU_SUBSTEP_COST`, :data:`CPU_SEMI_STEP_COST`; x :data:`IMPLICIT_COST_RATIO` for
        implicit Euler). On CUDA, where points run in parallel, 10 us per substep at the least."""
        per_step = CPU_SUBSTEP_COST + self.model.node_count * self.model.world_count * CPU_SEMI_STEP_COST
        if self.integrator == "implicitEuler":
            per_step *= IMPLICIT_COST_RATIO
        if self.device != "cpu":
            per_step = max(per_step / 1000.0, 10e-6)
        return frames * self.substeps * per_step

    def _announce_long_run(self, frames: int) -> None:
        """Warn before a run that will take long, with the estimate and why."""
        seconds = self.estimated_seconds(frames)
        if seconds < LONG_RUN_SECONDS:
            return
        from ..runtime.progress import format_seconds

        log.warning(
            "this run will take about %s: %s frames x %s substeps a frame (%s) x %s points; --frames N runs fewer frames",
            format_seconds(seconds), f"{frames:,}", f"{self.substeps:,}", self.reason, f"{self.model.node_count:,}",
        )  # fmt: skip

    def output_bytes_per_frame(self) -> int:
        """Bytes a written frame adds to the output (float32 centerline points, and surface points
        and normals)."""
        vertices = sum(b.vertex_count for b in self.surfaces) if self.surfaces else 0
        return 12 * (self.model.node_count + 2 * vertices)

    def output_file_bytes(self, output=None) -> tuple[int, int]:
        """An upper bound of the output file's size [bytes]: ``(fixed, per_frame)``, the part
        written once (metadata, prim specs, widths, curve counts, the Surfaces' topology and
        texture coordinates) and what each frame adds (:meth:`output_bytes_per_frame`, each
        Centerline's and Surface's extent and every sample's bookkeeping), for a text stage when
        ``output`` ends in ``.usda``."""
        tubes, surfaces = self.scene.tubes, self.surfaces or ()
        arrays = sum(4 * (len(t.points) + len(t.curve_counts)) for t in tubes)  # float32 widths, int32 counts
        for s in surfaces:
            st_indices = getattr(s, "st_indices", None)
            arrays += 4 * (len(s.face_vertex_counts) + len(s.face_vertex_indices)) + 8 * len(s.st)
            arrays += 4 * len(st_indices) if st_indices is not None else 0
        samples = self.output_bytes_per_frame() + 24 * (len(tubes) + len(surfaces))  # (and each Centerline's and Surface's extent)
        if output is not None and os.fspath(output).lower().endswith(".usda"):
            arrays, samples = int(arrays * TEXT_OUTPUT_FACTOR), int(samples * TEXT_OUTPUT_FACTOR)
        fixed = OUTPUT_FIXED_BYTES + len(tubes) * OUTPUT_PRIM_BYTES + arrays
        return fixed, samples + (2 * len(tubes) + 3 * len(surfaces)) * OUTPUT_SAMPLE_BYTES

    def _check_output_fits(self, frames: int, output=None) -> None:
        """Refuse, before anything is written, an output larger than the memory available now
        (usd-core holds a stage's samples in memory until it is saved, so such a run would end
        killed by the system with nothing saved), or than the free space of ``output``'s folder
        (the run would go to its end and fail to save)."""
        from ..runtime import memory

        per_frame = self.output_bytes_per_frame()
        size, free = frames * per_frame, memory.available_memory()
        if free is not None and OUTPUT_MEMORY_FACTOR * size > free:
            raise SceneError(
                f"the output would hold about {_size(size)} ({frames:,} frames x {per_frame:,} bytes), "
                f"and a run holds ~{OUTPUT_MEMORY_FACTOR:g}x that while usd-core keeps it until the run ends: more than the "
                f"{_size(free)} of memory available; --every K or --frames N write fewer frames"
            )  # fmt: skip
        if output is None:
            return
        folder = os.path.dirname(os.path.abspath(os.fspath(output)))
        disk = memory.available_disk(folder)
        if disk is None:
            return
        fixed, per_frame = self.output_file_bytes(output)
        size = fixed + frames * per_frame
        if size > disk:
            fewer = "" if fixed > disk else ", or write fewer frames (--every K, --frames N)"
            raise SceneError(
                f"{output}: the output would take about {_size(size)} ({frames:,} frames x {per_frame:,} bytes, and {fixed:,} "
                f"bytes of topology and metadata), more than the {_size(disk)} free in {folder}; free some space{fewer}"
            )  # fmt: skip

    def _announce_large_output(self, frames: int) -> None:
        """Warn before a run whose output gets large (usd-core holds it in memory until it is saved)."""
        size = frames * self.output_bytes_per_frame()
        if size < LARGE_OUTPUT_BYTES:
            return
        log.warning(
            "the output will hold about %.1f GB (%s frames x %s bytes), kept in memory until the run ends; "
            "--every K or --frames N write fewer frames", size / 1e9, f"{frames:,}", f"{self.output_bytes_per_frame():,}",
        )  # fmt: skip


def _size(n: float) -> str:
    """A size [bytes] in words: ``10.0 kB``, ``3.2 MB``, ``1.5 GB``, ``44,400 TB``."""
    if n >= 1e12:
        return f"{n / 1e12:,.0f} TB" if n >= 1e14 else f"{n / 1e12:.1f} TB"
    if n >= 1e9:
        return f"{n / 1e9:.1f} GB"
    return f"{n / 1e6:.1f} MB" if n >= 1e6 else f"{n / 1e3:.1f} kB"
