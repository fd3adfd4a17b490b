"""Centerline extraction on the synthetic tubes of warp_tube.bench.synthetic_tubes: hubs on the true
axis, and the frame-0 Surface of the written scene (built through the public API, inner-bend guard
and caps included) against the input mesh, both ways.

Oracle: each mesh is the sweep of circles of known radius normal to a known curve (integrated from
prescribed curvature and torsion), so every normal cross-section is centred on the curve and the
distance of a hub from the curve, over the local radius, is its centring error.
"""

from __future__ import annotations

import numpy as np
import pytest

from warp_tube.bench.extraction import simulated_surface
from warp_tube.bench.synthetic_tubes import check_case, frenet_curve, synthetic_cases
from warp_tube.extract.fidelity import FIDELITY_BOUNDS, surface_fidelity
from warp_tube.extract.pipeline import extract_centerline
from warp_tube.extract.polyline import arclength, project_points
from warp_tube.extract.tubelike import NOT_A_TUBE

CASES = synthetic_cases()
BY_NAME = {c.name: c for c in CASES}


def centring_errors(tube, case):
    """Distance of each interior hub from the true curve over the true radius there, shape (hubs - 2,)."""
    d, arc = project_points(tube.points[1:-1], case.curve)
    return d / np.interp(arc, arclength(case.curve), case.radius)


def test_the_synthetic_set_is_varied_and_valid():
    assert len(CASES) >= 20
    for case in CASES:
        assert check_case(case) is None
    rk = np.array([np.max(c.radius * np.abs(c.curvature)) for c in CASES])
    torsion = np.array([np.max(np.abs(c.torsion) * c.radius) for c in CASES])
    taper = np.array([np.ptp(c.radius) / c.radius.mean() for c in CASES])
    # Straight to tight (radius x curvature 0 to about 0.8), planar and twisted, constant and varying
    # radius, open, flat-capped and round-capped ends.
    assert rk.min() == 0.0 and rk.max() > 0.75 and (rk > 0.5).sum() >= 8
    assert (torsion == 0.0).sum() >= 4 and (torsion > 0.2).sum() >= 4
    assert (taper == 0.0).sum() >= 2 and (taper > 0.3).sum() >= 8
    kinds = {k for c in CASES for k in c.ends}
    assert kinds == {"open", "flat", "round"}


def test_frenet_curve_has_the_prescribed_curvature():
    # A helix of curvature k and torsion t has radius k / (k^2 + t^2) about its axis.
    k, t = 0.5, 0.3
    _, x, _ = frenet_curve(lambda s: k + 0.0 * s, lambda s: t + 0.0 * s, 20.0, step=0.005)
    # The axis is along the Darboux vector; points lie at the helix radius from it.
    axis_dir = np.array([t, 0.0, k]) / np.hypot(k, t)  # Darboux vector t T + k B at s = 0 (T = x, B = z)
    centre = np.array([0.0, k / (k * k + t * t), 0.0])  # the axis passes through x0 + N / curvature-of-helix
    rel = x - centre
    radial = rel - (rel @ axis_dir)[:, None] * axis_dir
    # RK4 with step 0.005 over 20: the radius holds to ~1e-6 of it; 1e-4 leaves room for the
    # trapezoidal position integration.
    assert np.allclose(np.linalg.norm(radial, axis=1), k / (k * k + t * t), rtol=1e-4)


@pytest.mark.parametrize("spokes", [3, 4, 16, 64])
def test_the_section_radius_of_area_fitted_spokes_is_the_circles(spokes):
    """Spokes fitted to a circle of radius r so that their polygon has its area (as the extraction
    fits them to the wall between the spokes) are r sqrt(2 pi / (S sin(2 pi / S))) long: 1.55 r for
    3 spokes. The widths took their mean, so the tube's mass and stiffness depended on --spokes
    (EI x5.8 at 3 spokes); the section radius is r for any S (exact up to float64 round-off)."""
    from warp_tube.extract.usd import section_radius

    r = 0.004
    s = r * np.sqrt(2.0 * np.pi / (spokes * np.sin(2.0 * np.pi / spokes)))
    np.testing.assert_allclose(section_radius(np.full((5, spokes), s)), r, rtol=1e-12)


def test_extracted_widths_hardly_depend_on_the_spokes(tmp_path):
    """A cylinder (r = 5 mm, 200 mm) extracted with 4 and with 16 spokes: the widths written are
    2 r within 2.5% both (the wall's own fit between the spokes: 1.6% at 4 spokes); they were the
    mean spoke lengths, 1.27 r at 4."""
    import trimesh
    from pxr import Usd

    from warp_tube.extract.usd import write_scene

    mesh = trimesh.creation.cylinder(radius=0.005, height=0.2, sections=64).subdivide_to_size(0.004)
    for spokes in (4, 16):
        path = str(tmp_path / f"s{spokes}.usda")
        write_scene(extract_centerline(mesh, hubs=21, spokes=spokes), path, meters_per_unit=1.0, push=False)
        stage = Usd.Stage.Open(path)
        curves = [p for p in stage.Traverse() if p.GetTypeName() == "BasisCurves"]
        widths = np.array(curves[0].GetAttribute("widths").Get())
        np.testing.assert_allclose(widths[2:-2] / 2.0, 0.005, rtol=0.025)


def test_mesh_vertices_lie_at_the_radius_from_the_curve():
    case = BY_NAME["helix_high_torsion_open_open"]
    d, arc = project_points(case.mesh.vertices, case.curve)
    r = np.interp(arc, arclength(case.curve), case.radius)
    # Open ends: every vertex is a ring vertex; the projection onto the 0.01-step polyline is within
    # (0.01)^2 k / 8 of the smooth curve's.
    assert np.allclose(d, r, rtol=1e-4, atol=1e-4 * r.mean())


@pytest.mark.parametrize("name", sorted(BY_NAME))
def test_hubs_on_the_axis_and_frame0_surface_reproduces_the_mesh(name):
    case = BY_NAME[name]
    tube = extract_centerline(case.mesh, source=name)
    err = centring_errors(tube, case)
    # The bounds: every interior hub within 5 % of the local radius, mean at most 1.5 %.
    assert err.max() <= 0.05, (err.max(), int(np.argmax(err)))
    assert err.mean() <= 0.015, err.mean()
    fid = surface_fidelity(tube, case.mesh, surface=simulated_surface(tube))
    # Both ways, on the Surface warp-tube run writes at frame 0: mean <= 4 %, p99 <= 15 %,
    # max <= 40 % of the mean radius.
    assert fid.to_surface.within(*FIDELITY_BOUNDS), fid.to_surface
    assert fid.to_input.within(*FIDELITY_BOUNDS), fid.to_input
    # Circular sections: no end ring is degenerate.
    assert max(fid.end_ratios) <= 1.5, fid.end_ratios
    # Ends: open where the mesh is open, capped at a round tip, trimmed at a flat cut.
    expect = {"open": "open", "round": "closed", "flat": "cut"}
    got = sorted(e.kind for e in tube.ends)
    assert got == sorted(expect[k] for k in case.ends), (got, case.ends)
    assert tube.caps == (case.ends == ("round", "round"))
    assert not [w for w in tube.warnings if w.startswith(NOT_A_TUBE)]
    assert tube.branches == []
