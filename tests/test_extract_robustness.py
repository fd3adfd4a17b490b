"""warp-tube extract on inputs a new user gives it by mistake: a closed ring (a torus, which has no
ends), a file of random bytes named as a mesh, a --scale that shrinks the mesh below what can be
resolved, and counts of one in the messages.

Meshes are built here with trimesh (or by hand where the topology matters) and written to tmp_path.
"""

from __future__ import annotations

import logging
import os
from itertools import pairwise

import numpy as np
import pytest
import trimesh

from warp_tube.cli import main
from warp_tube.extract.closed_ring import euler_characteristic, is_closed_ring
from warp_tube.extract.mesh_io import clean_mesh, mesh_from_arrays
from warp_tube.extract.pipeline import extract_centerline
from warp_tube.extract.tubelike import NOT_A_TUBE
from warp_tube.extract.wording import counted
from warp_tube.scene.spec import SceneError


def _refusal(call) -> str:
    """The message of the SceneError that ``call()`` raises."""
    with pytest.raises(SceneError) as e:
        call()
    return str(e.value)


def torus():
    """A ring of tube: centre-line radius 0.05 m, tube radius 0.008 m (watertight, genus 1)."""
    return trimesh.creation.torus(major_radius=0.05, minor_radius=0.008)


def straight_tube(stations=41, ring=24, length=10.0, radius=1.0, caps=True):
    """A tube along x, ``stations`` rings of ``ring`` vertices joined by strips; ``caps`` closes both
    ends with fans. Returns ``(vertices (V, 3), faces (F, 3))``; vertex ``i * ring + j`` is vertex j
    of ring i."""
    x = np.linspace(0.0, length, stations)
    phi = 2.0 * np.pi * np.arange(ring) / ring
    v = np.stack([np.repeat(x, ring), radius * np.tile(np.cos(phi), stations),
                  radius * np.tile(np.sin(phi), stations)], 1)  # fmt: skip
    i, j = np.meshgrid(np.arange(stations - 1), np.arange(ring), indexing="ij")
    a0, a1 = i * ring + j, i * ring + (j + 1) % ring
    f = np.concatenate([np.stack([a0, a1, a1 + ring], -1).reshape(-1, 3),
                        np.stack([a0, a1 + ring, a0 + ring], -1).reshape(-1, 3)])  # fmt: skip
    if caps:
        k = len(v)
        v = np.vstack([v, [[0.0, 0.0, 0.0], [length, 0.0, 0.0]]])
        jj = np.arange(ring)
        last = (stations - 1) * ring
        f = np.vstack([f, np.stack([np.full(ring, k), (jj + 1) % ring, jj], 1),
                       np.stack([np.full(ring, k + 1), last + jj, last + (jj + 1) % ring], 1)])  # fmt: skip
    return v, f


def tube_with_a_small_handle(ring=24, first=12, last=20, rise=0.6, steps=8):
    """A capped straight tube (radius 1, 10 long) whose wall carries a small hollow handle: the wall
    quads of spoke 0 at stations ``first`` and ``last`` are opened and joined by an arched square
    duct (one quad wide) rising ``rise`` above the wall. Watertight, genus 1, but not a ring."""
    v, f = straight_tube(ring=ring)
    holes = [[i * ring, i * ring + 1, (i + 1) * ring + 1, (i + 1) * ring] for i in (first, last)]
    opened = {tuple(sorted(t)) for q in holes for t in ([q[0], q[1], q[2]], [q[0], q[2], q[3]])}
    f = np.asarray([t for t in f.tolist() if tuple(sorted(t)) not in opened])
    rings = [holes[0]]
    for t in np.linspace(0.0, 1.0, steps + 1)[1:-1]:
        corners = (1.0 - t) * v[holes[0]] + t * v[holes[1]]
        lift = rise * np.sin(np.pi * t) * corners[:, 1:] / np.linalg.norm(corners[:, 1:], axis=1, keepdims=True)
        v = np.vstack([v, corners + np.concatenate([np.zeros((4, 1)), lift], 1)])
        rings.append(list(range(len(v) - 4, len(v))))
    rings.append(holes[1])
    duct = [[a[k], a[(k + 1) % 4], b[(k + 1) % 4]] for a, b in pairwise(rings) for k in range(4)]
    duct += [[a[k], b[(k + 1) % 4], b[k]] for a, b in pairwise(rings) for k in range(4)]
    return trimesh.Trimesh(v, np.vstack([f, duct]), process=False)


