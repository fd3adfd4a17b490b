"""Contact between distant parts of tubes (warp_tube.sim.proximity) on exact geometry: two straight
tubes crossing at a known distance, on both device paths (all pairs, hash grid) and with groups.
The tubes' rest shapes lie apart (``apart``): points in contact at rest are left out."""

import numpy as np
import pytest
import warp as wp

from warp_tube.sim import proximity
from warp_tube.sim.proximity import ContactMonitor


def crossing(n, gap_z, radius=0.1, copies=1):
    """Host dict of ``copies`` pairs of straight tubes of ``n`` points crossing at right angles,
    ``gap_z`` [m] apart at their middles (tube A along x at z = 0, tube B along y at z = gap_z)."""
    s = np.linspace(-1.0, 1.0, n)
    a = np.stack([s, 0 * s, 0 * s], axis=1)
    b = np.stack([0 * s, s, 0 * s + gap_z], axis=1)
    pts = np.concatenate([a, b] * copies)
    start = np.arange(0, 2 * copies * n + 1, n)
    return {"node_rest_q": pts, "node_radius": np.full(len(pts), radius), "tube_node_start": start}


def apart(host: dict) -> np.ndarray:
    """Rest positions of ``host``'s tubes moved 10 m apart, one from the next along x (same arclengths)."""
    tube = np.repeat(np.arange(len(host["tube_node_start"]) - 1), np.diff(host["tube_node_start"]))
    return host["node_rest_q"] + 10.0 * tube[:, None] * np.array([1.0, 0.0, 0.0])


