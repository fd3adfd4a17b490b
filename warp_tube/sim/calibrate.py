"""The push of an extracted scene, sized by simulating the scene itself.

An extracted scene pushes its middle hub (``/World/Push``, ramped up over frames 0-24, held to 48,
released at 60). A force from beam theory (:func:`warp_tube.extract.usd.push_force`, a straight,
simply supported beam) can be tens of times too small for a tube that winds: a curved tube pushed
in its plane acts as an arch, held by its axial stiffness. :func:`size_push` runs the scene as
written (the CPU, no surface) over the ramp and hold, measures the largest displacement of any
point, and scales the force's samples so that the displacement becomes the target. The response to
a force that small is linear (a few radii on a tube tens of radii long), so one run is enough;
:func:`size_push` reports the displacement the scaled force gives as the run measured it, scaled.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["PushSize", "size_push", "PUSH_FRAMES"]

#: frames simulated to size the push: the ramp (0-24) and the hold (24-48) of an extracted scene
PUSH_FRAMES = 49


@dataclass(frozen=True)
class PushSize:
    """What :func:`size_push` did.

    Attributes:
        factor: the force's samples were multiplied by this.
        force_n: the largest force magnitude after scaling [N].
        before_m: the largest displacement with the force as it was [m].
        target_m: the displacement sized for [m].
    """

    factor: float
    force_n: float
    before_m: float
    target_m: float


def largest_displacement(scene, frames: int = PUSH_FRAMES) -> float:
    """The largest distance of a point from rest over frames 1 to ``frames - 1`` [m] (the CPU, no
    surface)."""
    from .simulation import Simulation

    sim = Simulation(scene, device="cpu", surface=False)
    out = 0.0
    for _ in range(1, frames):
        sim.step()
        out = max(out, sim.max_displacement())
    return out


def size_push(path: str, force_path: str = "/World/Push", radii: float = 2.0, frames: int = PUSH_FRAMES) -> PushSize | None:
    """Scale the samples of force ``force_path`` in scene file ``path`` so that its tube moves by
    ``radii`` mean radii within ``frames`` frames; the file is rewritten (atomically).

    Returns:
        The :class:`PushSize`, or None where the scene has no such force or it moves nothing.

    Raises:
        NumericalError: the scene blows up with the force as it was.
    """
    from ..scene.edit import scale_force_samples
    from ..scene.usd import load_scene

    scene = load_scene(path)
    forces = [f for f in scene.forces if f.path == force_path]
    if not forces:
        return None
    tube = scene.tubes[forces[0].tube]
    target = radii * float(np.mean(tube.radius))
    before = largest_displacement(scene, frames)
    if not before > 0.0:
        return None
    factor = target / before
    scale_force_samples(path, force_path, factor)
    return PushSize(factor=factor, force_n=factor * float(np.linalg.norm(forces[0].values, axis=-1).max()), before_m=before,
                    target_m=target)  # fmt: skip
