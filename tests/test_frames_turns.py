"""The on-chip kernel's Bishop frames by a product of turns (kernels/frames.py: edge_normal,
carried_twist, turn_product, unit_turn, turned_components) against the frames carried edge to edge by the least rotation
(rotate_minimal, the sequential form the per-tube kernel uses), on curves chosen to reach the
formulas' edges: tangents turned back on the previous one (the half turn), tangents crossing the
plane z = 0 (where edge_normal jumps) and pointing straight down."""

import numpy as np
import pytest
import warp as wp

from warp_tube.kernels.frames import carried_twist, edge_binormal, edge_normal, rotate_minimal, turn_product, turned_components, unit_turn
from warp_tube.kernels.bending import kappa_target


@wp.func
def turned(t: wp.vec3, n: wp.vec3, z: wp.vec2):
    """Normal ``n`` of unit tangent ``t`` turned about it by turn ``z`` (normalised): the turned
    normal ``u`` and ``t x u``, the Bishop frame the scan of turns stands for."""
    c = unit_turn(z)
    m = wp.cross(t, n)
    return n * c[0] + m * c[1], m * c[0] - n * c[1]


@wp.kernel(enable_backward=False)
def bishop_both_ways(t: wp.array[wp.vec3], t_rest: wp.vec3, u_rest: wp.vec3, by_rotation: wp.array[wp.vec3], by_turns: wp.array[wp.vec3]):
    # Sequentially, as bending.curvature_targets: each normal carried from the previous edge's by
    # the least rotation, its round-off taken out (kept unit and normal to its edge).
    u = rotate_minimal(t_rest, t[0], u_rest)
    by_rotation[0] = u
    for i in range(1, t.shape[0]):
        u = rotate_minimal(t[i - 1], t[i], u)
        u = wp.normalize(u - t[i] * wp.dot(u, t[i]))
        by_rotation[i] = u
    # By turns: each edge's own normal turned by the product of the turns up to it.
    z = carried_twist(t_rest, u_rest, t[0], edge_normal(t[0]), edge_binormal(t[0]))
    u0, v0 = turned(t[0], edge_normal(t[0]), z)
    by_turns[0] = u0
    for i in range(1, t.shape[0]):
        z = turn_product(z, carried_twist(t[i - 1], edge_normal(t[i - 1]), t[i], edge_normal(t[i]), edge_binormal(t[i])))
        ui, vi = turned(t[i], edge_normal(t[i]), z)
        by_turns[i] = ui


def normals(tangents, t_rest=(1.0, 0.0, 0.0)):
    t = np.asarray(tangents, dtype=np.float64)
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    tr = np.asarray(t_rest, dtype=np.float64) / np.linalg.norm(t_rest)
    u_rest = np.cross(tr, [0.0, 0.0, 1.0]) if abs(tr[2]) < 0.9 else np.cross(tr, [1.0, 0.0, 0.0])
    u_rest /= np.linalg.norm(u_rest)
    n = len(t)
    out = [wp.zeros(n, dtype=wp.vec3, device="cpu") for _ in range(2)]
    wp.launch(bishop_both_ways, dim=1, inputs=[wp.array(t.astype(np.float32), dtype=wp.vec3, device="cpu"), wp.vec3(*tr), wp.vec3(*u_rest)],
              outputs=out, device="cpu")  # fmt: skip
    return t, out[0].numpy().astype(np.float64), out[1].numpy().astype(np.float64)


def helix_tangents(n, turns=3.0, pitch=0.3):
    s = np.linspace(0.0, 2 * np.pi * turns, n)
    return np.stack([-np.sin(s), np.cos(s), np.full(n, pitch)], axis=1)


@pytest.mark.parametrize(
    "name",
    ["helix", "helix_down", "random_walk", "half_turns", "straight_down"],
)
def test_turns_give_the_frames_the_least_rotation_carries(name):
    rng = np.random.default_rng(11)
    if name == "helix":  # tangents stay above z = 0
        tangents = helix_tangents(200)
    elif name == "helix_down":  # a helix about x: tangents cross z = 0 every half turn
        h = helix_tangents(200, turns=4.0, pitch=0.5)
        tangents = h[:, [2, 0, 1]]
    elif name == "random_walk":  # rough: consecutive tangents tens of degrees apart
        # (kept off near-reversals, where the least rotation's 1 / (1 + a.b) amplifies round-off
        # in either form: a 174 degree turn, 1 / (1 + a.b) = 150, parts them by 2e-5; exact
        # reversals, the half turn, are the next case)
        tangents = rng.normal(0.0, 1.0, (300, 3))
        for i in range(1, len(tangents)):
            tangents[i] = tangents[i - 1] / np.linalg.norm(tangents[i - 1]) + 0.5 * rng.normal(0.0, 1.0, 3)
    elif name == "half_turns":  # exact reversals, one of them onto straight down
        tangents = np.array([[1.0, 0.2, 0.1], [0.0, 0.3, 1.0], [0.0, -0.3, -1.0], [0.5, 0.5, 0.0], [-0.5, -0.5, 0.0],
                             [0.0, 0.0, 1.0], [0.0, 0.0, -1.0], [0.3, -0.2, -1.0], [1.0, 1.0, 1.0]])  # fmt: skip
    else:  # along -z, where edge_normal's formula has its sign switch
        tangents = np.array([[0.0, 0.0, -1.0]] * 5 + [[1e-4, 0.0, -1.0], [-1e-4, 1e-4, -1.0], [0.0, 0.0, 1.0]])
    t, by_rotation, by_turns = normals(tangents)
    # both unit normals of their edges
    for u in (by_rotation, by_turns):
        np.testing.assert_allclose(np.linalg.norm(u, axis=1), 1.0, atol=2e-5)
        assert np.abs(np.sum(u * t, axis=1)).max() < 2e-5
    # The same frames, float32 round-off apart: each way accumulates a few 1e-8 a step (measured
    # 1.1e-6 after the 200 edges of the helix); 1e-5 is some 100 ulp of a unit vector, where a turn
    # composed the wrong way round or of the wrong sign is off by O(1).
    np.testing.assert_allclose(by_turns, by_rotation, rtol=0, atol=1e-5)