# ---------------------------------------------------------------------------------------------
# a closed ring


def test_the_euler_characteristic_tells_a_ring_from_an_open_or_capped_tube():
    ring = torus()
    open_v, open_f = straight_tube(caps=False)
    capped_v, capped_f = straight_tube(caps=True)
    open_tube, capped = trimesh.Trimesh(open_v, open_f), trimesh.Trimesh(capped_v, capped_f)
    assert [euler_characteristic(m) for m in (ring, open_tube, capped)] == [0, 0, 2]
    assert [is_closed_ring(m) for m in (ring, open_tube, capped)] == [True, False, False]


def test_a_closed_ring_warns_where_it_was_cut_and_how_much_is_left_out(tmp_path, monkeypatch, capsys, caplog):
    monkeypatch.chdir(tmp_path)
    torus().export("ring.stl")
    with caplog.at_level(logging.WARNING, logger="warp_tube"):
        assert main(["extract", "ring.stl", "-o", "ring.usda"]) == 0
    (warning,) = [r.getMessage() for r in caplog.records if "closed ring" in r.getMessage()]
    assert warning.startswith(f"ring.stl: {NOT_A_TUBE}: a closed ring with no ends"), warning
    assert "cut open at (" in warning and ") and (" in warning
    left_out = float(warning.split("leaves ")[1].split("%")[0])
    # the gap cut out is about one tube radius of a ring 2 pi x 6.25 radii round (3 %, and 4.5 % at
    # a gap of 1.75 radii): all but a few % of the ring is kept
    assert 0.0 < left_out <= 4.5, warning
    assert "(between its two end rings)" in warning, warning
    summary = capsys.readouterr().out.splitlines()[0]
    assert f"closed ring cut open ({left_out:.0f}% of its surface left out)" in summary, summary
    assert "0 side branches left out" in summary and summary.endswith("both ways, on the part kept"), summary
    assert (tmp_path / "ring.usda").exists()


