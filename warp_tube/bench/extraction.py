"""Extraction measured as a user meets it: the frame-0 Surface of the scene ``warp-tube extract``
writes, built through the public path (scene file, scene reader, ``Simulation``), for the
extraction tests and ``benchmarks/bench_extract.py``."""

from __future__ import annotations

import os
import tempfile

import numpy as np

from ..extract.fidelity import RestSurface, rest_surface
from ..extract.pipeline import ExtractedTube
from ..extract.usd import write_scene
from ..io import StageWriter  # noqa: F401 (registers the output writer with the frame loop)
from ..scene.usd import load_scene
from ..sim.simulation import Simulation

__all__ = ["simulated_surface"]


def simulated_surface(tube: ExtractedTube, meters_per_unit: float = 1.0, device="cpu") -> RestSurface:
    """The frame-0 Surface of the scene ``warp-tube extract`` writes for ``tube``, built through the
    public API: :func:`warp_tube.extract.usd.write_scene`, :func:`warp_tube.load_scene`, then
    ``warp_tube.Simulation(scene, device).surface_points()`` before any step.

    Args:
        tube: the extracted tube [mesh units]; meters_per_unit: metres per mesh unit (the scene's).

    Returns:
        The surface [mesh units] (``unguarded``: the same rebuilt with the guard off, by :func:`rest_surface`).
    """
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "scene.usda")
        write_scene(tube, path, meters_per_unit=meters_per_unit)
        sim = Simulation(load_scene(path), device=device)
        points = sim.surface_points()[0].astype(np.float64)
        faces = np.asarray(sim.surfaces[0].face_vertex_indices, dtype=np.int64).reshape(-1, 3)
    plain = rest_surface(tube.points, tube.spoke_lengths, tube.reference_normal, tube.caps, device)
    return RestSurface(points, faces, plain.unguarded, tube.hubs, tube.spokes)
