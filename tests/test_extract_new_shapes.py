"""warp-tube extract on shapes the other extraction tests do not build, where a message was wrong.

Oracle: each mesh is built here with trimesh, so what the extraction can and cannot measure on it
is known from its construction.
"""

from __future__ import annotations

import numpy as np
import trimesh

from warp_tube.extract.pipeline import extract_centerline


def open_tube(radius: float, length: float, around: int = 24, rings: int = 41) -> trimesh.Trimesh:
    """A straight tube along z with open ends: ``rings`` rings of ``around`` vertices [m]."""
    a = np.linspace(0.0, 2.0 * np.pi, around, endpoint=False)
    z = np.linspace(0.0, length, rings)
    v = np.stack([np.tile(radius * np.cos(a), rings), np.tile(radius * np.sin(a), rings), np.repeat(z, around)], 1)
    i, j = np.meshgrid(np.arange(rings - 1), np.arange(around), indexing="ij")
    p, q = i * around + j, i * around + (j + 1) % around
    faces = np.concatenate([np.stack([p, q, q + around], -1), np.stack([p, q + around, p + around], -1)])
    return trimesh.Trimesh(v, faces.reshape(-1, 3), process=False)


def test_a_fit_measured_one_way_only_is_not_reported_as_nan():
    """A flat bar (a box 20 x 6 x 1 of 12 triangles) is refined before the extraction, so its wall
    is sampled between its ends too (measured, unlike the box as given, whose vertices are all at
    its ends). A fit with one direction not measured (NaN figures) is warned of with the figures it
    has, saying which direction was not measured, instead of printing "nan / nan / nan %"."""
    import dataclasses

    from warp_tube.extract import tubelike
    from warp_tube.extract.fidelity import Distances

    # (16 spokes, so that the rings miss the bar's flat section: 32, which a section this flat gets
    # by default, follow it within the bounds)
    tube = extract_centerline(trimesh.creation.box((20.0, 6.0, 1.0)), spokes=16)
    assert tube.fidelity.to_surface.counted > 0  # refined: vertices away from its ends
    none = Distances(float("nan"), float("nan"), float("nan"), 0, tube.fidelity.to_surface.left_out)
    unmeasured = dataclasses.replace(tube, fidelity=dataclasses.replace(tube.fidelity, to_surface=none))
    misses = [w for w in tubelike.check(unmeasured, np.zeros((0, 0), dtype=bool), hubs_given=False)
              if w.startswith("the rest surface misses the mesh")]  # fmt: skip
    assert len(misses) == 1
    assert "nan" not in misses[0].lower()
    assert "mesh to surface not measured" in misses[0]
    # the direction that was measured keeps its figures (the round rings miss the bar's flat section)
    to_input = misses[0].split("surface to mesh ")[1]
    assert to_input[0].isdigit() and "%" in to_input


def test_a_scale_that_makes_the_tube_under_a_millimetre_long_warns(tmp_path):
    """A tube 20 mm long and 1 mm in radius given in metres, extracted with ``--scale 0.001`` (as
    if it were in mm), is 20 um long: extract warns that the mesh may already be in metres, as it
    warns of a tube over 20 m long. The same mesh without ``--scale`` gets no such warning.
    The warning's bound is 1 mm of length (no tube this simulator is for is shorter)."""
    from warp_tube.extract.command import extract_to_scene

    mesh = tmp_path / "tube_in_metres.ply"
    open_tube(radius=0.001, length=0.02).export(mesh)
    small = extract_to_scene(mesh, tmp_path / "small.usda", scale=0.001, hubs=8, progress=False)
    assert small.tube.length < 1e-3  # metres: 0.001 x ~0.02
    assert any("is the mesh already in metres" in w for w in small.warnings), small.warnings
    plain = extract_to_scene(mesh, tmp_path / "plain.usda", hubs=8, progress=False)
    assert 0.015 < plain.tube.length < 0.02
    assert not any("already in metres" in w for w in plain.warnings), plain.warnings


def test_a_coarse_mesh_is_judged_as_a_fine_one_of_the_same_shape():
    """A box of 12 triangles is refused as not tube-like, as the same box in fine triangles is
    (before refinement its 8 vertices gave a radius estimate that passed it as a tube); a cylinder
    with vertices at its end rings only has its rebuilt surface's fit measured, as a fine one has."""
    import pytest

    from warp_tube.scene.spec import SceneError

    box = trimesh.creation.box((10.0, 10.0, 10.0))
    fine_box = trimesh.Trimesh(*trimesh.remesh.subdivide_to_size(box.vertices, box.faces, max_edge=0.5))
    for mesh in (box, fine_box):
        with pytest.raises(SceneError, match="not tube-like"):
            extract_centerline(mesh, strict=True)
    cylinder = trimesh.creation.cylinder(radius=1.0, height=20.0, sections=32)  # capped, vertices at its ends only
    tube = extract_centerline(cylinder)
    assert tube.fidelity.to_surface.counted > 100
    # a 32-gon's wall lies between cos(pi/32) = 0.995 and 1 radius from the axis; the radius within 2%
    np.testing.assert_allclose(np.median(tube.radius), 1.0, rtol=0.02)
