"""Captured frames (:mod:`warp_tube.runtime.replay`) give exactly what the launches give when run directly."""

import numpy as np
import pytest
import warp as wp

from warp_tube.runtime.replay import GraphCache, can_capture
from warp_tube import Simulation
from warp_tube.centerline.explicit import SemiImplicitEulerSolver

from .test_kernel_paths import all_features_scene

pytestmark = pytest.mark.skipif(not can_capture("cpu"), reason="this Warp cannot capture on the CPU")


def frames(sim, plan):
    """Integrate ``plan`` ((substeps, repeats) pairs) ping-ponging two states; final positions."""
    s0, s1 = sim.state, sim.next_state
    for substeps, repeats in plan:
        for _ in range(repeats):
            sim.solver.integrate(s0, s1, sim.control, sim.frame_dt / substeps, substeps)
            s0, s1 = s1, s0
    return s0.node_q.numpy().copy(), s0.node_qd.numpy().copy()


@pytest.mark.parametrize("onchip", [False, True])
def test_replayed_frames_equal_direct_launches(onchip):
    # One recorded command captured at several (dt, substeps): each graph must keep the values it
    # was captured with, so mixing them has to reproduce the direct launches bit for bit.
    out = []
    for capture in (False, True):
        sim = Simulation(all_features_scene(), device="cpu", world_count=2, surface=False)
        n = sim.substeps  # stable; the plan's other counts are finer
        plan = [(n, 5), (2 * n, 5), (n, 5), (4 * n, 4), (2 * n, 3)]
        sim.step()  # builds the assistant line, so the frames below use every feature
        sim.solver = SemiImplicitEulerSolver(sim.model, onchip=onchip)
        sim.solver._graphs.enabled = capture
        out.append(frames(sim, plan))
        if capture:
            assert len(sim.solver._graphs._graphs) >= 4  # the plan's repeated keys were captured
    q0 = all_features_scene().tubes[0].points
    assert np.abs(out[0][0][0] - q0).max() > 1e-3  # it moved
    np.testing.assert_array_equal(out[0][0], out[1][0])
    np.testing.assert_array_equal(out[0][1], out[1][1])


def test_surface_replay_follows_the_positions():
    sim = Simulation(all_features_scene(), device="cpu", surface=True)
    b = sim.surfaces[0]
    q = wp.clone(sim.state.node_q)
    first = [b.compute(q)[0].numpy().copy() for _ in range(3)]  # run, capture, replay
    assert len(b._graphs._graphs) == 1
    np.testing.assert_array_equal(first[0], first[2])
    moved = q.numpy()
    moved[:, :, 2] += 0.25  # the same array, new contents: the replay must read them
    q.assign(moved)
    np.testing.assert_allclose(b.compute(q)[0].numpy(), first[0] + [0.0, 0.0, 0.25], atol=1e-6)


def test_graph_cache_captures_from_the_second_use():
    calls = []
    a = wp.zeros(1, dtype=float, device="cpu")

    @wp.kernel
    def add_one(x: wp.array[float]):
        x[0] = x[0] + 1.0

    cache = GraphCache("cpu")
    launch = lambda: (calls.append(1), wp.launch(add_one, 1, inputs=[a], device="cpu"))  # noqa: E731
    for _ in range(5):
        cache.run("k", launch)
    # Python ran the launch twice (direct, then under capture); the kernel ran five times.
    assert len(calls) == 2
    assert a.numpy()[0] == 5.0
