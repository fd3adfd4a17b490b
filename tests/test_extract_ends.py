"""Where an extracted tube ends, what the tube-likeness check says, and the warnings of warp-tube extract.

Meshes are built here with known ends: voxel tubes (blocky, flat ends) and swept tubes with round
tips from warp_tube.bench.synthetic_tubes.
"""

from __future__ import annotations

import logging

import numpy as np
import pytest
import trimesh

from warp_tube.bench.synthetic_tubes import frenet_curve, sweep_mesh
from warp_tube.cli import main
from warp_tube.extract.mesh_io import boundary_loops
from warp_tube.extract.pipeline import extract_centerline
from warp_tube.extract.tubelike import NOT_A_TUBE
from warp_tube.scene.spec import SceneError

from .test_extract import helix, tube_mesh, voxel_surface


def pouch_tube(h=0.125):
    """A tube along x (radius 1.5, from x = 0, closed flat, to x = 20) narrowing to radius 0.9 over its
    last unit and open there, with a blind pouch (radius 1, 6 long along +y) at x = 17: its tip lies
    farther from the closed end along the inside than the opening does."""
    x, y, z = np.meshgrid(np.arange(-1, 22, h), np.arange(-2, 9, h), np.arange(-2, 2, h), indexing="ij")
    r = np.where(x < 19.0, 1.5, 0.9)
    main_ = (x >= 0) & (x <= 20) & (y**2 + z**2 <= r**2)
    pouch = (y >= 0) & (y <= 6) & ((x - 17) ** 2 + z**2 <= 1.0)
    m = voxel_surface(main_ | pouch, h)
    m.vertices += np.array([-1.0, -2.0, -2.0]) - 1.5 * h
    c = m.triangles_center
    opening = (np.abs(m.face_normals[:, 0]) > 0.9) & (c[:, 0] > 20.0 - 0.5 * h)
    return trimesh.Trimesh(m.vertices, m.faces[~opening], process=False)


def test_an_open_loop_is_an_end_even_when_a_blind_pouch_lies_farther():
    mesh = pouch_tube()
    (loop,) = boundary_loops(mesh)
    assert 0.8 < loop.radius < 1.1  # the small opening
    tube = extract_centerline(mesh)
    kinds = [e.kind for e in tube.ends]
    assert sorted(kinds) == ["cut", "open"], kinds
    tips = {e.kind: e.tip for e in tube.ends}
    # The open end at the opening, the other at the flat closed end x = 0 (voxel surfaces lie up to
    # half a voxel off the nominal shape).
    assert np.linalg.norm(tips["open"] - loop.centroid) < 1e-9
    assert abs(tips["cut"][0] - 0.0) < 0.25
    # The pouch (6 long beyond the tube's axis at x = 17) is a side branch left out.
    assert len(tube.branches) == 1
    junction, length = tube.branches[0]
    assert abs(tube.points[junction, 0] - 17.0) < 1.5 and 4.0 < length < 7.5


def capsule(length=12.0, radius=1.0):
    """A straight tube with round tips along +x from the origin: (mesh, curve points)."""
    s, x, t = frenet_curve(lambda u: 0.0 * u, lambda u: 0.0 * u, length, step=0.05)
    return sweep_mesh(x, t, np.full(len(s), radius), ("round", "round"), ring=32), x


def test_an_opening_in_the_wall_is_not_an_end():
    mesh, axis = capsule()
    c = mesh.triangles_center
    hole = np.linalg.norm(c - np.array([6.0, 1.0, 0.0]), axis=1) < 0.6  # a branch cut flush, on the side
    holed = trimesh.Trimesh(mesh.vertices, mesh.faces[~hole], process=False)
    (loop,) = boundary_loops(holed)
    tube = extract_centerline(holed)
    # Both ends at the round tips (capped), not at the opening.
    assert [e.kind for e in tube.ends] == ["closed", "closed"] and tube.caps
    assert sorted(abs(e.tip[0] - 6.0) for e in tube.ends) == pytest.approx([7.0, 7.0], abs=0.05)
    (opening,) = tube.openings
    assert opening.kind == "wall" and opening.radius == pytest.approx(loop.radius)
    assert opening.vertices == len(loop.vertices)
    # The hubs stay on the axis past the opening: the spokes meet the opening's closure.
    assert np.abs(tube.points[:, 1:]).max() < 0.05


