"""Every feature on every centerline path: each scene of ``scenes/`` and a curved, assisted,
spring-damped batch run for one second of simulated time on the per-tube kernel, the on-chip
kernel (on the CPU through Warp's CPU blocks, on CUDA as a GPU block kernel) and implicit Euler,
and their positions compared.

- Per-tube against on-chip: the same semi-implicit step and the same force functions, summed in
  another order (each term's contributions gathered through shared memory instead of added in a
  loop) and the curved frames composed by a scan instead of in order; so only float32 round-off
  parts them.
- Implicit against semi-implicit: both are first-order in the step, so at the same small step
  they differ by O(h); halving the step must about halve the difference (a missing or different
  term would leave a difference that does not shrink).
"""

import pathlib

import numpy as np
import pytest
import warp as wp

import warp_tube
from warp_tube.centerline.explicit import SemiImplicitEulerSolver
from warp_tube.centerline.implicit import ImplicitEulerSolver
from warp_tube.scene.spec import ForceSpec, Scene, SimulationSettings, StageInfo, TubeParams, TubeSpec
from warp_tube.sim.simulation import Simulation

SCENES = sorted((pathlib.Path(__file__).resolve().parents[1] / "scenes").glob("*.usda"))
SECONDS = 1.0
def cuda(test):
    """Marked ``gpu``; skips without a CUDA device."""
    return pytest.mark.gpu(pytest.mark.skipif(not wp.get_cuda_device_count(), reason="no CUDA device")(test))


def batch_scene():
    """Two curved tubes in one prim with every feature (anchors, pins, gravity, both dampings) and
    four pushes, three with assistant lines: two lines on the first tube, one on the second.

    Mass damping 10/s: at 3/s, with the second line pushed next to the clamp, the lines' points
    (held by springs alone) amplified a 1e-8 m perturbation to 2.5e-5 m within the second
    (measured on the per-tube path alone), and the semi-implicit steps h, h/2, h/4, h/8 kept
    differing by ~6e-5 m after 1 s: no comparison of paths can be tighter than the scene itself
    is well-posed. Here a perturbation decays and every path converges."""
    s = np.linspace(0.0, 0.3, 16)
    a = np.stack([s, 0.03 * np.sin(12 * s), 0.01 * s], axis=1)
    b = a[:11] + [0.0, 0.1, 0.0]
    params = TubeParams(density=1050.0, youngs_modulus=5e4, damping=10.0, spring_damping=2e-4, anchor_stiffness=40.0)
    tube = TubeSpec("/World/T", np.concatenate([a, b]), [16, 11], np.full(27, 0.01), params, pinned=[0, 1], anchors=[15, 16, 26])
    forces = (
        ForceSpec("/World/P", 0, 8, [0.0, 0.2], [[0, 0, 0.0], [0.0, 0.05, 0.05]], assistant_line=True),
        ForceSpec("/World/Q", 0, 21, [0.0], [[0.02, 0.0, 0.0]], assistant_line=True),
        ForceSpec("/World/R", 0, 12, [0.0, 0.3], [[0.0, 0.0, 0.0], [0.0, -0.03, 0.02]], assistant_line=True),
        ForceSpec("/World/S", 0, 24, [0.0], [[0.0, 0.0, -0.01]], assistant_line=False),
    )
    stage = StageInfo(meters_per_unit=1.0, time_codes_per_second=24.0, end_time_code=24.0)
    return Scene((tube,), forces, settings=SimulationSettings(gravity=(0.0, -9.81, 0.0)), stage=stage)


def load(name):
    return batch_scene() if name == "batch" else warp_tube.load_scene(str(name))


def run(name, path, device="cpu", refine=1, worlds=1):
    """Positions [m], shape (worlds, points, 3), after ``SECONDS`` of the scene on ``path``
    ("perTube", "onchip", "implicit") with ``refine`` x the substeps the scene picks; and the
    simulation."""
    sim = Simulation(load(name), device=device, world_count=worlds, surface=False)
    sim.substeps *= refine
    sim.dt = sim.frame_dt / sim.substeps
    sim._retry = False  # the path under test, at the step chosen here, or a failure
    if path == "implicit":
        sim.solver = ImplicitEulerSolver(sim.model, iterations=4, tolerance=1e-9)
    else:
        sim.solver = SemiImplicitEulerSolver(sim.model, onchip=path == "onchip", block_dim=64)
        assert sim.solver.onchip == (path == "onchip")
    for _ in range(round(SECONDS / sim.frame_dt)):
        sim.step()
    q = sim.state.node_q.numpy().astype(np.float64) + sim.state.node_q_lo.numpy()
    return q, sim


NAMES = [*SCENES, "batch"]
IDS = [p.stem if isinstance(p, pathlib.Path) else p for p in NAMES]


@pytest.mark.parametrize("name", NAMES, ids=IDS)
def test_onchip_equals_per_tube(name):
    worlds = 3 if name == "batch" else 1
    a, sim = run(name, "perTube", worlds=worlds)
    b, _ = run(name, "onchip", worlds=worlds)
    motion = np.abs(a - sim.model.host.node_rest_q[None]).max()
    assert motion > 1e-3  # it really moved
    if name == "batch":
        f = sim.model.features
        assert all(f) and sim.model.al_lines == 2 and sim.model.host.tube_al_force.tolist() == [[0, 1], [2, -1]]
    # float32 round-off (~1e-7 relative per operation) carried through one second of damped
    # substeps (1,100 to 4,000 of them): measured up to 1.2e-7 m; 2e-6 m is still 1e-3 of the
    # smallest motion here and far below any missing term's effect (a missing spring damping or
    # holonomy term moves points by 1e-4 m within the first frames).
    np.testing.assert_allclose(b, a, rtol=0, atol=2e-6)


@pytest.mark.parametrize("name", NAMES, ids=IDS)
def test_implicit_converges_to_semi_implicit(name):
    diffs = []
    for refine in (1, 2):
        a, sim = run(name, "perTube", refine=refine)
        b, _ = run(name, "implicit", refine=refine)
        diffs.append(np.abs(a - b).max())
    motion = np.abs(a - sim.model.host.node_rest_q[None]).max()
    print(f"{name}: |implicit - semi-implicit| {diffs[0]:.2e} m at h, {diffs[1]:.2e} m at h/2 (motion {motion:.2e} m)")
    # Both are first-order: the difference is the two methods' O(h) errors, about halved when h
    # is (0.65 leaves room for the second-order part); at these steps it is a small fraction of
    # the motion. Where both have settled to the same equilibrium the difference is round-off
    # (below 1e-6 m) and does not shrink further.
    assert diffs[0] < 0.02 * motion
    assert diffs[1] < 0.65 * diffs[0] or diffs[1] < 1e-6


@cuda
@pytest.mark.parametrize("name", NAMES, ids=IDS)
def test_cuda_paths_equal_the_cpu(name):
    worlds = 3 if name == "batch" else 1
    a, _ = run(name, "perTube", worlds=worlds)
    b, sim = run(name, "onchip", device="cuda:0", worlds=worlds)
    assert sim.solver.onchip
    # Fast math (approximate division and square root) and FMA on the GPU against the CPU's
    # per-tube kernel: a few float32 ulp per substep, amplified as above.
    np.testing.assert_allclose(b, a, rtol=0, atol=1e-5)
    c, _ = run(name, "implicit", worlds=worlds)
    d, _ = run(name, "implicit", device="cuda:0", worlds=worlds)
    # float64 solves on both; float32 state round-off.
    np.testing.assert_allclose(d, c, rtol=0, atol=1e-5)
