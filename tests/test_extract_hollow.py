"""A hollow tube (a hose: a wall around a bore) is extracted as the solid tube of its outer wall.

Oracle: each hose is built here with trimesh (trimesh's annulus, or two cylinder walls), finely
subdivided and bent onto an arc (1 radian) of a circle of known radius, so its axis (an arc) and outer radius are
known exactly from the construction.
"""

from __future__ import annotations

import logging

import numpy as np
import pytest
import trimesh

from warp_tube.extract.pipeline import extract_centerline

OUTER, INNER, LENGTH, BEND = 0.01, 0.008, 0.3, 0.3  # m: radii, length, bend radius of the axis


def _bent(m: trimesh.Trimesh) -> trimesh.Trimesh:
    """``m`` (along z, centred at 0), its edges split to 6 mm at most and bent onto an arc of radius BEND in the xz-plane."""
    v, f = trimesh.remesh.subdivide_to_size(m.vertices, m.faces, max_edge=0.006)
    th = (v[:, 2] + 0.5 * LENGTH) / BEND
    bent = np.stack([(BEND + v[:, 0]) * np.cos(th) - BEND, v[:, 1], (BEND + v[:, 0]) * np.sin(th)], 1)
    return trimesh.Trimesh(bent, f, process=False)


def _walls(radius: float) -> trimesh.Trimesh:
    """The side wall of a closed cylinder (its flat caps removed)."""
    c = trimesh.creation.cylinder(radius=radius, height=LENGTH, sections=48)
    c.update_faces(np.abs(c.face_normals[:, 2]) < 0.5)
    c.remove_unreferenced_vertices()
    return c


def _hose(kind: str) -> trimesh.Trimesh:
    if kind == "rims":  # one closed surface: outer and inner walls joined by flat rings at the ends
        return _bent(trimesh.creation.annulus(r_min=INNER, r_max=OUTER, height=LENGTH, sections=48))
    if kind == "walls":  # two open walls, the inner one facing the bore
        inner = _walls(INNER)
        inner.invert()
        return _bent(trimesh.util.concatenate([_walls(OUTER), inner]))
    return _bent(trimesh.creation.cylinder(radius=OUTER, height=LENGTH, sections=48))  # solid


@pytest.mark.parametrize("kind", ["rims", "walls", "solid"])
def test_a_hose_is_extracted_on_its_axis_with_its_outer_radius(kind, caplog):
    """The hubs lie on the bent axis and the spokes reach the outer wall, as for the solid tube of
    the same outer shape; the hollow ones are warned of with the bore's size (the walls' area ratio,
    INNER / OUTER = 0.8). Before, the annulus' axis was a thread inside its wall (radius 1.6-1.8 mm,
    "a closed ring cut open").

    Tolerances: radius within 3% of OUTER (the 48-gon's area radius is 0.9986 OUTER; the rebuilt
    surface's fit bound is 4% of the radius on average); hubs within 5% of OUTER of the arc (the
    extraction's centring on a faceted wall)."""
    with caplog.at_level(logging.WARNING, logger="warp_tube"):
        tube = extract_centerline(_hose(kind), hubs=21)
    pts = np.asarray(tube.points)
    off_axis = np.hypot(np.hypot(pts[:, 0] + BEND, pts[:, 2]) - BEND, pts[:, 1])
    assert off_axis.max() < 0.05 * OUTER, off_axis.max()
    r = np.asarray(tube.radius)
    assert abs(r.mean() / OUTER - 1.0) < 0.03, r.mean()
    hollow = [rec.getMessage() for rec in caplog.records if "a hollow tube" in rec.getMessage()]
    if kind == "solid":
        assert not hollow
        return
    assert len(hollow) == 1, hollow
    assert "bore about 0.80 of the outer radius" in hollow[0]  # area ratio: the radii's, equal lengths
    assert ("joined by flat rims" in hollow[0]) == (kind == "rims")
    assert all(e.kind == "open" for e in tube.ends)  # the rims' removal leaves the outer wall open


def test_a_speck_inside_a_tube_is_no_bore(caplog):
    """A small closed piece inside a tube (a segmentation's floater in the lumen) is no bore: its
    area is under BORE_AREA of the wall's. It is left out as any smaller component, and no
    hollow tube is reported."""
    speck = trimesh.creation.icosphere(subdivisions=2, radius=0.2 * OUTER)
    speck.apply_translation([-BEND * (1 - np.cos(0.5)), 0.0, BEND * np.sin(0.5)])  # the axis' middle
    m = trimesh.util.concatenate([_hose("solid"), speck])
    with caplog.at_level(logging.WARNING, logger="warp_tube"):
        tube = extract_centerline(m, hubs=21)
    assert not [rec for rec in caplog.records if "a hollow tube" in rec.getMessage()]
    assert abs(np.asarray(tube.radius).mean() / OUTER - 1.0) < 0.03


def test_a_finely_meshed_torus_has_no_flat_rims():
    """A torus cut into 840 sections round the ring: faces beside each other along it are within 1
    degree and their planes a hair apart, so the bands at its top and bottom read as flat rings
    face by face (before: "a hollow tube joined by flat rims", a 4 mm tube across the ring, or a
    crash). A rim is flat as a whole: these bands turn right round the ring, so it is no hollow tube."""
    from warp_tube.extract.hollow import outer_wall

    torus = trimesh.creation.torus(major_radius=0.035, minor_radius=0.005, major_sections=840, minor_sections=32)
    assert torus.is_watertight and torus.euler_number == 0
    mesh, bore = outer_wall(torus, "torus")
    assert bore is None and mesh is torus


def test_recentring_hubs_nearly_on_top_of_each_other_keeps_a_finite_smoothing():
    """Hubs far closer together than the smoothing length gave a Gaussian wider than memory allows
    (ValueError: Maximum allowed size exceeded): the width is capped at the number of hubs."""
    from warp_tube.extract.loops import boundary_loops, cap_loops
    from warp_tube.extract.queries import MeshQueries
    from warp_tube.extract.sections import recentre_hubs

    m = _hose("solid")
    v, f = cap_loops(m, boundary_loops(m))
    q = MeshQueries(v, f, v, f, "cpu")
    hubs = np.stack([np.zeros(12), np.zeros(12), np.linspace(0.0, 1e-12, 12)], axis=1)  # 1e-13 m apart
    out = recentre_hubs(q, hubs, diag=float(np.linalg.norm(np.ptp(m.vertices, axis=0))), scale=0.5 * OUTER)
    assert out.shape == hubs.shape and np.isfinite(out).all()
