"""The on-chip kernel (the GPU path, here on Warp's CPU blocks) against the per-tube kernel (the
CPU path), and CUDA against the CPU when a CUDA device exists."""

import numpy as np
import pytest
import warp as wp

from warp_tube.scene.spec import ForceSpec, Scene, SimulationSettings, StageInfo, TubeParams, TubeSpec
from warp_tube import Simulation
from warp_tube.centerline.explicit import SemiImplicitEulerSolver


def all_features_scene():
    """Two curved tubes in one prim with every feature: anchors, pins, gravity, both dampings,
    a force with its assistant line."""
    s = np.linspace(0.0, 0.3, 16)
    a = np.stack([s, 0.03 * np.sin(12 * s), 0.01 * s], axis=1)
    b = a[:11] + [0.0, 0.1, 0.0]
    params = TubeParams(density=1050.0, youngs_modulus=5e4, damping=3.0, spring_damping=2e-4, anchor_stiffness=40.0)
    tube = TubeSpec("/World/T", np.concatenate([a, b]), [16, 11], np.full(27, 0.01), params, pinned=[0, 1], anchors=[15, 16, 26])
    push = ForceSpec("/World/P", 0, 8, [0.0, 0.2], [[0, 0, 0.0], [0.0, 0.05, 0.05]], assistant_line=True)
    push2 = ForceSpec("/World/Q", 0, 21, [0.0], [[0.02, 0.0, 0.0]], assistant_line=False)
    stage = StageInfo(meters_per_unit=1.0, time_codes_per_second=24.0, end_time_code=12.0)
    return Scene((tube,), (push, push2), settings=SimulationSettings(gravity=(0.0, -9.81, 0.0)), stage=stage)


def run(device, onchip, frames=12, worlds=2):
    sim = Simulation(all_features_scene(), device=device, world_count=worlds, surface=False)
    sim.solver = SemiImplicitEulerSolver(sim.model, onchip=onchip)
    for _ in range(frames):
        sim.step()
    return np.stack([sim.centerline_points(w)[0] for w in range(worlds)]), sim


def test_onchip_kernel_matches_per_tube_kernel_on_cpu():
    a, sim = run("cpu", onchip=False)
    b, _ = run("cpu", onchip=True)
    assert sim.model.features == sim.model.features._replace(
        bending=True, curved=True, anchors=True, gravity=True, mass_damping=True, spring_damping=True, external=True, assistant_line=True
    )
    moved = np.abs(a - all_features_scene().tubes[0].points).max()
    assert moved > 5e-3  # it really moved
    # Same forces summed in another order (exchanged through shared memory against added in a
    # loop, frames composed by a scan against in order): float32 round-off only, amplified over
    # ~700 substeps; 1e-5 m is 1e-3 of the motion.
    np.testing.assert_allclose(a, b, atol=1e-5)


@pytest.mark.skipif(not wp.get_cuda_device_count(), reason="no CUDA device")
def test_cuda_matches_cpu():
    a, _ = run("cpu", onchip=False)
    b, sim = run("cuda:0", onchip=None)
    assert sim.solver.onchip
    np.testing.assert_allclose(a, b, atol=1e-5)  # as above: order of summation and FMA only


@pytest.mark.skipif(not wp.get_cuda_device_count(), reason="no CUDA device")
def test_implicit_cuda_matches_cpu():
    from warp_tube.centerline.implicit import ImplicitEulerSolver

    scene = all_features_scene()
    out = []
    for device in ("cpu", "cuda:0"):
        sim = Simulation(scene, device=device, world_count=2, surface=False)
        sim.solver = ImplicitEulerSolver(sim.model)
        for _ in range(12):
            sim.step()
        out.append(np.stack([sim.centerline_points(w)[0] for w in range(2)]))
    np.testing.assert_allclose(out[0], out[1], atol=1e-5)  # float64 solves; float32 state round-off
