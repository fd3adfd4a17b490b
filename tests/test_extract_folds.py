"""Rings at tight folds: spokes fitted to the section between them, and a hairpin whose two legs
nearly touch and whose lumens merge at its apex (as in the jejunum's folds), rebuilt by the
simulator within the fidelity bounds both ways."""

from __future__ import annotations

import numpy as np

from warp_tube.bench.extraction import simulated_surface
from warp_tube.extract.fidelity import FIDELITY_BOUNDS, surface_fidelity
from warp_tube.extract.pipeline import extract_centerline
from warp_tube.extract.sections import fit_polygon

from .test_extract import voxel_surface


def _polygon_hits(lengths: np.ndarray, rays: int) -> np.ndarray:
    """Distances from the origin along ``rays`` directions (angle 2 pi k / rays) to the polygon whose
    corner j lies at ``lengths[j]`` along angle 2 pi j / S: ray-segment intersections solved as
    2 x 2 linear systems, shape (rays,)."""
    spokes = len(lengths)
    corner = lengths[:, None] * np.stack([np.cos(2 * np.pi * np.arange(spokes) / spokes),
                                          np.sin(2 * np.pi * np.arange(spokes) / spokes)], -1)  # fmt: skip
    out = np.empty(rays)
    for k in range(rays):
        d = np.array([np.cos(2 * np.pi * k / rays), np.sin(2 * np.pi * k / rays)])
        j = k * spokes // rays
        a, b = corner[j], corner[(j + 1) % spokes]
        t, _ = np.linalg.solve(np.stack([d, a - b], -1), a)  # t d = a + u (b - a)
        out[k] = t
    return out


def test_fit_polygon_recovers_the_polygon_its_rays_see():
    spokes, m = 16, 4
    phi = 2.0 * np.pi * np.arange(spokes) / spokes
    # Convex polygons (a circle, an oval, a lopsided oval) and a random one.
    true = np.stack([np.ones(spokes), 1.0 + 0.2 * np.cos(2.0 * phi), 1.0 + 0.2 * np.cos(2.0 * phi) + 0.1 * np.sin(phi),
                     np.random.default_rng(3).uniform(0.7, 1.3, spokes)])  # fmt: skip
    t = np.stack([_polygon_hits(row, spokes * m) for row in true])
    # Every ray, the spokes' own exact: the polygon's edges are exactly the fit's model (1 / r linear
    # in 1 / length along an edge), so the fit is the polygon within float round-off.
    exact = fit_polygon(t, np.ones_like(t, dtype=bool), true, m)
    assert np.allclose(exact, true, rtol=1e-9)
    # The rays between the spokes alone (each spoke's own ray missed, its measure 10 % off), convex
    # polygons: only the pull towards the wrong measure (weight FIT_PULL = 0.05 against 1.75 of the
    # six rays next to a spoke) moves the fit off, by about 0.05 / 1.8 x 10 % = 0.3 %.
    valid = np.ones_like(t, dtype=bool)
    valid[:, ::m] = False
    fitted = fit_polygon(t[:3], valid[:3], 1.1 * true[:3], m)
    assert np.abs(fitted / true[:3] - 1.0).max() < 0.005, np.abs(fitted / true[:3] - 1.0).max()


def merged_hairpin(h: float = 0.1, gap: float = 0.3, bulb: float = 1.6, offset: float = 0.4):
    """A blocky (voxel) hairpin of radius 1: two straight legs along x (length 8, centres 2 + gap
    apart), joined by a half torus, with a ball of radius ``bulb`` at its apex (``offset`` beyond
    the torus's centre) where the two lumens merge; flat cut ends."""
    a = 1.0 + 0.5 * gap
    x, y, z = np.meshgrid(np.arange(0, 12, h), np.arange(-a - 2.2, a + 2.2, h), np.arange(-2.2, 2.2, h),
                          indexing="ij")  # fmt: skip
    legs = (x <= 8.0) & (((y - a) ** 2 + z**2 <= 1.0) | ((y + a) ** 2 + z**2 <= 1.0))
    apex = (x >= 8.0) & ((np.hypot(x - 8.0, y) - a) ** 2 + z**2 <= 1.0)
    ball = (x - 8.0 - offset) ** 2 + y**2 + z**2 <= bulb**2
    return voxel_surface(legs | apex | ball, h)


def test_hairpin_with_merged_apex_meets_the_bounds():
    mesh = merged_hairpin()
    tube = extract_centerline(mesh)
    fid = surface_fidelity(tube, mesh, surface=simulated_surface(tube))
    # At the apex the centred axis turns about a line inside the merged lumen: rings normal to it
    # would cross, and the simulator's inner-bend guard cut them (p99 15.2 % surface to mesh, 16.1 %
    # mesh to surface before the hubs there were moved and the spokes fitted). The README's bounds:
    # mean <= 4 %, p99 <= 15 %, max <= 40 % of the mean radius, both ways.
    assert fid.to_surface.within(*FIDELITY_BOUNDS), fid.to_surface
    assert fid.to_input.within(*FIDELITY_BOUNDS), fid.to_input
    assert sorted(e.kind for e in tube.ends) == ["cut", "cut"]
    assert max(fid.end_ratios) <= 1.5, fid.end_ratios
