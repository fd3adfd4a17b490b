"""Closed ends of tubes with rough walls: rounded tips capped, flat cuts trimmed, open ends open.

The meshes: a capsule of radius ``R = 5`` (trimesh's, 40 long tip to tip, edges subdivided to 1,
about R / 5) and a straight tube of the same radius and 60 long, open or sealed by flat fans at
both ends, every vertex then moved along its normal by a seeded normal deviate of ``sigma R``
(sigma 0.1 or 0.2: noise of one or two edge lengths). On such a wall the nearest point is the tip
of its deepest inward spike and the wall folds: the end's radius is measured by the median of rays
round the line's first radii, not by the distance from the wall; the end of the centred voxel path
is cut back until it reaches the tube's width rather than its own (a path to the farthest voxel of
a rough tip ends in a fold of it, a channel about as wide as the noise); and a flat patch of the
wall is a seal only where the inside lies on one side of it (the capsule's folds in the planes
through its axis are flat, and lie in the wall). Capped, a rounded tip ends within a noise's
reach of the mesh's tip and its end hub about one radius in.
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from warp_tube.extract.mesh_io import boundary_loops, cap_loops
from warp_tube.extract.pipeline import extract_centerline

R = 5.0


def noisy(mesh: trimesh.Trimesh, sigma: float, seed: int) -> trimesh.Trimesh:
    """``mesh`` with every vertex moved along its normal by a normal deviate of ``sigma R``."""
    rng = np.random.default_rng(seed)
    v = np.array(mesh.vertices)
    v += np.asarray(mesh.vertex_normals) * rng.normal(0.0, sigma * R, (len(v), 1))
    return trimesh.Trimesh(v, mesh.faces, process=False)


def capsule() -> trimesh.Trimesh:
    """A capsule 40 long tip to tip, edges of at most 1."""
    return trimesh.creation.capsule(height=30.0, radius=R, count=[32, 32]).subdivide_to_size(1.0)


def straight(sealed: bool) -> trimesh.Trimesh:
    """An open tube 60 long (32 sides, rings 1 apart), or one sealed by flat fans, edges of at most 1."""
    z = np.linspace(-30.0, 30.0, 61)
    theta = 2.0 * np.pi * np.arange(32) / 32
    v = np.stack([np.repeat(R * np.cos(theta)[None], 61, 0), np.repeat(R * np.sin(theta)[None], 61, 0),
                  np.repeat(z[:, None], 32, 1)], axis=-1).reshape(-1, 3)
    f = []
    for i in range(60):
        for j in range(32):
            a, b, c, d = i * 32 + j, i * 32 + (j + 1) % 32, (i + 1) * 32 + j, (i + 1) * 32 + (j + 1) % 32
            f += [(a, b, d), (a, d, c)]
    m = trimesh.Trimesh(v, np.asarray(f), process=False)
    if sealed:
        m = trimesh.Trimesh(*cap_loops(m, boundary_loops(m)), process=False).subdivide_to_size(1.0)
    return m


@pytest.mark.parametrize("sigma, seed", [(0.1, 0), (0.1, 3), (0.2, 0), (0.2, 1), (0.2, 2), (0.2, 3)])
def test_noisy_rounded_tips_are_capped(sigma, seed):
    t = extract_centerline(noisy(capsule(), sigma, seed))
    # The wall's radius is measured by the median of rays round the end (noise of mean zero), and
    # the cap is judged on it: the best cap misses these tips by 0.10 to 0.15 of it (the clean
    # capsule's by 0.001), within the tolerance of 0.2.
    assert [e.kind for e in t.ends] == ["closed", "closed"]
    # Capped, the tube spans the capsule tip to tip (40) within a noise's reach of each tip (2 sigma R).
    assert t.tip_to_tip == pytest.approx(40.0, abs=4.0 * sigma * R)
    # The end hubs lie about one radius in from the tips, as on a hemisphere.
    for e in t.ends:
        assert 0.5 * R < e.trimmed < 1.6 * R


def test_a_clean_capsule_is_capped_as_before():
    t = extract_centerline(capsule())
    assert [e.kind for e in t.ends] == ["closed", "closed"]
    assert t.tip_to_tip == pytest.approx(40.0, abs=0.05)


@pytest.mark.parametrize("sigma, seed", [(0.1, 1), (0.1, 2), (0.2, 1), (0.2, 3)])
def test_noisy_flat_cuts_stay_cut(sigma, seed):
    t = extract_centerline(noisy(straight(sealed=True), sigma, seed))
    # The noise keeps every ray hit 0.1 R or so off the seal's plane, so the flat-cut test of a
    # smooth wall (hits within 0.03 end radii of a plane) fails, and a cap would fit it within the
    # tolerance as well (0.13 to 0.18 of the radius). What tells a flat cut on a rough wall is that
    # the tube keeps its width up to it: the median ray half-way from the end hub to the seal is
    # a mean of 0.98 to 1.02 (at sigma 0.2: 0.90 to 1.02) of the radius on rings 0.4 to 0.6 R before
    # it (a rounded tip's: 0.82 to 0.88, at 0.2: 0.65 to 0.85); a cut needs 0.93. An end judged so
    # is sealed, its normal along the tube (within 8 degrees: the noise tilts the line).
    assert [e.kind for e in t.ends] == ["cut", "cut"]
    for e in t.ends:
        assert e.seal is None or abs(e.seal[1][2]) > 0.99
    if sigma == 0.1:
        assert all(e.seal is not None for e in t.ends)


def test_noisy_open_ends_stay_open():
    t = extract_centerline(noisy(straight(sealed=False), 0.2, 1))
    assert [e.kind for e in t.ends] == ["open", "open"]


@pytest.mark.parametrize("sigma", [0.2, 0.25])
def test_a_very_rough_capsule_is_measured_on_its_smoothed_copy(sigma):
    """Spikes of half a radius (noise of 0.2-0.25 R on edges of R / 5) cut the widths from inside
    short as well as the chords from the wall: the wall alone gives a fraction of the radius (1.8
    and 0.7 of 5 for seed 0), its copy smoothed by Taubin's filter the radius."""
    from warp_tube.extract.mesh_io import clean_mesh
    from warp_tube.extract.queries import MeshQueries
    from warp_tube.extract.scale import rough_scale, tube_scale

    m = clean_mesh(noisy(capsule(), sigma, 0), "<test>")
    lo, hi = m.bounds
    diag = float(np.linalg.norm(hi - lo))
    v, f = cap_loops(m, boundary_loops(m))
    q = MeshQueries(v, f, v, f, "cpu")
    wall = tube_scale(q, q.inner_diameters(m, 2.0 * diag), lo, hi, diag)
    assert wall.rough and wall.median < 0.5 * R  # (the wall's own chords and widths: far short)
    s = rough_scale(wall, v, f, lo, hi, diag, "cpu")
    # Ten passes of Taubin's filter take the noise and keep the tube: the median radius within 20 %
    # of R (the chords of the rounded tips and what noise the filter leaves shorten it: 4.3 of 5),
    # the narrow one above 0.4 R; the wall stays rough for what follows.
    assert s.rough and 0.8 * R < s.median < 1.05 * R and s.narrow > 0.4 * R
