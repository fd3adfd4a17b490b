"""Extraction of flattened tubes (collapsed vessels, bowel): elliptic sections of aspect 2 to 5.

Oracle: each mesh is an elliptic tube built here around a known axis (a straight line or a quarter
circle) with the section's semi-axes along known directions, so the distance from a hub along any
spoke direction to the wall is known exactly (:func:`exact_spokes`, by bisection on the ellipse's
equation in the section of the nearest axis point).
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from warp_tube.extract.fidelity import FIDELITY_BOUNDS
from warp_tube.extract.flat import MAX_ASPECT, polygon_axes
from warp_tube.extract.pipeline import extract_centerline
from warp_tube.extract.tube_check import tube_warnings

A = 0.005  # long semi-axis [m]
LENGTH = 0.1


def elliptic_tube(aspect: float, bent: bool, roll: float = 0.0, stations: int = 200, ring: int = 64):
    """An open tube of semi-axes ``A`` and ``A / aspect``, ``LENGTH`` long: straight along x, or a
    quarter circle in the xy plane; the long axis in the bending plane, turned by ``roll`` [rad]."""
    u = np.linspace(0.0, 1.0, stations)
    if bent:
        rc, th = 2.0 * LENGTH / np.pi, 0.5 * np.pi * u
        c = np.stack([rc * np.sin(th), rc * (1.0 - np.cos(th)), 0.0 * u], 1)
        n = np.stack([-np.sin(th), np.cos(th), 0.0 * u], 1)
    else:
        c = np.stack([LENGTH * u, 0.0 * u, 0.0 * u], 1)
        n = np.tile([0.0, 1.0, 0.0], (stations, 1))
    z = np.tile([0.0, 0.0, 1.0], (stations, 1))
    n, b = np.cos(roll) * n + np.sin(roll) * z, -np.sin(roll) * n + np.cos(roll) * z
    phi = 2.0 * np.pi * np.arange(ring) / ring
    v = c[:, None] + A * np.cos(phi)[None, :, None] * n[:, None] + (A / aspect) * np.sin(phi)[None, :, None] * b[:, None]
    i, j = np.meshgrid(np.arange(stations - 1), np.arange(ring), indexing="ij")
    p, q = i * ring + j, i * ring + (j + 1) % ring
    f = np.concatenate([np.stack([p, q, q + ring], -1).reshape(-1, 3), np.stack([p, q + ring, p + ring], -1).reshape(-1, 3)])
    return trimesh.Trimesh(v.reshape(-1, 3), f, process=False)


def exact_spokes(tube, aspect: float, bent: bool, roll: float = 0.0) -> np.ndarray:
    """Distance from each hub along each of its spoke directions to the elliptic wall, (hubs, S)."""
    d, p = tube.spoke_directions(), tube.points

    def section(x):  # coordinates along the long and short axes of the nearest axis point's section
        if bent:
            rc = 2.0 * LENGTH / np.pi
            un, ub = rc - np.hypot(x[..., 0], x[..., 1] - rc), x[..., 2]
        else:
            un, ub = x[..., 1], x[..., 2]
        return np.cos(roll) * un + np.sin(roll) * ub, -np.sin(roll) * un + np.cos(roll) * ub

    lo, hi = np.zeros(d.shape[:2]), np.full(d.shape[:2], 2.0 * A)
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        x, y = section(p[:, None] + mid[..., None] * d)
        inside = (x / A) ** 2 + (y * aspect / A) ** 2 < 1.0
        lo, hi = np.where(inside, mid, lo), np.where(inside, hi, mid)
    return 0.5 * (lo + hi)


@pytest.mark.parametrize("bent", [False, True], ids=["straight", "quarter_arc"])
@pytest.mark.parametrize("aspect", [2.0, 4.0, 5.0])
def test_flat_sections_have_spokes_on_the_ellipse(aspect, bent):
    """32 spokes follow an elliptic section of aspect 2, 4 and 5: no spoke clipped to the ring's
    mean (the long spokes were 20-60 % short at aspect 4), no side branch at the open ends'
    corners, no ray counted as missing the wall, and the rest surface within the README's bounds."""
    tube = extract_centerline(elliptic_tube(aspect, bent), spokes=32)
    err = tube.spoke_lengths / exact_spokes(tube, aspect, bent) - 1.0
    # The spokes are fitted so that the ring's polygon runs through the wall between them (corners
    # just outside it): on an ellipse of aspect 5 that lengthens the spokes next to the short axis
    # by up to 4.2 % (a 2-D fit of the exact section gives the same); 5 % leaves room for the mesh's facets.
    assert np.abs(err).max() < 0.05, (np.abs(err).max(), np.unravel_index(np.abs(err).argmax(), err.shape))
    # and none is shorter than the wall along it by more than the facets' sag (64 per ring: 0.3 % of A)
    # and the hub's placement (1 %)
    assert err.min() > -0.015, err.min()
    assert tube.branches == []
    assert tube.missed_spokes == 0
    assert not any("openings" in w or "too flat" in w for w in tube.warnings + tube_warnings(tube, tube.fidelity))
    assert tube.fidelity.within(*FIDELITY_BOUNDS), tube.fidelity
    assert abs(tube.aspect - aspect) < 0.05 * aspect  # 64 rays' polygon: within 1 % at aspect 5


