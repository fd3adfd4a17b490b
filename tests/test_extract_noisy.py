"""Centerline extraction on rough walls: tubes whose vertices carry noise of about an edge length.

Scanned and segmented meshes (CT segmentations, marching-cubes staircases) have such walls. The
oracle is the exact geometry before the noise: a tube of radius ``R`` about the z axis, from
``z = -L / 2`` to ``L / 2`` (open, or closed by hemispheres), meshed with edges of about ``R / 10``
(or ``R / 5``), every vertex then moved along its normal (or in any direction) by a seeded normal
deviate of ``sigma R``. Before :mod:`warp_tube.extract.scale`, chords from such a wall crossed its
folds, the radius estimate fell to a tenth of ``R`` or less, and extraction took minutes and put
hundreds of hubs.
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from warp_tube.extract.mesh_io import boundary_loops, cap_loops, clean_mesh, flat_cuts
from warp_tube.extract.pipeline import extract_centerline
from warp_tube.extract.queries import MeshQueries
from warp_tube.extract.scale import tube_scale

R = 5.0
L = 60.0


def revolve(profile, around: int) -> trimesh.Trimesh:
    """Surface of revolution about z of the profile rows ``(rho, z)``; a row with ``rho == 0`` is a pole."""
    verts, rings = [], []
    theta = 2.0 * np.pi * np.arange(around) / around
    for rho, z in profile:
        if rho <= 1e-9:
            rings.append([len(verts)])
            verts.append((0.0, 0.0, z))
        else:
            rings.append(list(range(len(verts), len(verts) + around)))
            verts += [(rho * np.cos(t), rho * np.sin(t), z) for t in theta]
    faces = []
    for a, b in zip(rings[:-1], rings[1:]):
        for j in range(around):
            j1 = (j + 1) % around
            if len(a) == 1:
                faces.append((a[0], b[j], b[j1]))
            elif len(b) == 1:
                faces.append((a[j], b[0], a[j1]))
            else:
                faces += [(a[j], b[j1], b[j]), (a[j], a[j1], b[j1])]
    return trimesh.Trimesh(np.asarray(verts), np.asarray(faces), process=False)


def tube(edge: float, capsule: bool) -> trimesh.Trimesh:
    """The exact tube (see the module), edges of about ``edge``."""
    straight = L / 2 - (R if capsule else 0.0)
    z = np.linspace(-straight, straight, round(2 * straight / edge) + 1)
    profile = [(R, zi) for zi in z]
    if capsule:
        a = np.linspace(0.0, 0.5 * np.pi, round(0.5 * np.pi * R / edge) + 1)[:-1]
        cap = [(R * np.sin(x), -straight - R * np.cos(x)) for x in a]
        profile = cap + profile + [(rho, -zi) for rho, zi in cap[::-1]]
    return revolve(profile, round(2 * np.pi * R / edge))


def noisy(mesh: trimesh.Trimesh, sigma: float, seed: int, isotropic: bool = False) -> trimesh.Trimesh:
    """``mesh`` with every vertex moved by a normal deviate of ``sigma R``: along its normal, or in any direction."""
    rng = np.random.default_rng(seed)
    v = np.array(mesh.vertices)
    if isotropic:
        v += rng.normal(0.0, sigma * R, v.shape)
    else:
        v += np.asarray(mesh.vertex_normals) * rng.normal(0.0, sigma * R, len(v))[:, None]
    return trimesh.Trimesh(v, mesh.faces, process=False)


def figures(t):
    """Mean spoke length over R and the hubs' distances from the z axis over R, of the hubs more than
    1.5 R from either tip (a capsule's hubs nearer its tips have shorter spokes by design)."""
    inner = np.abs(t.points[:, 2]) < L / 2 - 1.5 * R
    return float(t.spoke_lengths[inner].mean() / R), np.linalg.norm(t.points[inner, :2], axis=1) / R


def scale_of(mesh: trimesh.Trimesh):
    m = clean_mesh(mesh, "<test>")
    lo, hi = m.bounds
    diag = float(np.linalg.norm(hi - lo))
    v, f = cap_loops(m, boundary_loops(m))
    q = MeshQueries(v, f, v, f, "cpu")
    return tube_scale(q, q.inner_diameters(m, 2.0 * diag), lo, hi, diag)


def test_a_smooth_wall_keeps_the_chords_from_it():
    s = scale_of(tube(0.5, capsule=False))
    # Chords from a smooth wall are the diameters (the 63-gon's inscribed circle: 0.1 % short).
    assert not s.rough and s.kept == s.chords
    assert s.median == pytest.approx(R, rel=0.01) and s.narrow == pytest.approx(R, rel=0.01)
    # The width from inside (lower quartile of chords through points spread over the inside) is
    # 0.75 to 0.95 of the radius; the wall counts as rough below a quarter of it.
    assert 0.75 * R < s.width < 0.95 * R


def test_a_rough_wall_is_measured_past_its_folds():
    s = scale_of(noisy(tube(0.5, capsule=False), 0.1, seed=1))
    # Noise of one edge (a tenth of R): about 40 % of the chords from the wall cross a fold, and
    # their 10th percentile is 0.05 R. Kept, the chords as long as the width give the radius to
    # within the reach of the noise's folds (two sigma).
    assert s.rough and 0 < s.kept < s.chords
    assert 0.8 * R < s.median < 1.1 * R and s.narrow > 0.4 * R


@pytest.mark.parametrize(
    "capsule, edge, sigma, isotropic, seed",
    [
        (False, 0.5, 0.10, False, 2),  # open ends, noise of one edge along the normals
        (True, 0.5, 0.20, False, 3),  # closed ends, noise of two edges: spikes reach half-way in
        (True, 0.5, 0.10, True, 4),  # closed ends, noise in any direction (folds over its neighbours)
        (True, 1.0, 0.20, False, 5),  # coarser mesh, noise of one edge
    ],
)
def test_noisy_tubes_extract_about_their_true_axis_and_radius(capsule, edge, sigma, isotropic, seed):
    clean = extract_centerline(tube(edge, capsule))
    t = extract_centerline(noisy(tube(edge, capsule), sigma, seed, isotropic))
    spoke, axis = figures(t)
    # The noise has mean zero, so the wall's mean radius is R; spokes hit the first crossing of the
    # wall (its inward folds) and are fitted between them (outward bulges): within 10 % of R (1 to
    # 5 % long on these and on seeds 10 to 15).
    assert spoke == pytest.approx(1.0, abs=0.1)
    # A hub is the centroid of its section's ray hits, each off the true wall by ~sigma R, the moves
    # smoothed along the tube: the mean distance from the true axis within 0.08 R (0.014 to 0.062 R
    # on seeds 10 to 15), the largest of the 15 to 40 hubs within 0.25 R (up to 0.19 R where spikes
    # of the noise reach half-way to the axis).
    assert axis.max() < 0.25 and axis.mean() < 0.08
    # The radius estimate sets the voxel size: a quarter of the narrow radius on the clean tube,
    # and not less than a quarter of that here (0.32 to 0.65 of it; it was a twentieth of it or
    # less, with millions of voxels and minutes of Dijkstra).
    assert t.voxel_size > clean.voxel_size / 4.0
    # More hubs only follow the noise: tries stop when one gains less than 10 %. The noisy end rings'
    # lopsidedness adds a try or two: up to 4.1 times the clean count on seeds 10 to 15 (up to 30
    # times, hundreds of hubs, before).
    assert t.hubs <= 5 * clean.hubs
    # A noisy rounded tip is trimmed where its dome starts, or capped: the tube spans L within 8 %.
    assert t.tip_to_tip == pytest.approx(L, rel=0.08)


def test_faces_of_a_rough_wall_are_no_flat_cuts():
    m = noisy(tube(1.0, capsule=True), 0.2, seed=6, isotropic=True)
    # Every face of such a wall is a coplanar group of its own, many with an area over a tenth of
    # the least seal's: none is a seal (and merging them pairwise took a second).
    assert flat_cuts(m, 0.25 * np.pi * (0.7 * R) ** 2) == []
    # A real seal (a fan of coplanar faces) still is one.
    capped = tube(1.0, capsule=False)
    v, f = cap_loops(capped, boundary_loops(capped))
    cuts = flat_cuts(trimesh.Trimesh(v, f, process=False), 0.25 * np.pi * R**2)
    assert len(cuts) == 2 and all(c.area == pytest.approx(np.pi * R**2, rel=0.01) for c in cuts)


@pytest.mark.parametrize("seed", [0, 1])
def test_a_noisy_helix_is_followed_turn_by_turn(seed):
    """A helix of radius 10 and pitch 8 (two turns) of a tube of radius 1, 32 vertices around,
    every vertex moved by a normal deviate of 0.1 in any direction (half an edge: faces fold over
    each other). Crossing parity along one axis took a streak outside the tube for inside where a
    column crossed such folds; between the turns such a streak let the centreline cut across them
    (a 127-long tube came out 17-51 long). The inside is now the vote of three axes: the tube is
    followed turn by turn. Bounds: the length within 2% (the noise roughens the traced path by
    less), the hubs within 0.25 radii of the true axis (the noise moves the wall by 0.1 radius, the
    sections' centres by less; measured 0.11-0.12)."""
    from warp_tube.bench.synthetic_tubes import sweep_mesh

    a = np.linspace(0.0, 4.0 * np.pi, 600)
    axis = np.stack([10.0 * np.cos(a), 10.0 * np.sin(a), 8.0 * a / (2.0 * np.pi)], 1)
    tangents = np.gradient(axis, axis=0)
    tangents /= np.linalg.norm(tangents, axis=1)[:, None]
    mesh = sweep_mesh(axis, tangents, np.ones(len(axis)), ("open", "open"), ring=32)
    noisy = mesh.vertices + np.random.default_rng(seed).normal(0.0, 0.1, mesh.vertices.shape)
    tube = extract_centerline(trimesh.Trimesh(noisy, mesh.faces, process=False))
    true_length = float(np.linalg.norm(np.diff(axis, axis=0), axis=1).sum())
    assert abs(tube.tip_to_tip / true_length - 1.0) < 0.02, (tube.tip_to_tip, true_length)
    off_axis = np.linalg.norm(tube.points[:, None] - axis[None], axis=-1).min(axis=1)
    assert off_axis.max() < 0.25, off_axis.max()
