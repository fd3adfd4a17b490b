"""``warp-tube extract MESH -o SCENE.usda [--hubs N] [--spokes S] [--scale F | --scale FX FY FZ] [--strict]``."""

from __future__ import annotations

import logging

from .pipeline import ExtractedTube, extract_centerline
from .usd import write_scene
from .mesh_io import load_mesh

__all__ = ["extract_to_scene"]

log = logging.getLogger(__name__)


def extract_to_scene(mesh_path, output, *, hubs=None, spokes=16, scale=None, device=None, strict=False) -> ExtractedTube:
    """Extract the tube in a mesh file and write a simulation scene for it.

    Args:
        mesh_path: STL, PLY, OBJ, ... file.
        output: scene ``.usda`` to write (see :func:`warp_tube.extract.usd.write_scene`).
        hubs: hubs N (default automatic, see :func:`warp_tube.extract.pipeline.extract_centerline`).
        spokes: spokes per hub S.
        scale: None, one factor or (fx, fy, fz): metres per mesh unit along each axis (e.g.
            0.000832031 0.000832031 0.001 for CT voxel indices of 0.83 x 0.83 x 1 mm). Without it
            the mesh is taken to be in metres. The scene is written in metres (metersPerUnit 1).
        strict: refuse a mesh that is not tube-like (SceneError) instead of warning.

    Raises:
        SceneError: unreadable or unusable mesh (with ``strict``: not tube-like), or an output that cannot be
            written.
    """
    factors = (1.0, 1.0, 1.0) if scale is None else scale
    mesh = load_mesh(mesh_path, factors)
    tube = extract_centerline(mesh, hubs=hubs, spokes=spokes, device=device, source=str(mesh_path), strict=strict)
    if tube.length > 20.0:
        log.warning("%s: the tube is %.3g m long: is the mesh in mm or voxels? Pass --scale", mesh_path, tube.length)
    write_scene(tube, output, meters_per_unit=1.0)
    log.info("%s: %d hubs x %d spokes, %.4g m, %d side branches -> %s (%.2f s)", mesh_path, tube.hubs,
             tube.spokes, tube.length, len(tube.branches), output, tube.timings["total"])
    return tube