def test_strict_refuses_a_closed_ring_in_one_line_and_writes_nothing(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    torus().export("ring.stl")
    assert main(["extract", "ring.stl", "-o", "ring.usda", "--strict"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert err.startswith("warp-tube: ring.stl: not tube-like: a closed ring with no ends"), err
    # (said as what the tube would do: nothing is cut open, nothing written)
    assert "the tube would be cut open at" in err and "and leave " in err and "of the ring's surface out" in err, err
    assert err.endswith("(--strict)"), err
    assert not (tmp_path / "ring.usda").exists()


def test_a_small_handle_on_a_straight_tube_is_not_a_ring():
    mesh = tube_with_a_small_handle()
    cleaned = clean_mesh(mesh, "handle")
    assert is_closed_ring(cleaned)  # the topology alone would call it a ring
    tube = extract_centerline(mesh, source="handle")
    assert tube.ring is None
    assert not any("closed ring" in w for w in tube.warnings), tube.warnings
    assert tube.tip_to_tip == pytest.approx(10.0, rel=0.05)


# ---------------------------------------------------------------------------------------------
# files that are not meshes


def _garbage(kind: str) -> bytes:
    rng = np.random.default_rng(7)
    header = b"ply\nformat binary_little_endian 1.0\nelement vertex 8\nproperty float x\nproperty float y\n" \
             b"property float z\nelement face 4\nproperty list uchar int vertex_indices\nend_header\n"  # fmt: skip
    return {"random": rng.bytes(4000), "ply then random": b"ply\n" + rng.bytes(4000),
            "truncated": header + rng.bytes(30), "empty": b""}[kind]  # fmt: skip


@pytest.mark.parametrize("kind", ["random", "ply then random", "truncated"])
def test_garbage_named_ply_says_it_is_not_a_readable_ply_mesh(kind, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "garbage.ply").write_bytes(_garbage(kind))
    assert main(["extract", "garbage.ply", "-o", "s.usda"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == "warp-tube: garbage.ply: not a readable PLY mesh: the file is damaged, truncated or not PLY", err
    assert not (tmp_path / "s.usda").exists()


def test_garbage_named_stl_and_a_text_file_name_the_file_and_what_is_wrong(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "garbage.stl").write_bytes(np.random.default_rng(3).bytes(1000))
    (tmp_path / "notes.txt").write_text("a tube\n")
    assert main(["extract", "garbage.stl", "-o", "s.usda"]) == 2
    assert main(["extract", "notes.txt", "-o", "s.usda"]) == 2
    first, second = capsys.readouterr().err.strip().splitlines()
    assert first == "warp-tube: garbage.stl: not a readable STL mesh: the file is damaged, truncated or not STL"
    assert second == "warp-tube: notes.txt: a .txt file: expected a mesh file (.stl, .ply, .obj, .off or .glb)"
    assert not (tmp_path / "s.usda").exists()


@pytest.mark.parametrize("ext", ["stl", "ply", "obj", "off", "glb"])
def test_an_empty_file_of_every_format_is_called_an_empty_file(ext, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / f"empty.{ext}").write_bytes(b"")
    assert main(["extract", f"empty.{ext}", "-o", "s.usda"]) == 2
    assert capsys.readouterr().err.strip() == f"warp-tube: empty.{ext}: an empty file: expected a surface mesh"
    assert not (tmp_path / "s.usda").exists()


# ---------------------------------------------------------------------------------------------
# triangle soups and several components


def _soup(v, f, jitter_ulps=0, shrink=0.0, seed=0):
    """Each triangle its own corners, in float32 (as STL has them), moved by up to ``jitter_ulps``
    float32 steps each, or pulled towards their triangle's centre by ``shrink`` of the way."""
    tri = np.asarray(v, dtype=np.float64)[f]
    tri = tri + shrink * (tri.mean(axis=1, keepdims=True) - tri)
    p = tri.reshape(-1, 3).astype(np.float32)
    step = np.random.default_rng(seed).integers(-jitter_ulps, jitter_ulps + 1, p.shape)
    for _ in range(jitter_ulps):
        p = np.where(step > 0, np.nextafter(p, np.float32(np.inf)), np.where(step < 0, np.nextafter(p, np.float32(-np.inf)), p))
        step = step - np.sign(step)
    return trimesh.Trimesh(p.astype(np.float64), np.arange(len(p)).reshape(-1, 3), process=False)


def test_a_soup_whose_shared_corners_differ_by_a_float32_step_is_welded_into_one_tube(caplog):
    """An STL written triangle by triangle, in mm, its shared corners one float32 step apart: one
    tube, not thousands of components (then a near-zero end radius asked for billions of samples)."""
    v, f = straight_tube(stations=41, ring=24, length=100.0, radius=5.0, caps=False)
    v = v + np.array([30.0, -20.0, 10.0])  # (off the origin: coarser float32 steps)
    with caplog.at_level(logging.WARNING, logger="warp_tube"):
        out = clean_mesh(_soup(v, f, jitter_ulps=1), "soup.stl", scale=1e-3)
    assert "connected component" not in caplog.text, caplog.text
    assert len(out.faces) == len(f) and len(out.vertices) == len(v)
    tube = extract_centerline(out, hubs=20)
    assert tube.tip_to_tip == pytest.approx(0.1, rel=0.02)


def test_resampling_a_polyline_is_bounded_whatever_the_step():
    from warp_tube.extract.polyline import nearest_on_polyline

    line = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    dist, arc = nearest_on_polyline(np.array([[0.25, 0.5, 0.0], [0.75, 0.0, 1.0]]), line, 1e-13)
    assert dist == pytest.approx([0.5, 1.0]) and arc == pytest.approx([0.25, 0.75], abs=1e-5)  # (1e5 samples at most)


def test_a_mesh_fallen_into_many_small_pieces_is_named_so(caplog):
    v, f = straight_tube(stations=11, ring=12, length=10.0, radius=1.0, caps=False)
    with caplog.at_level(logging.WARNING, logger="warp_tube"):
        message = _refusal(lambda: clean_mesh(_soup(v, f, shrink=0.01), "pieces.stl"))
    assert message == "pieces.stl: only 1 face: expected a tube surface"
    text = caplog.text
    assert f"{len(f)} connected components" in text and "many small pieces" in text, text
    assert f"{100.0 / len(f):.3g}% of the area" in text and f"{len(f) - 1} others" in text, text


def test_of_several_components_the_largest_by_area_is_kept_not_the_one_of_most_faces(caplog):
    """A 300 mm artery meshed coarsely (1,920 faces) and a 40 mm twig meshed finely (5,120): the
    artery is kept, and the warning names both."""
    va, fa = straight_tube(stations=61, ring=16, length=0.3, radius=0.006, caps=False)
    vt, ft = straight_tube(stations=81, ring=32, length=0.04, radius=0.001, caps=False)
    both = trimesh.Trimesh(np.vstack([va, vt + [0.0, 0.05, 0.0]]), np.vstack([fa, ft + len(va)]), process=False)
    with caplog.at_level(logging.WARNING, logger="warp_tube"):
        out = clean_mesh(both, "two.stl")
    assert len(out.faces) == 1920 and np.ptp(out.vertices[:, 0]) == pytest.approx(0.3)
    text = caplog.text
    assert "2 connected components; kept the largest by surface area (1,920 faces, 0.3 m across" in text, text
    assert "left out: 5,120 faces, 0.0401 m across" in text, text


# ---------------------------------------------------------------------------------------------
# --scale that makes the mesh too small


def test_a_scale_that_shrinks_the_mesh_below_resolution_names_its_size(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    trimesh.creation.cylinder(radius=0.005, height=0.08, sections=24).export("cyl.stl")
    assert main(["extract", "cyl.stl", "-o", "c.usda", "--scale", "1e-9"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("warp-tube: cyl.stl: the mesh is 8e-11 across after scaling by 1e-09"), err
    assert "too small" in err and "check --scale" in err and "zero area" not in err, err
    assert not (tmp_path / "c.usda").exists()


def test_a_realistic_scale_is_not_refused_and_a_collapsed_mesh_still_has_zero_area():
    mm = trimesh.creation.cylinder(radius=0.5, height=8.0, sections=24)  # a 1 mm vessel in mm
    out = clean_mesh(mm, "vessel", scale=1e-3)
    assert np.ptp(out.vertices, axis=0).max() == pytest.approx(8e-3)
    point = trimesh.Trimesh([[0.0, 0.0, 0.0]] * 3, [[0, 1, 2]], process=False)
    assert _refusal(lambda: clean_mesh(point, "point")) == "point: every face has zero area: expected a tube surface"


# ---------------------------------------------------------------------------------------------
# counts of one


def test_counted_pluralises():
    assert [counted(1, "face"), counted(0, "face"), counted(2, "vertex"), counted(1, "vertex")] == [
        "1 face", "0 faces", "2 vertices", "1 vertex"]  # fmt: skip
    assert counted(1, "side branch") == "1 side branch" and counted(3, "side branch") == "3 side branches"
    assert counted(12345, "face", fmt=",") == "12,345 faces"


def test_messages_say_one_face_one_vertex_one_point_one_entry(tmp_path, monkeypatch, capsys):
    one = trimesh.Trimesh([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], [[0, 1, 2]], process=False)
    assert _refusal(lambda: clean_mesh(one, "tri")) == "tri: only 1 face: expected a tube surface"
    lone = trimesh.Trimesh([[0.0, 0.0, 0.0]], np.zeros((0, 3), dtype=np.int64), process=False)
    assert _refusal(lambda: clean_mesh(lone, "dot")) == "dot: empty mesh (1 vertex, 0 faces): expected a tube surface"
    nan = trimesh.Trimesh([[np.nan, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], [[0, 1, 2]], process=False)
    assert _refusal(lambda: clean_mesh(nan, "nan")).startswith("nan: 1 vertex with NaN or infinite coordinates")
    short = _refusal(lambda: mesh_from_arrays(np.eye(3), [3], [0], source="prim"))
    assert short.endswith("faceVertexIndices has 1 entry"), short
    monkeypatch.chdir(tmp_path)
    (tmp_path / "pt.ply").write_text("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
                                     "property float z\nend_header\n0 0 0\n")  # fmt: skip
    one.export("tri.stl")
    assert main(["extract", "pt.ply", "-o", "s.usda"]) == 2
    assert main(["extract", "tri.stl", "-o", "s.usda"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert err == ["warp-tube: pt.ply: 1 point and no faces (a point cloud): expected a surface mesh",
                   "warp-tube: tri.stl: only 1 face: expected a tube surface"], err  # fmt: skip
    assert not (tmp_path / "s.usda").exists()


def test_a_capillary_in_metres_extracts_as_the_same_tube_a_million_times_larger():
    """Extraction is the same at every size: a tube 30 um long and 0.8 um across, in metres, gives
    the hubs and spokes of the same mesh in metres a million times larger, scaled (before: trimesh's
    face normals, cut off at an absolute 1e-12, were 0 on every face, and the mesh "enclosed no
    volume")."""
    from .test_extract import tube_mesh

    big, _, _ = tube_mesh(curve=lambda u: np.stack([30.0 * u, 3.0 * np.sin(4.0 * u), 0.0 * u], 1),
                          radius=lambda u: 0.8 + 0.0 * u, stations=120, ring=24)  # fmt: skip
    small = trimesh.Trimesh(big.vertices * 1e-6, big.faces, process=False)
    a = extract_centerline(big, device="cpu")
    b = extract_centerline(small, device="cpu")
    assert a.hubs == b.hubs
    # the same extraction but for the float32 queries' round-off (relative to each mesh's size)
    assert np.abs(b.points * 1e6 - a.points).max() < 1e-3 * 0.8
    assert np.abs(b.spoke_lengths * 1e6 - a.spoke_lengths).max() < 1e-3 * 0.8


def test_an_opening_in_the_wall_is_warned_of_with_its_hub_and_size():
    """A hole cut in the wall (a branch cut flush) is kept across and recorded in customData; the
    README says openings are reported in the log: a warning, not only an info line."""
    from warp_tube.extract.tube_check import tube_warnings

    v, f = straight_tube(stations=61, ring=24, length=60.0, radius=5.0, caps=False)
    i, j = np.divmod(np.arange(len(f) // 2), 24)  # (face k and k + F/2 are the quad of ring i, side j)
    hole = (i >= 28) & (i < 36) & (j < 6)
    keep = ~np.concatenate([hole, hole])
    tube = extract_centerline(trimesh.Trimesh(v, f[keep], process=False), hubs=25)
    (wall,) = [o for o in tube.openings if o.kind == "wall"]
    found = [w for w in tube_warnings(tube) if "opening" in w]
    assert found == [f"1 opening in the tube's wall ({2.0 * wall.radius:.3g} m across at hub {wall.hub}, of 25 hubs): "
                     "the tube is kept across and its simulated surface closed there (recorded in customData "
                     "warptube:openings)"], found  # fmt: skip
    assert 26 <= wall.hub * 60.0 / 24 <= 40 and 6.0 < 2.0 * wall.radius < 10.0


def test_a_thin_tube_along_its_boxs_diagonal_is_refused_naming_the_voxel_it_needs():
    """A straight tube r = 1 mm, 400 mm long, along the diagonal of its bounding box: the grid's cap
    over that mostly empty box makes voxels wider than the tube; the refusal says so and what to do."""
    v, f = straight_tube(stations=200, ring=24, length=0.4, radius=0.001, caps=False)
    v = v @ trimesh.geometry.align_vectors([1, 0, 0], np.ones(3) / np.sqrt(3))[:3, :3].T
    message = _refusal(lambda: extract_centerline(trimesh.Trimesh(v, f, process=False), source="diag.stl"))
    assert message.startswith("diag.stl: ") and "need voxels of 0.000248" in message, message
    assert "6,000,000 voxels over its bounding box of 0.233 x 0.233 x 0.233 allow only 0.00129" in message, message
    assert "turn the mesh so that the tube lies along an axis" in message, message


def test_an_obj_of_two_coordinate_vertices_is_refused(tmp_cwd, capsys):
    """``v 0 0`` (no z) is a 2-D mesh: one line saying vertices need 3 coordinates, not a NumPy error."""
    (tmp_cwd / "flat.obj").write_text("v 0 0\nv 1 0\nv 0 1\nf 1 2 3\n")
    assert main(["extract", "flat.obj", "-o", "s.usda"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == "warp-tube: flat.obj: vertices with 2 coordinates: vertices must have 3 coordinates (x, y, z)", err
    message = _refusal(lambda: clean_mesh(trimesh.Trimesh(np.zeros((3, 2)), [[0, 1, 2]], process=False), "m"))
    assert message == "m: vertices with 2 coordinates: vertices must have 3 coordinates (x, y, z)", message
    assert sorted(p.name for p in tmp_cwd.iterdir()) == ["flat.obj"]


@pytest.mark.parametrize("make, words", [
    (lambda: (os.symlink("b.ply", "a.ply"), os.symlink("a.ply", "b.ply")), "a.ply: a symbolic link loop"),
    (lambda: os.symlink("/dev/zero", "a.ply"), "a.ply: not a regular file (a device, pipe or socket)"),
    (lambda: os.symlink("gone.ply", "a.ply"), "a.ply: a symbolic link to gone.ply, which does not exist"),
])  # fmt: skip
def test_a_link_loop_or_a_device_is_named_for_what_it_is(make, words, tmp_cwd, capsys):
    make()
    assert main(["extract", "a.ply", "-o", "s.usda"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"warp-tube: {words}") and "no such file" not in err, err
    assert not (tmp_cwd / "s.usda").exists()


@pytest.mark.parametrize("hubs, spokes, words", [
    (1_000_000_000, 16, "--hubs 1,000,000,000: expected at most 1,000,000"),
    (1_000_000, 1024, "--hubs 1,000,000 x --spokes 1024: 1,024,000,000 spokes need about 2097.2 GB of memory"),
])  # fmt: skip
def test_hubs_beyond_what_memory_allows_are_refused_before_any_work(hubs, spokes, words, tmp_cwd, capsys, monkeypatch):
    import warp_tube.extract.command as command

    monkeypatch.setattr(command, "load_mesh", lambda *a: pytest.fail("the mesh was read"))
    monkeypatch.setattr("warp_tube.runtime.memory.available_memory", lambda: 64 * 10**9)
    (tmp_cwd / "m.ply").write_bytes(b"ply\n")
    assert main(["extract", "m.ply", "-o", "s.usda", "--hubs", str(hubs), "--spokes", str(spokes)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"warp-tube: {words}") and len(err.splitlines()) == 1, err
    assert sorted(p.name for p in tmp_cwd.iterdir()) == ["m.ply"]


def test_coordinates_beyond_float32_are_named_without_numpys_warning(tmp_path):
    """An ASCII PLY of float properties holding 3e38 and 1e39: trimesh's cast to float32 overflows
    (inf, with NumPy's RuntimeWarning); the infinite vertex is named, and no warning escapes."""
    import warnings

    from warp_tube.extract.mesh_io import load_mesh
    from warp_tube.scene.spec import SceneError

    path = tmp_path / "big.ply"
    path.write_text("ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
                    "element face 4\nproperty list uchar int vertex_indices\nend_header\n"
                    "0 0 0\n1e39 0 0\n0 1 0\n0 0 1\n3 0 1 2\n3 0 1 3\n3 0 2 3\n3 1 2 3\n")  # fmt: skip
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # (a RuntimeWarning would raise here)
        with pytest.raises(SceneError, match="1 vertex with NaN or infinite coordinates"):
            load_mesh(str(path))


def test_obj_relative_indices_count_back_from_the_vertices_read_so_far(tmp_path):
    """OBJ's negative indices count back from the vertices (texture coordinates, normals) read so
    far: a file writing each triangle's vertices and then ``f -3 -2 -1`` (or ``-3/-3/-3``) is the
    same mesh as one with absolute indices (before: trimesh counted back from the file's last
    vertex, leaving one face)."""
    from warp_tube.extract.mesh_io import load_mesh

    from .test_extract import tube_mesh

    mesh, _, _ = tube_mesh(stations=40, ring=16)
    tri = mesh.vertices[mesh.faces]
    plain = "".join(f"v {x:.17g} {y:.17g} {z:.17g}\n" for x, y, z in mesh.vertices)
    plain += "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in mesh.faces)
    interleaved = "".join("".join(f"v {x:.17g} {y:.17g} {z:.17g}\n" for x, y, z in t) + "f -3 -2 -1\n" for t in tri)
    full = "".join("".join(f"v {x:.17g} {y:.17g} {z:.17g}\nvt 0.5 0.5\nvn 0 0 1\n" for x, y, z in t) + "f -3/-3/-3 -2/-2/-2 -1/-1/-1\n"
                   for t in tri)  # fmt: skip
    loaded = {}
    for name, text in (("plain", plain), ("interleaved", interleaved), ("full", full)):
        (tmp_path / f"{name}.obj").write_text(text)
        loaded[name] = load_mesh(str(tmp_path / f"{name}.obj"))
    for name in ("interleaved", "full"):  # the same surface: the same triangles, welded alike
        assert len(loaded[name].faces) == len(mesh.faces), name
        got = np.sort(loaded[name].vertices[loaded[name].faces].reshape(len(mesh.faces), -1), axis=0)
        want = np.sort(loaded["plain"].vertices[loaded["plain"].faces].reshape(len(mesh.faces), -1), axis=0)
        np.testing.assert_allclose(got, want, atol=1e-12)


@pytest.mark.parametrize("case", ["two closed segments", "a wall inside an open tube"])
def test_a_wall_across_the_tube_is_left_out_and_the_tube_kept_whole(case, caplog):
    """A mesh whose faces meet three to an edge all round the tube: two closed segments of one tube
    exported end to end (their touching caps one wall once welded), or an open tube with a disk
    across its bore on a ring of its wall. The tube's two sides go on through that ring (their
    normals agree), the wall does not: it is left out, named, and the tube extracted whole
    (0.2 m; it fell apart at the wall and one half, 0.1 m, was kept)."""
    if case == "two closed segments":
        a = trimesh.creation.cylinder(radius=0.01, height=0.1, sections=32)
        a.apply_translation([0, 0, 0.05])
        b = a.copy()
        b.apply_translation([0, 0, 0.1])
        mesh = trimesh.util.concatenate([a, b])
    else:  # rings of 32 points at z = 0, 0.1 and 0.2 m, the wall between them, a disk on the middle ring
        n = 32
        t = 2.0 * np.pi * np.arange(n) / n
        verts = np.concatenate([np.c_[0.01 * np.cos(t), 0.01 * np.sin(t), np.full(n, z)] for z in (0.0, 0.1, 0.2)] + [[[0.0, 0.0, 0.1]]])
        faces = []
        for r in (0, 1):
            for j in range(n):
                p, q = r * n + j, r * n + (j + 1) % n
                faces += [[p, q, q + n], [p, q + n, p + n]]
        faces += [[3 * n, n + j, n + (j + 1) % n] for j in range(n)]
        mesh = trimesh.Trimesh(verts, np.asarray(faces), process=False)
    with caplog.at_level(logging.WARNING):
        clean = clean_mesh(mesh, "m.stl")
    said = " ".join(r.getMessage() for r in caplog.records)
    assert "1 piece of them touching it (a wall inside the tube" in said, said
    assert np.ptp(clean.vertices[:, 2]) == pytest.approx(0.2)  # (the whole tube, both sides of the wall)
    extracted = extract_centerline(clean, hubs=21)
    assert extracted.length == pytest.approx(0.2, abs=0.01)  # (end hubs trimmed where a capped end rounds off: within 1 cm)