def test_spokes_are_turned_onto_the_long_axis():
    """A 4:1 section turned 3 degrees (or 11 degrees, half a gap of 16 spokes) about the axis is
    followed as well as one with its long axis on the package's reference normal: the extraction
    turns the spokes so that one lies along the long axis (half a gap off it, a 16-spoke ring
    misses the section by 21 % of the radius at the 99th percentile, over the 15 % bound)."""
    for roll in np.radians([3.0, 11.25]):
        tube = extract_centerline(elliptic_tube(4.0, False, roll), hubs=30)
        err = tube.spoke_lengths / exact_spokes(tube, 4.0, False, roll) - 1.0
        # 16 spokes fitted through a 4:1 ellipse: the spokes beside the short axis 8.8 % long (2-D fit)
        assert np.abs(err).max() < 0.1, (roll, np.abs(err).max())
        assert tube.fidelity.p99 < FIDELITY_BOUNDS[1]
        assert tube.branches == [] and tube.missed_spokes == 0


def test_a_section_flatter_than_supported_is_named_too_flat():
    """A 12:1 section (semi-axes 5 and 0.42 mm) is warned of as too flat, with its measured aspect,
    and not as a mesh with openings."""
    tube = extract_centerline(elliptic_tube(12.0, False), hubs=40)
    found = tube.warnings + tube_warnings(tube, tube.fidelity)
    flat = [w for w in found if "too flat" in w]
    assert len(flat) == 1 and f"supported up to {MAX_ASPECT:g}:1" in flat[0], found
    assert not any("openings" in w for w in found), found
    assert tube.aspect > MAX_ASPECT


def test_polygon_axes_of_an_ellipse():
    """The aspect and long axis of a polygon of rays to an ellipse of aspect 3 turned by 0.4 rad:
    within 0.5 % and 0.01 rad (256 rays: the inscribed polygon's moments differ from the ellipse's
    by about (2 pi / 256)^2)."""
    phi = 2.0 * np.pi * np.arange(256) / 256
    x = phi - 0.4
    t = 1.0 / np.sqrt(np.cos(x) ** 2 + 9.0 * np.sin(x) ** 2)
    aspect, angle = polygon_axes(t[None])
    assert abs(aspect[0] - 3.0) < 0.015 and abs(angle[0] - 0.4) < 0.01
    round_aspect, _ = polygon_axes(np.ones((1, 32)))
    assert abs(round_aspect[0] - 1.0) < 1e-9


def test_flat_sections_get_32_spokes_where_none_are_asked_for(caplog):
    """16 spokes evenly spaced cannot follow a 4:1 ellipse (the rest surface missed it by 4.0% of
    the radius on average, the fit's bound 4%): where no count is asked for, sections flatter than
    3.5:1 get 32 and fit within the bounds without a warning; round ones keep 16, and a count
    asked for is kept."""
    import logging

    from warp_tube.extract.flat import FLAT_SPOKES, SPOKES

    with caplog.at_level(logging.WARNING, logger="warp_tube"):
        flat = extract_centerline(elliptic_tube(4.0, False))
    assert flat.spokes == FLAT_SPOKES and not [r for r in caplog.records if "misses the mesh" in r.getMessage()]
    assert extract_centerline(elliptic_tube(2.0, False)).spokes == SPOKES
    assert extract_centerline(elliptic_tube(4.0, False), spokes=16).spokes == 16
