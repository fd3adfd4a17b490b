"""``warp-tube extract MESH -o SCENE.usda [--hubs N] [--spokes S] [--scale F | --scale FX FY FZ] [--strict]``."""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass, field

import numpy as np

from ..scene.files import USD_EXTENSIONS, output_path
from ..scene.shape_notes import FLOAT32_REFUSE, float32_steps
from ..scene.spec import SceneError
from ..runtime.progress import Phase
from .fidelity import Fidelity
from .mesh_io import load_mesh
from .flat import FLAT_SPOKES, SPOKES
from .pipeline import ExtractedTube, extract_centerline
from .tube_check import check_size, side_branches, size_warning, summary_line, tube_warnings
from .usd import write_scene

__all__ = ["extract_to_scene", "Extraction"]

log = logging.getLogger(__name__)

@dataclass
class Extraction:
    """What ``extract`` did: the tube (metres), its fit (None if not measured), the scene written,
    the warnings given."""

    tube: ExtractedTube
    fidelity: Fidelity | None
    output: str
    warnings: list = field(default_factory=list)
    name: str = ""  # the output as the user gave it

    def summary(self) -> str:
        """One line: hubs, length, radius range, ends, branches, fit."""
        return summary_line(self.tube, self.fidelity, self.name or self.output)


def extract_to_scene(mesh_path, output, *, hubs=None, spokes=None, scale=None, device=None, progress=None,
                     strict=False, staging=None) -> Extraction:  # fmt: skip
    """Extract the tube in a mesh file and write a simulation scene for it.

    Args:
        mesh_path: STL, PLY, OBJ, ... file.
        output: scene to write, ``.usda`` (text), ``.usdc`` or ``.usd`` (binary); never the mesh
            itself; replaced only by a complete scene (see :func:`warp_tube.extract.usd.write_scene`).
        hubs: hubs N (default automatic, see :func:`warp_tube.extract.pipeline.extract_centerline`).
        spokes: spokes per hub S; None: 16, or 32 where the sections are flat.
        scale: None, one factor or (fx, fy, fz): metres per mesh unit along each axis (e.g.
            0.000832031 0.000832031 0.001 for CT voxel indices of 0.83 x 0.83 x 1 mm). Without it
            the mesh is taken to be in metres. The scene is written in metres (metersPerUnit 1).
        device: Warp device for the queries.
        progress: status lines for the long phases on stderr (default: when it is a terminal).
        strict: refuse a mesh that is not tube-like (SceneError) instead of warning.
        staging: write the scene there instead (a name beside ``output``), for a caller that edits
            it before renaming it to ``output`` (``warp-tube extract`` sizes its push first); None:
            ``output`` itself.

    Returns:
        The :class:`Extraction`. Warnings (a shape that does not look like a tube, a closed ring
        cut open, a rest surface that misses the mesh, a fit that could not be measured, a very
        large ``hubs``) are logged and listed in it.

    Raises:
        SceneError: unreadable or unusable mesh (with ``strict``: not tube-like), ``hubs`` over
            :data:`~warp_tube.extract.tube_check.MAX_HUBS` or ``hubs x spokes`` beyond the memory
            available (:func:`~warp_tube.extract.tube_check.check_size`), or an output that cannot be written.
    """
    from ..runtime.warp_setup import init_warp

    given = os.fspath(output)
    output = output_path(output, USD_EXTENSIONS, inputs=[mesh_path], what="scene")
    check_size(hubs, FLAT_SPOKES if spokes is None else spokes)  # (at most what the sections get)
    warnings = []
    big = size_warning(hubs, SPOKES if spokes is None else spokes)
    if big:
        log.warning(big)
        warnings.append(big)
    init_warp()
    factors = (1.0, 1.0, 1.0) if scale is None else scale
    name = os.path.basename(os.fspath(mesh_path))
    with Phase(f"reading {name}", enabled=progress):
        mesh = load_mesh(mesh_path, factors)
    with Phase(f"extracting the centerline of {name} ({len(mesh.faces):,} faces)", enabled=progress):
        tube = extract_centerline(mesh, hubs=hubs, spokes=spokes, device=device, source=str(mesh_path), strict=strict)
    fid = tube.fidelity
    warnings += tube.warnings  # the tube-likeness check and the fit on the simulator's rest surface (logged)
    found = tube_warnings(tube, fid, automatic_hubs=hubs is None)
    length = tube.tip_to_tip  # (the length the summary gives)
    if length > 20.0:
        found.append(f"the tube is {length:.3g} m long: is the mesh in mm or voxels? Pass --scale")
    elif length < 1e-3:  # under 1 mm: e.g. --scale 0.001 given for a mesh already in metres
        found.append(
            f"the tube is {length:.3g} m long ({1e3 * length:.3g} mm): is the mesh already in metres "
            "(then leave --scale out), or is --scale too small?"
        )
    for w in found:
        log.warning("%s: %s", mesh_path, w)
    warnings += found
    share, reach, shortest = float32_steps(np.asarray(tube.points, dtype=np.float64), [len(tube.points)])  # [m]
    if share > FLOAT32_REFUSE:  # (what the written scene's check would refuse, named for the mesh)
        raise SceneError(f"{mesh_path}: the tube lies up to {reach:.3g} m from the mesh's origin with hubs {shortest:.3g} m "
                         f"apart: the simulation holds positions as float32 world coordinates, whose steps there are "
                         f"{100.0 * share:.3g}% of a segment (at most {100.0 * FLOAT32_REFUSE:g}% is taken); translate the "
                         f"mesh nearer its origin (its shape does not depend on where it lies)")  # fmt: skip
    with Phase(f"writing {os.path.basename(output)}", enabled=progress):
        write_scene(tube, staging or output, meters_per_unit=1.0, inputs=[mesh_path], final_name=output)
    log.info("%s: %d hubs x %d spokes, %.4g m, %s -> %s (%.2f s)", mesh_path, tube.hubs, tube.spokes, tube.length,
             side_branches(len(tube.branches)), output, tube.timings["total"])  # fmt: skip
    return Extraction(tube, fid, output, warnings, given)