def test_two_open_ends_and_a_spare_loop():
    mesh, axis = capsule(length=14.0)
    c = mesh.triangles_center
    keep = (c[:, 0] > -0.01) & (c[:, 0] < 14.01)  # cut both round tips off: two open ends
    hole = np.linalg.norm(c - np.array([5.0, 0.0, 1.0]), axis=1) < 0.5
    opened = trimesh.Trimesh(mesh.vertices, mesh.faces[keep & ~hole], process=False)
    opened.remove_unreferenced_vertices()
    tube = extract_centerline(opened)
    assert [e.kind for e in tube.ends] == ["open", "open"]
    assert sorted(e.tip[0] for e in tube.ends) == pytest.approx([0.0, 14.0], abs=1e-6)
    assert [o.kind for o in tube.openings] == ["wall"]


def test_a_sphere_is_not_tube_like_and_strict_refuses_it(caplog):
    sphere = trimesh.creation.icosphere(radius=1.0)
    with caplog.at_level(logging.WARNING, logger="warp_tube"):
        tube = extract_centerline(sphere)
    assert any(w.startswith(NOT_A_TUBE) and "mean radii long" in w for w in tube.warnings)
    assert NOT_A_TUBE in caplog.text
    with pytest.raises(SceneError, match="not tube-like.*--strict"):
        extract_centerline(sphere, strict=True)


def test_a_cylinder_missing_a_face_along_it_is_not_tube_like():
    c = trimesh.creation.cylinder(radius=1.0, height=10.0, sections=24)
    side = np.flatnonzero(np.abs(c.face_normals[:, 2]) < 0.1)
    pair = [f for f in side if np.allclose(c.face_normals[f], c.face_normals[side[0]])]
    assert len(pair) == 2  # the two triangles of one side face
    slit = trimesh.Trimesh(c.vertices, np.delete(c.faces, pair, axis=0), process=False)
    tube = extract_centerline(slit)
    assert any(w.startswith(NOT_A_TUBE) and "not closed loops" in w for w in tube.warnings), tube.warnings
    assert not any(w.startswith(NOT_A_TUBE) for w in extract_centerline(c).warnings)


def test_cli_strict_exits_2_without_output_and_plain_extract_warns(tmp_cwd, capsys, caplog):
    trimesh.creation.icosphere(radius=0.01).export(tmp_cwd / "ball.stl")
    assert main(["extract", "ball.stl", "-o", "ball.usda", "--strict"]) == 2
    err = capsys.readouterr().err
    assert "ball.stl" in err and "not tube-like" in err and "Traceback" not in err
    assert not (tmp_cwd / "ball.usda").exists()
    with caplog.at_level(logging.WARNING, logger="warp_tube"):
        assert main(["extract", "ball.stl", "-o", "ball.usda"]) == 0
    assert "ball.stl: not tube-like" in caplog.text
    assert (tmp_cwd / "ball.usda").exists()


def test_too_few_hubs_warn_with_the_fidelity():
    mesh, _, _ = tube_mesh(curve=helix, caps=False)
    coarse = extract_centerline(mesh, hubs=5)
    (warning,) = coarse.warnings
    assert "misses the mesh" in warning and "--hubs 5" in warning and "%" in warning
    auto = extract_centerline(mesh)
    assert auto.warnings == [] and auto.hubs > 5


def _straight(length, radius, ends):
    s, x, t = frenet_curve(lambda u: 0.0 * u, lambda u: 0.0 * u, length, step=0.05)
    return sweep_mesh(x, t, np.full(len(s), radius), ends, ring=32)


def test_ends_trimmed_back_over_much_of_a_short_tube_are_warned_of(caplog):
    """A tube cut flat at both ends so short that its end rings, kept clear of the cuts, leave much
    of its length out: warned of (before: nothing; the summary gave the length from tip to tip);
    a long one, not."""
    with caplog.at_level(logging.WARNING):
        long = extract_centerline(_straight(12.0, 1.0, ("open", "open")), device="cpu")
    assert "trimmed back" not in caplog.text
    assert long.length > 0.95 * long.tip_to_tip
    caplog.clear()
    with caplog.at_level(logging.WARNING):  # 3 radii long, cut flat at both ends
        short = extract_centerline(_straight(3.0, 1.0, ("flat", "flat")), device="cpu")
    assert [e.kind for e in short.ends] == ["cut", "cut"] and short.length < 0.9 * short.tip_to_tip
    assert f"its end hubs span {short.length:.4g} of the {short.tip_to_tip:.4g} from tip to tip" in caplog.text


