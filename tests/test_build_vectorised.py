"""The vectorised model and surface build against the loops it replaced (tests/reference_build.py)."""

from __future__ import annotations

import numpy as np
import pytest

from tests.reference_build import build_topology_loop, rest_curvature_coordinates_loop
from warp_tube.model.tube import build_model, rest_curvature_coordinates, rest_curvature_of_curves
from warp_tube.scene.spec import Scene, TubeParams, TubeSpec
from warp_tube.surface.topology import build_topology


def wavy(n: int, phase: float = 0.0) -> np.ndarray:
    """A smooth curve through 3-d space, (n, 3) [m], 1 m long along x."""
    s = np.linspace(0.0, 1.0, n)
    return np.stack([s, 0.1 * np.sin(9 * s + phase) + 0.05 * np.sin(23 * s), 0.1 * np.cos(7 * s + phase)], 1)


@pytest.mark.parametrize("n", [2, 3, 4, 5, 20, 65, 66, 67, 200, 5000])
def test_rest_curvature_matches_the_point_loop(n):
    x = wavy(n)
    ref = rest_curvature_coordinates_loop(x)
    got = rest_curvature_coordinates(x)
    assert got.shape == (n, 3)
    # Both carry the same frame along the tube in float64: the loop one rotation and
    # re-projection at a time, the new code as composed quaternions. Each of the n - 2 transports
    # rounds at ~1.1e-16 relative, and the error accumulates along the tube, so the two agree to
    # n x 2.2e-16 of the largest component (measured: 5.6e-15 relative at n = 5000).
    scale = max(float(np.abs(ref).max()), 1e-300)
    assert np.abs(got - ref).max() <= n * 2.2e-16 * scale
    assert np.all(got[0] == 0.0) and np.all(got[-1] == 0.0)


def test_rest_curvature_of_a_jagged_tube_and_a_straight_one():
    rng = np.random.default_rng(7)
    x = wavy(300) + 0.002 * rng.normal(size=(300, 3))  # sharp turns at every point
    ref = rest_curvature_coordinates_loop(x)
    assert np.abs(rest_curvature_coordinates(x) - ref).max() <= 300 * 2.2e-16 * np.abs(ref).max()
    straight = np.stack([np.linspace(0, 1, 10), np.zeros(10), np.zeros(10)], 1)
    # A straight tube has no curvature, exactly: every cross product of parallel edges is 0.
    assert np.all(rest_curvature_coordinates(straight) == 0.0)


def test_batched_rest_curvature_equals_one_tube_at_a_time():
    pts = np.stack([wavy(20, phase=0.1 * k) for k in range(7)])
    batched = rest_curvature_coordinates(pts)
    # Element-wise operations in the same order for every tube: bit for bit the same.
    for k in range(7):
        assert np.array_equal(batched[k], rest_curvature_coordinates(pts[k]))
    mixed = [wavy(20), wavy(5), wavy(20, 1.0), wavy(2)]
    for got, x in zip(rest_curvature_of_curves(mixed), mixed):
        assert np.array_equal(got, rest_curvature_coordinates(x))


def test_build_model_takes_each_curves_rest_curvature():
    params = TubeParams(density=1000.0, youngs_modulus=1e5)
    a = TubeSpec("/A", np.concatenate([wavy(12), wavy(7, 0.5) + 2.0]), [12, 7], np.full(19, 0.01), params)
    b = TubeSpec("/B", wavy(12, 1.0) - 2.0, [12], np.full(12, 0.01), params)
    m = build_model(Scene((a, b)), device="cpu")
    expect = np.concatenate([rest_curvature_coordinates_loop(a.points[:12]), rest_curvature_coordinates_loop(a.points[12:]),
                             rest_curvature_coordinates_loop(b.points)])  # fmt: skip
    # the per-curve loop's values, to the transport's round-off (as above, n <= 12)
    assert np.abs(m.host.node_kappa_rest - expect).max() <= 12 * 2.2e-16 * np.abs(expect).max()
    assert m.features.curved


TOPOLOGY_FIELDS = ("vertex_count", "hub_count", "face_vertex_counts", "face_vertex_indices", "st", "ring_hub",
                   "ring_kind", "ring_cos", "ring_sin", "ring_vertex", "st_interpolation")  # fmt: skip