@pytest.mark.parametrize("n", [15, 101])  # 30 points: all pairs; 202: hash grid (above SMALL)
def test_crossing_tubes_touch_exactly_when_closer_than_two_radii(n):
    assert (2 * n <= proximity.SMALL) == (n == 15)
    for gap_z, touching in ((0.15, True), (0.25, False)):
        host = crossing(n, gap_z)
        mon = ContactMonitor(apart(host), host["node_radius"], host["tube_node_start"], device="cpu")
        q = wp.array(host["node_rest_q"], dtype=wp.vec3, device="cpu")
        deepest = mon.deepest(q)
        # The middles (odd n: a point at s = 0 on each tube) are gap_z apart: overlap gap_z - 2 r,
        # in float32 (1e-6 covers its round-off).
        expected = min(gap_z - 0.2, 0.0)
        np.testing.assert_allclose(deepest, [expected], atol=1e-6)
        hit = mon.closest(host["node_rest_q"])
        if touching:
            assert hit[:2] == (n // 2, n + n // 2) and abs(hit[2] - expected) < 1e-12
        else:
            assert hit is None


@pytest.mark.parametrize("small", [0, 10**9])  # hash grid, all pairs
def test_points_in_contact_at_rest_never_count(small):
    """Three tubes meeting at a shared point (an airway's junction: each tube's end there) and a
    hairpin whose legs lie side by side, 1.5 radii apart: in contact at rest, as the scene puts
    them, so not reported at rest nor when they move; points not in contact at rest (the hairpin
    and the trunk) are, once they come within two radii."""
    s = np.linspace(0.0, 1.0, 21)
    r = 0.02
    trunk = np.stack([0 * s, 1.0 - s, 0 * s], 1)  # ends at the origin
    left = np.stack([-s, -s, 0 * s], 1) / np.sqrt(2)  # start at the origin
    right = np.stack([s, -s, 0 * s], 1) / np.sqrt(2)
    leg = np.stack([2.0 + 0 * s, s, 0 * s], 1)
    hairpin = np.concatenate([leg, leg[::-1] + [1.5 * r, 0.0, 0.0]])  # legs 1.5 r apart (a 0.03 m fold)
    rest = np.concatenate([trunk, left, right, hairpin])
    start = np.array([0, 21, 42, 63, 105])
    mon = ContactMonitor(rest, np.full(len(rest), r), start, device="cpu", small=small)
    q = wp.array(rest, dtype=wp.vec3, device="cpu")
    assert mon.deepest(q)[0] == 0.0 and mon.closest(rest) is None
    moved = rest.copy()
    moved[63:] += [-2.0 + 1.5 * r, 0.5, 0.0]  # the hairpin's first leg 1.5 r beside the trunk's first half
    q.assign(moved)
    # The deepest overlap: 1.5 r - 2 r between the trunk and the first leg (float32 round-off: 1e-6).
    np.testing.assert_allclose(mon.deepest(q), [-0.5 * r], atol=1e-6)
    i, j, gap = mon.closest(moved)
    assert i < 21 and 63 <= j < 84 and abs(gap + 0.5 * r) < 1e-9


def _bifurcation(angle_deg: float, h: float = 0.01, n: int = 31) -> np.ndarray:
    """A trunk ending at the origin along -y and two branches leaving it at +-angle/2 from -y,
    points ``h`` apart [m]: (3 n, 3)."""
    s = np.arange(n) * h
    t = np.radians(0.5 * angle_deg)
    trunk = np.stack([0 * s, (n - 1) * h - s, 0 * s], 1)
    return np.concatenate([trunk] + [np.stack([side * np.sin(t) * s, -np.cos(t) * s, 0 * s], 1) for side in (-1, 1)])


@pytest.mark.parametrize("small", [0, 10**9])  # hash grid, all pairs
def test_branches_near_their_junction_never_count(small):
    """Two branches leaving a trunk's end 90 degrees apart (an airway's bifurcation), radius 0.02 m:
    points of two tubes within pi/2 x 2r = 0.0628 m of their junction, through it, are close along
    the tubes, like points of one tube (their surfaces meet at any branching), and never count.
    The branches swung to 80 degrees overlap near the junction only (not counted; counting pairs
    on different tubes as distant, as before, reports 1.4 mm there); swung to 60 degrees, points
    farther out overlap too, and count. Oracle: every pair's distance by NumPy on the exact
    geometry, with the rule written out."""
    r, n = 0.02, 31
    rest = _bifurcation(90.0)
    start = np.array([0, n, 2 * n, 3 * n])
    mon = ContactMonitor(rest, np.full(len(rest), r), start, device="cpu", small=small)
    s = np.arange(n) * 0.01
    assert set(mon.junction) == {mon.junction[n - 1]} and mon.junction[0] >= 0  # one junction, every tube
    np.testing.assert_allclose(mon.to_junction, np.concatenate([s[::-1], s, s]), atol=1e-12)
    q = wp.array(rest, dtype=wp.vec3, device="cpu")
    i, j = np.triu_indices(3 * n, 1)
    other = i // n != j // n
    i, j = i[other], j[other]
    to_junction = np.concatenate([s[::-1], s, s])
    apart_at_rest = np.linalg.norm(rest[i] - rest[j], axis=1) >= 2 * r
    for angle, counts in ((80.0, False), (60.0, True)):
        moved = _bifurcation(angle)
        q.assign(moved)
        gap = np.linalg.norm(moved[i] - moved[j], axis=1) - 2 * r
        far = to_junction[i] + to_junction[j] > 0.5 * np.pi * 2 * r
        expected = min(gap[far & apart_at_rest].min(), 0.0)
        assert (expected < 0.0) == counts
        if not counts:
            assert gap[apart_at_rest].min() < -1e-3  # without the junction: a contact at 80 degrees
        np.testing.assert_allclose(mon.deepest(q), [expected], atol=1e-6)  # float32 round-off


def test_points_close_along_one_tube_never_count():
    # A straight tube whose points are much closer than two radii: neighbours along the tube.
    s = np.linspace(0.0, 1.0, 200)
    host = {"node_rest_q": np.stack([s, 0 * s, 0 * s], axis=1), "node_radius": np.full(200, 0.05),
            "tube_node_start": np.array([0, 200])}  # fmt: skip
    mon = ContactMonitor(host["node_rest_q"], host["node_radius"], host["tube_node_start"], device="cpu")
    assert mon.deepest(wp.array(host["node_rest_q"], dtype=wp.vec3, device="cpu"))[0] == 0.0


@pytest.mark.parametrize("n", [15, 101])
def test_groups_do_not_touch_each_other(n):
    # Two copies of the crossing at the same place: group 0 touches (0.15 apart), group 1 holds the
    # second copy shifted to 0.3 apart; copies overlap in space but are different groups.
    host = crossing(n, 0.15, copies=2)
    host["node_rest_q"][2 * n + n :, 2] = 0.3  # group 1's tube B
    group = np.repeat([0, 1], 2 * n)
    mon = ContactMonitor(apart(host), host["node_radius"], host["tube_node_start"], device="cpu", node_group=group)
    deepest = mon.deepest(wp.array(host["node_rest_q"], dtype=wp.vec3, device="cpu"))
    np.testing.assert_allclose(deepest, [-0.05, 0.0], atol=1e-6)
    assert mon.closest(host["node_rest_q"], group=1) is None


@pytest.mark.parametrize("n", [15, 101])
def test_the_same_positions_array_checked_again_after_it_moves(n):
    """The monitor replays one recorded launch per positions array: frame after frame it must see
    the array's new contents (touching, then apart, then touching again)."""
    near, far = crossing(n, 0.15), crossing(n, 0.25)
    mon = ContactMonitor(apart(near), near["node_radius"], near["tube_node_start"], device="cpu")
    q = wp.array(near["node_rest_q"], dtype=wp.vec3, device="cpu")
    for host, expected in ((near, -0.05), (far, 0.0), (near, -0.05)):
        q.assign(host["node_rest_q"])
        np.testing.assert_allclose(mon.deepest(q), [expected], atol=1e-6)  # float32 round-off, as above


@pytest.mark.parametrize("vary", [False, True])
def test_worlds_of_one_geometry_share_one_worlds_pairs(vary):
    # A batch's worlds of one geometry (equal blocks with the same radii, arclengths and tubes)
    # take one world's distant pairs, offset world after world: the same pairs as testing every
    # world's own (exact integer sets); a world with other radii takes the general path.
    rng = np.random.default_rng(0)
    W, N = 16, 20
    rest = np.repeat(np.cumsum(rng.normal(size=(1, N, 3)) * 0.01, axis=1), W, axis=0)
    r = np.full((W, N), 0.01)
    if vary:
        r[3] *= 2.0
    start = np.array([0, 12, 20])
    starts = (start[:-1][None] + N * np.arange(W)[:, None]).reshape(-1)
    m = ContactMonitor(rest.reshape(-1, 3), r.reshape(-1), np.append(starts, W * N), node_group=np.repeat(np.arange(W), N), small=32)
    got = m._pairs[0].numpy().astype(np.int64) * (W * N) + m._pairs[1].numpy()
    i, j = m._keep(*proximity._group_pairs(m.group))
    assert len(got) > 0 and np.array_equal(np.sort(got), np.sort(i * (W * N) + j))


def test_the_hash_grid_finds_what_all_pairs_find_in_any_layout():
    """Random wavy tubes in three groups (some overlapping, some not), and a long row of tubes:
    the hash grid (its table shaped to the points' extent, :func:`proximity.grid_dims`) and all
    pairs give the same deepest overlap of every group, to the bit (the same float32 distances)."""
    rng = np.random.default_rng(3)
    scenes = []
    for _ in range(12):
        nt, npts = int(rng.integers(2, 30)), int(rng.integers(8, 40))
        s = np.linspace(0.0, 0.15, npts)
        tubes = []
        for _ in range(nt):
            d = rng.normal(size=3)
            d /= np.linalg.norm(d)
            tubes.append(rng.uniform(-0.1, 0.1, 3) + s[:, None] * d + 0.01 * np.sin(s[:, None] * rng.uniform(5, 40) + rng.uniform(0, 6, 3)))
        scenes.append((np.concatenate(tubes), nt, npts, rng.uniform(0.003, 0.01, nt * npts), rng.integers(0, 3, nt).repeat(npts)))
    x = np.arange(20) * 0.01  # 300 tubes along z, 2.1 cm apart: neighbours overlap by 0.1 cm, radius 1.1 cm
    row = np.concatenate([np.stack([x, 0 * x, 0 * x + 0.021 * k], 1) for k in range(300)])
    scenes.append((row, 300, 20, np.full(len(row), 0.011), np.zeros(len(row), dtype=int)))
    for q, nt, npts, r, groups in scenes:
        start = np.arange(nt + 1) * npts
        qa = wp.array(q, dtype=wp.vec3, device="cpu")
        rest = apart({"node_rest_q": q, "tube_node_start": start})
        grid = ContactMonitor(rest, r, start, node_group=groups, small=0).deepest(qa)
        pairs = ContactMonitor(rest, r, start, node_group=groups, small=10**9).deepest(qa)
        np.testing.assert_array_equal(grid, pairs)
    np.testing.assert_allclose(grid, [-0.001], atol=1e-6)  # the row's neighbours: 2.1 cm apart, 2.2 cm of radii


def test_the_hash_grid_table_follows_the_points_extent():
    cell = 0.02
    row = np.stack([np.arange(100_000) * 0.002, np.zeros(100_000), np.zeros(100_000)], 1)  # 200 m along x
    dims = proximity.grid_dims(row, cell, len(row))
    assert dims[1] == dims[2] == 1 and dims[0] >= 8_000  # every slot along the row, none wasted across it
    cube = np.random.default_rng(0).uniform(0.0, 1.0, (100_000, 3))  # 51 cells along each axis
    assert proximity.grid_dims(cube, cell, len(cube)) == (51, 51, 51)  # a slot for every cell (fewer than 2 a point)
    big = np.random.default_rng(0).uniform(0.0, 10.0, (100_000, 3))  # 501 cells along each axis
    dims = proximity.grid_dims(big, cell, len(big))
    assert len(set(dims)) == 1 and abs(np.prod(dims) - 200_000) < 0.05 * 200_000  # ~2 slots a point, evenly
    assert np.prod(proximity.grid_dims(np.zeros((1, 3)), cell, 1)) == 1  # one point: one cell
