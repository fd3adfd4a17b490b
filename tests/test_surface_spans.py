"""A world of many tubes split among warps (warp_tube.surface.spans): whole tubes a span, every
hub and cap ring in one span, and the block kernel over spans giving the world kernel's points,
normals and bounds bit for bit."""

import numpy as np
import pytest
import warp as wp

from warp_tube.surface import spans
from warp_tube.surface.builder import SurfaceBuilder
from warp_tube.surface.topology import RING_BODY, build_topology


def _tubes(rng, count):
    counts = rng.integers(2, 30, count)
    starts = np.r_[0, np.cumsum(counts)]
    pts = []
    for c in counts:  # helices of random lengths, scattered
        th = np.linspace(0.0, 2.0, c)
        pts.append(np.stack([np.cos(th), np.sin(th), 0.3 * th], 1) + rng.normal(0.0, 3.0, 3))
    return starts, np.concatenate(pts)


@pytest.mark.parametrize("caps", [False, True])
@pytest.mark.parametrize("worlds", [1, 7, 100_000])
def test_spans_are_whole_tubes_covering_every_hub_and_ring(caps, worlds):
    starts, _ = _tubes(np.random.default_rng(2), 300)
    topo = build_topology(starts, 6, caps=caps)
    s = spans.block_spans(starts, topo.ring_hub, topo.ring_kind, worlds)
    n_hubs = int(starts[-1])
    assert s.hub_start[0] == 0 and s.hub_start[-1] == n_hubs and np.all(np.diff(s.hub_start) > 0)
    assert set(s.hub_start.tolist()) <= set(starts.tolist())  # spans end where tubes end
    assert s.cap_ring[0] == n_hubs and s.cap_ring[-1] == len(topo.ring_hub) and np.all(np.diff(s.cap_ring) >= 0)
    for k in range(s.count):  # each span's cap rings belong to its own tubes, and all of theirs are there
        hubs = topo.ring_hub[s.cap_ring[k] : s.cap_ring[k + 1]]
        assert np.all((hubs >= s.hub_start[k]) & (hubs < s.hub_start[k + 1]))
        assert np.all(topo.ring_kind[s.cap_ring[k] : s.cap_ring[k + 1]] != RING_BODY)
    if worlds >= spans.TARGET_WARPS:
        assert s.count == 1  # the worlds alone fill the device
    else:  # spans of about MIN_SPAN_HUBS hubs (a tube goes with the block of 32 its first hub is
        # in; tubes are shorter than 32, so every block holds a start: 32 hubs a span on average,
        # at most 32 plus a tube of 29)
        sizes = np.diff(s.hub_start)
        assert 28 <= sizes.mean() <= 33 and sizes.max() <= 32 + 29
        assert s.hubs_max == int(sizes.max())


@pytest.mark.parametrize("caps", [False, True])
def test_block_kernel_over_spans_equals_the_world_kernel(caps):
    # 37 tubes of 2 to 29 hubs in one world: the block kernel (Warp's CPU blocks) splits them
    # into spans of about 32 hubs; the same arithmetic in the same order per hub and ring.
    rng = np.random.default_rng(1)
    starts, pts = _tubes(rng, 37)
    lengths = 0.1 + 0.05 * rng.random((len(pts), 8))
    q = wp.array((pts + rng.normal(0.0, 0.02, pts.shape))[None].astype(np.float32), dtype=wp.vec3, device="cpu")
    out = []
    for kernel in ("world", "block"):
        b = SurfaceBuilder(starts, pts, 8, lengths, caps=caps, device="cpu", kernel=kernel)
        p, n = b.compute(q)
        out.append((p.numpy().copy(), n.numpy().copy(), b.extent().numpy().copy(), b.spans.count))
    (p0, n0, e0, c0), (p1, n1, e1, c1) = out
    assert c0 == 1 and c1 > 10
    assert np.array_equal(p0, p1) and np.array_equal(n0, n1) and np.array_equal(e0, e1)
    assert np.array_equal(e1[0], np.stack([p0[0].min(axis=0), p0[0].max(axis=0)]))