def test_cleaning_keeps_a_closed_mesh_closed_where_slivers_join_faces():
    """Marching cubes leaves slivers: faces of three distinct collinear corners, which close the
    mesh where an edge is split on one side only. Dropping them (as zero-area faces) opened cracks
    in a watertight mesh, and a Y-branch came out 23% short with exit 0; they are kept."""
    from warp_tube.extract.mesh_io import clean_mesh

    mesh, _ = capsule()
    assert mesh.is_watertight
    v, f = mesh.vertices.copy(), mesh.faces.copy()
    edges = mesh.edges_unique[::97][:40]  # split some edges on one side: (a, b, c) -> (a, m, c) + (m, b, c), sliver (a, b, m)
    faces = []
    done = np.zeros(len(f), dtype=bool)
    for a, b in edges:
        k = next(i for i, face in enumerate(f) if not done[i] and a in face and b in face)
        face = list(f[k])
        while not (face[0] == a and face[1] == b) and not (face[0] == b and face[1] == a):
            face = face[1:] + face[:1]
        p, q, c = face
        m = len(v)
        v = np.vstack([v, 0.5 * (v[p] + v[q])])
        done[k] = True
        faces += [[p, m, c], [m, q, c], [p, q, m]]
    mesh2 = trimesh.Trimesh(v, np.vstack([f[~done], faces]), process=False)
    assert mesh2.is_watertight and (mesh2.area_faces == 0).sum() >= 1
    cleaned = clean_mesh(mesh2, "slivers")
    assert cleaned.is_watertight


def test_where_no_vertex_is_measured_the_tubes_volume_tells_a_tube_from_a_plate():
    """A plain capsule's vertices all lie at its ends, and so do a thin plate's beyond the thin tube
    found across it: no vertex is measured against the rings, and the left-out test says nothing.
    The tube's own volume against the mesh's tells them apart (before: a 0.2 x 0.2 x 0.002 plate
    passed --strict). The volume is exact for a cylinder (pi r^2 L: trapezoids of equal sections)."""
    from types import SimpleNamespace

    from warp_tube.extract.fidelity import Distances, Fidelity
    from warp_tube.extract.tubelike import tube_volume
    from warp_tube.extract.tubelike import check as tubelike_check

    r, length = 0.01, 0.2
    x = np.linspace(0.0, length, 21)
    points = np.stack([x, 0 * x, 0 * x], 1)
    assert abs(tube_volume(SimpleNamespace(points=points, spoke_lengths=np.full((21, 16), r))) / (np.pi * r * r * length) - 1) < 1e-12
    none = Distances(float("nan"), float("nan"), float("nan"), 0, 500)
    fid = Fidelity(to_surface=none, to_input=Distances(0.01, 0.02, 0.03, 100, 0), rings_to_input=none, mean_radius=r,
                   end_ratios=(1.0, 1.0), guard_moved=0.0)  # fmt: skip
    end = SimpleNamespace(kind="closed", trimmed=r, radius=r)
    tube = SimpleNamespace(ring=None, spoke_lengths=np.full((21, 16), r), points=points, tip_to_tip=length + 2 * r, length=length,
                           fidelity=fid, ends=(end, end), caps=True, hubs=21)  # fmt: skip
    capsule_volume = np.pi * r * r * length + 4.0 / 3.0 * np.pi * r**3
    assert not [w for w in tubelike_check(tube, np.zeros((21, 8), bool), hubs_given=False, mesh_volume=capsule_volume)
                if w.startswith(NOT_A_TUBE)]  # fmt: skip
    plate = tubelike_check(tube, np.zeros((21, 8), bool), hubs_given=False, mesh_volume=0.2 * 0.2 * 0.02)
    assert any(w.startswith(f"{NOT_A_TUBE}: the tube holds 7.9% of the volume the mesh encloses") for w in plate), plate


def test_openings_between_hubs_are_in_the_wall():
    """Holes in the wall half way between two hubs: their centres lie one radius from the
    centerline but farther from either hub, and were called branches (two of three, not warned)
    when measured from the nearest hub. Measured from the centerline they are all in the wall."""
    mesh, axis = capsule(length=14.0)
    c = mesh.triangles_center
    keep = (c[:, 0] > -0.01) & (c[:, 0] < 14.01)
    tube = extract_centerline(trimesh.Trimesh(mesh.vertices, mesh.faces[keep], process=False), hubs=8)
    mid = 0.5 * (tube.points[1:] + tube.points[:-1])  # half way between hubs, on the axis
    holes = np.zeros(len(mesh.faces), dtype=bool)
    for k, side in ((1, (0.0, 1.0, 0.0)), (3, (0.0, 0.0, 1.0)), (5, (0.0, -1.0, 0.0))):
        holes |= np.linalg.norm(c - (mid[k] + side), axis=1) < 0.4
    opened = trimesh.Trimesh(mesh.vertices, mesh.faces[keep & ~holes], process=False)
    opened.remove_unreferenced_vertices()
    tube = extract_centerline(opened, hubs=8)
    assert [o.kind for o in tube.openings] == ["wall"] * 3
    assert all(0.85 < o.distance < 1.0 for o in tube.openings)  # the loop's centre: inside the unit wall, by its sag