@wp.kernel(enable_backward=False)
def targets_both_ways(t: wp.array[wp.vec3], z: wp.array[wp.vec2], k: wp.array[wp.vec3], by_frame: wp.array[wp.vec3],
                      by_components: wp.array[wp.vec3]):  # fmt: skip
    i = wp.tid()
    n = edge_normal(t[i])
    u, v = turned(t[i], n, z[i])
    by_frame[i] = kappa_target(t[i], u, v, k[i])
    by_components[i] = kappa_target(t[i], n, wp.cross(t[i], n), turned_components(k[i], unit_turn(z[i])))


def test_turned_components_give_the_target_the_turned_frame_gives():
    # The on-chip kernel rebuilds a bending target from the rest curvature's components turned by
    # the edge's turn, in the edge's own frame (t, n, t x n), instead of from the turned frame:
    # the same vector. Random unit tangents (some straight down, where edge_normal switches),
    # turns of any length (normalised by both), components up to 3 in size: measured 4.8e-7
    # apart; 2e-6 is ~8 ulp of the largest, where a sign or a swapped component is off by O(1).
    rng = np.random.default_rng(5)
    t = rng.normal(0.0, 1.0, (400, 3))
    t[:4] = [[0.0, 0.0, -1.0], [0.0, 0.0, 1.0], [1e-4, 0.0, -1.0], [1.0, 0.0, 0.0]]
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    z = rng.normal(0.0, 1.0, (400, 2)) * rng.uniform(0.5, 2.0, (400, 1))
    k = rng.uniform(-3.0, 3.0, (400, 3))
    arrays = [wp.array(a.astype(np.float32), dtype=d, device="cpu") for a, d in ((t, wp.vec3), (z, wp.vec2), (k, wp.vec3))]
    out = [wp.zeros(400, dtype=wp.vec3, device="cpu") for _ in range(2)]
    wp.launch(targets_both_ways, dim=400, inputs=arrays, outputs=out, device="cpu")
    by_frame, by_components = (o.numpy().astype(np.float64) for o in out)
    assert np.abs(by_frame).max() > 1.0  # targets of the components' size
    np.testing.assert_allclose(by_components, by_frame, rtol=0, atol=2e-6)


@wp.kernel(enable_backward=False)
def binormal_both_ways(t: wp.array[wp.vec3], by_cross: wp.array[wp.vec3], by_formula: wp.array[wp.vec3]):
    i = wp.tid()
    by_cross[i] = wp.cross(t[i], edge_normal(t[i]))
    by_formula[i] = edge_binormal(t[i])


def test_edge_binormal_is_the_tangent_cross_its_normal():
    # edge_binormal gives t x edge_normal(t) from Duff et al.'s second basis vector, without the
    # cross product: random unit tangents and those where the formula switches sign (z = 0,
    # straight down, straight up). Measured 1.2e-7 apart; 1e-6 is a few ulp of a unit vector,
    # where a sign or a swapped component is off by O(1).
    rng = np.random.default_rng(8)
    t = rng.normal(0.0, 1.0, (400, 3))
    t[:5] = [[0.0, 0.0, -1.0], [0.0, 0.0, 1.0], [1e-4, 0.0, -1.0], [1.0, 0.0, 0.0], [0.6, -0.8, 0.0]]
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    out = [wp.zeros(400, dtype=wp.vec3, device="cpu") for _ in range(2)]
    wp.launch(binormal_both_ways, dim=400, inputs=[wp.array(t.astype(np.float32), dtype=wp.vec3, device="cpu")], outputs=out, device="cpu")
    by_cross, by_formula = (o.numpy().astype(np.float64) for o in out)
    np.testing.assert_allclose(np.linalg.norm(by_formula, axis=1), 1.0, atol=1e-6)
    np.testing.assert_allclose(by_formula, by_cross, rtol=0, atol=1e-6)
