"""What a run did: :class:`RunSummary`, returned by :meth:`Simulation.run
<warp_tube.sim.simulation.Simulation.run>` and printed by the command line."""

from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ["RunSummary"]


@dataclass
class RunSummary:
    """What a run did (printed by the CLI).

    Times [s]: ``wall_time`` is the whole run; ``startup_time`` the part up to the end of the
    first simulated frame, which includes compiling the kernels on first use, so the rate
    (:attr:`steps_per_second`) is taken over the frames after it when there are any;
    ``setup_time`` what came before the run's frames: setting up the output file, and what the
    caller adds (the CLI: reading the scene and building the model).
    ``output`` is the complete output (None while the run has not completed); ``partial`` the file
    holding the frames finished by a run that stopped early (None if none was finished); ``notes``
    where the model departs from a plain elastic rod (:func:`warp_tube.sim.notes.model_notes`).
    """

    scene: str
    device: str
    frames: int
    substeps: int
    dt: float
    integrator: str
    reason: str
    wall_time: float
    max_displacement: float
    output: str | None = None
    stopped: str | None = None
    warnings: list = field(default_factory=list)
    stage_defaults: list = field(default_factory=list)
    frames_simulated: int = 0
    substeps_simulated: int = 0
    startup_time: float = 0.0
    startup_substeps: int = 0
    partial: str | None = None
    first_frame: int = 0
    last_frame: int | None = None
    setup_time: float = 0.0
    notes: list = field(default_factory=list)

    @property
    def steps_per_second(self) -> float:
        """Substeps per second after the start-up (over the whole run if it was all start-up)."""
        steps = self.substeps_simulated - self.startup_substeps
        seconds = self.wall_time - self.startup_time
        if steps <= 0 or seconds <= 0:
            steps, seconds = self.substeps_simulated, self.wall_time
        return steps / seconds if seconds > 0 else float("nan")

    @property
    def lost(self) -> bool:
        """Whether the run stopped with frames handed to its output and no file holding them (a
        save that failed)."""
        return bool(self.stopped and self.frames and not self.output and not self.partial)

    def frames_written_text(self) -> str:
        """``frames 0-11 (12 frames)`` for the frames written, or ``no frame``."""
        if self.frames == 0 or self.last_frame is None:
            return "no frame"
        if self.frames == 1:
            return f"frame {self.last_frame} only"
        return f"frames {self.first_frame}-{self.last_frame} ({self.frames} frames)"

    def text(self) -> str:
        steady = self.substeps_simulated > self.startup_substeps and self.wall_time > self.startup_time
        rate = f"{self.steps_per_second:,.0f} substeps/s"
        if steady:
            timing = f"{self.wall_time:.3f} s for the frames (start-up {self.startup_time:.3f} s: kernel compilation and frame 1; then {rate})"
        else:
            timing = f"{self.wall_time:.3f} s for the frames ({rate}, start-up and kernel compilation included)"
        lines = [
            f"scene        {self.scene}",
            f"device       {self.device}",
            f"frames       {self.frames} written ({self.frames_simulated} simulated)" if not self.lost else
            f"frames       none saved ({self.frames_simulated} simulated; {self.frames} could not be saved)",
            f"integrator   {self.integrator}: {self.reason}",
            f"substeps     {self.substeps} per frame, dt = {self.dt:.3g} s",
            *([f"set-up       {self.setup_time:.3f} s (reading the scene, building the model, setting up the output; some kernels compile on a first run)"]
              if self.setup_time > 0.0 else []),
            f"wall time    {timing}",
            f"largest displacement  {self.max_displacement:.4g} m",
        ]
        if self.stage_defaults:
            lines.append("stage        unauthored, taken as: " + ", ".join(self.stage_defaults))
        if self.output:
            lines.append(f"output       {self.output}")
        if self.partial:
            lines.append(f"partial      {self.partial} ({self.frames_written_text()})")
        lines += [f"note         {n}" for n in self.notes]
        lines += [f"warning      {w}" for w in self.warnings]
        if self.stopped:
            lines.append(f"stopped      {self.stopped}")
        return "\n".join(lines)