@pytest.mark.parametrize("spokes", [3, 4, 9, 16])
@pytest.mark.parametrize("caps", [False, True])
@pytest.mark.parametrize("counts", [[2], [5], [3, 7, 2, 7], [20] * 6])
def test_build_topology_equals_the_tube_loop(spokes, caps, counts):
    rng = np.random.default_rng(len(counts) * 100 + spokes)
    starts = np.concatenate([[0], np.cumsum(counts)])
    rest = rng.normal(size=(starts[-1], 3))
    radius = rng.uniform(0.1, 1.0, size=(len(counts), 2))
    for kwargs in ({}, {"rest_q": rest}, {"rest_q": rest, "cap_radius": radius}):
        ref = build_topology_loop(starts, spokes, caps=caps, **kwargs)
        got = build_topology(starts, spokes, caps=caps, **kwargs)
        # Integer indices, and st from the same float64 values rounded to float32: identical.
        for name in TOPOLOGY_FIELDS:
            r, g = getattr(ref, name), getattr(got, name)
            if isinstance(r, np.ndarray):
                assert g.dtype == r.dtype, name
                assert np.array_equal(g, r), name
            else:
                assert g == r, name


def _varied_scene() -> Scene:
    """Prims of one and several curves, pins (one pinned pair: a rigid segment), anchors, radii
    varying along each curve, and every way of giving the stiffnesses."""
    rng = np.random.default_rng(3)
    by_modulus = TubeParams(density=1050.0, youngs_modulus=2e5, damping=1.5, spring_damping=0.01, anchor_stiffness=40.0)
    by_override = TubeParams(density=900.0, stretch_stiffness=3.0, bend_stiffness=2e-4, damping=0.0)
    mixed = TubeParams(density=1200.0, youngs_modulus=5e4, bend_stiffness=1e-3, spring_damping=0.002)
    tubes = []
    for k, params in enumerate((by_modulus, by_override, mixed, by_modulus)):
        counts = [(20, 5, 2), (7,), (3, 11), (40,)][k]
        pts = np.concatenate([wavy(c, 0.3 * k + j) + (k, j, 0.0) for j, c in enumerate(counts)])
        radius = 0.01 + 0.004 * rng.random(len(pts))
        tubes.append(TubeSpec(f"/T{k}", pts, list(counts), radius, params,
                              pinned=[0, 1, len(pts) - 1] if k != 1 else [], anchors=[2, len(pts) // 2] if k != 1 else [3]))  # fmt: skip
    return Scene(tuple(tubes))


def _shared_geometry_scene():
    """A batch's worlds: copies of one prim (three curves, pins and anchors) sharing its geometry
    arrays, each with its own material."""
    from warp_tube.scene.spec import replace_checked

    base = _varied_scene().tubes[0]
    rng = np.random.default_rng(5)
    out = []
    for k in range(6):
        params = replace_checked(base.params, youngs_modulus=float(rng.uniform(1e4, 1e6)), density=float(rng.uniform(900, 1200)),
                                 damping=float(k), anchor_stiffness=10.0 * (k + 1))  # fmt: skip
        out.append(replace_checked(base, path=f"/W{k}", params=params))
    return Scene(tuple(out))


@pytest.mark.parametrize("scene", ["varied", "many", "shared"])
def test_node_parameters_equal_the_curve_loop(scene):
    from tests.reference_build import node_parameters_loop
    from warp_tube.model.tube import node_parameters

    if scene == "varied":
        sc = _varied_scene()
    elif scene == "shared":  # prims holding the same geometry arrays: the first prim's repeated
        sc = _shared_geometry_scene()
        assert all(t.points is sc.tubes[0].points for t in sc.tubes)
    else:
        params = TubeParams(density=1000.0, youngs_modulus=1e5, damping=2.0)
        sc = Scene(tuple(TubeSpec(f"/V{k}", wavy(12, 0.01 * k), [12], np.full(12, 0.01), params, pinned=[0, 1]) for k in range(50)))
    got, got_curved = node_parameters(sc)
    ref, ref_curved = node_parameters_loop(sc)
    assert got_curved == ref_curved
    assert set(got) == set(ref)
    for name in ref:
        # The same float64 operations in the same order on each element, only over all curves at
        # once: equal bit for bit, shapes and dtypes included.
        assert got[name].dtype == ref[name].dtype and got[name].shape == ref[name].shape, name
        assert np.array_equal(got[name], ref[name]), name
