"""Device-side frame checks (warp_tube.sim.checks) against states whose answer is known exactly."""

import numpy as np
import warp as wp

from warp_tube.model.tube import build_model
from warp_tube.scene.spec import Scene, StageInfo, TubeParams, TubeSpec
from warp_tube.sim.checks import RUNAWAY_LENGTHS, FrameChecks


def two_tubes():
    x = np.linspace(0.0, 1.0, 6)
    pts = np.stack([x, 0 * x, 0 * x], axis=1)
    params = TubeParams(youngs_modulus=1e5, density=1000.0)
    tubes = tuple(TubeSpec(path=f"/T{k}", points=pts + [0, k, 0], curve_counts=(6,), radius=np.full(6, 0.05), params=params)
                  for k in range(2))  # fmt: skip
    return build_model(Scene(tubes, (), stage=StageInfo(meters_per_unit=1.0)), device="cpu")


def states(model, q_after, qd_after):
    before, after = model.state(), model.state()
    after.node_q.assign(q_after[None].astype(np.float32))
    after.node_qd.assign(qd_after[None].astype(np.float32))
    return before, after


def test_rest_frame_passes_with_zero_work():
    model = two_tubes()
    checks = FrameChecks(model, node_group=[0] * 6 + [1] * 6, extent=1.0)
    before, after = model.state(), model.state()
    failures, work = checks.check(before, after, model.control())
    assert failures == []
    assert work.shape == (1, 2) and np.all(work == 0.0)


def test_nan_and_runaway_are_named_in_their_own_group():
    model = two_tubes()
    checks = FrameChecks(model, node_group=[0] * 6 + [1] * 6, extent=1.0)
    q = model.host.node_rest_q.copy()
    q[8] = np.nan  # tube 1, point 2
    before, after = states(model, q, np.zeros_like(q))
    failures, _ = checks.check(before, after, model.control())
    assert [(f.group, f.node, f.what) for f in failures] == [(1, 8, "non-finite positions")]

    q = model.host.node_rest_q.copy()
    q[3, 1] += 2.0 * RUNAWAY_LENGTHS  # tube 0, point 3: beyond the runaway distance of a 1 m tube
    before, after = states(model, q, np.zeros_like(q))
    failures, _ = checks.check(before, after, model.control())
    assert [(f.group, f.node) for f in failures] == [(0, 3)]
    assert "tube lengths from rest" in failures[0].what


def test_kinetic_energy_against_the_work_of_a_force():
    model = two_tubes()
    checks = FrameChecks(model, node_group=[0] * 6 + [1] * 6, extent=1.0)
    control = model.control()
    f = np.zeros((1, 12, 3), np.float32)
    f[0, 4] = (0.0, 2.0, 0.0)  # 2 N on tube 0, point 4
    control.node_f_ext.assign(f)
    q = model.host.node_rest_q.copy()
    q[4, 1] += 0.25  # moved 0.25 m along the force: work 0.5 J exactly
    qd = np.zeros_like(q)
    mass = model.host.node_mass[4]
    # Kinetic energy 0.4 J: within 10x the work (5 J), so the frame is good ...
    qd[4, 1] = np.sqrt(2.0 * 0.4 / mass)
    before, after = states(model, q, qd)
    failures, work = checks.check(before, after, control)
    assert failures == []
    # float32 positions and sums: 1e-6 relative covers their round-off
    np.testing.assert_allclose(work[0], [0.5, 0.0], rtol=1e-6, atol=1e-9)
    # ... while the same speed in tube 1, where no force worked, is a blow-up of tube 1 only.
    qd[10, 1] = qd[4, 1]
    before, after = states(model, q, qd)
    failures, _ = checks.check(before, after, control)
    assert [(f.group, f.node) for f in failures] == [(1, 10)]
    assert "kinetic energy" in failures[0].what


def test_accepted_work_raises_the_budget():
    model = two_tubes()
    checks = FrameChecks(model, extent=1.0)
    q = model.host.node_rest_q.copy()
    qd = np.zeros_like(q)
    qd[2, 2] = np.sqrt(2.0 * 1.0 / model.host.node_mass[2])  # 1 J
    before, after = states(model, q, qd)
    assert len(checks.check(before, after, model.control())[0]) == 1
    checks.accept(np.array([[0.2]]))  # 0.2 J of earlier work: budget 2 J
    assert checks.check(before, after, model.control())[0] == []
