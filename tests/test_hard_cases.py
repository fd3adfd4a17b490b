"""Hard cases for the semi-implicit integrator. Every case: the state stays finite, the energy
stays bounded by the work the forces did, and one criterion of its own."""

import re

import numpy as np
import pytest

from .oracle_energy import total_energy
from warp_tube.model.tube import build_model
from warp_tube.bench.references import elastica_tip
from warp_tube.scene.spec import ForceSpec, Scene, SceneError, SimulationSettings, StageInfo, TubeParams, TubeSpec
from warp_tube import Simulation
from warp_tube.centerline.explicit import SemiImplicitEulerSolver
from warp_tube.centerline.stability import critical_time_step

from warp_tube.surface.topology import RING_POLE

from .conftest import settle
from .test_surface import intersecting_pairs

FPS = 24.0


def stage(frames):
    return StageInfo(meters_per_unit=1.0, time_codes_per_second=FPS, frames_per_second=FPS, end_time_code=float(frames))


def line(n, length):
    x = np.linspace(0.0, length, n)
    return np.stack([x, 0 * x, 0 * x], axis=1)


def run_with_energy_bound(scene, frames, gravity=None):
    """Run ``frames`` frames; check finiteness and E(t) <= E(0) + W(t) every frame.

    W is the work of the point forces: each force is held over a frame, so its work over the
    frame is exactly f . (x_end - x_start) of its point. The energy is measured with the stored
    (half-step) velocities, whose O(h w) error, and the assistant line's springs (not counted in
    E, they only take energy), are covered by a slack of 2% of the largest energy seen, plus the
    energy that float32 round-off of the positions can store in the springs (sum of ke times
    (1e-6 x extent)^2: an undamped float32 rest state jiggles by ~1e-7 of its size).
    """
    sim = Simulation(scene, device="cpu", surface=False)
    h = sim.model.host
    nodes = h.force_node
    e0 = total_energy(h, sim.state.node_q.numpy()[0], sim.state.node_qd.numpy()[0], gravity)
    work, e_max = 0.0, abs(e0)
    extent = float(np.ptp(h.node_rest_q, axis=0).max())
    floor = float(np.sum(h.seg_ke)) * (1e-6 * extent) ** 2
    for k in range(frames):
        f = sim.controls.forces_at((sim.frame + 0.5) * sim.frame_dt)
        x0 = sim.state.node_q.numpy()[0, nodes].astype(np.float64)
        sim.step()
        q = sim.state.node_q.numpy()[0]
        assert np.isfinite(q).all()
        work += float(np.sum(f * (q[nodes] - x0)))
        e = total_energy(h, q, sim.state.node_qd.numpy()[0], gravity)
        e_max = max(e_max, abs(e))
        assert e <= e0 + work + 0.02 * e_max + floor, f"frame {k}: energy {e:.4g} J > start {e0:.4g} J + work {work:.4g} J"
    return sim


def test_force_along_the_axis_stretches_by_fl_over_ea():
    # The assistant line's offset direction is along the tube (degenerate); the pull must still
    # give the linear axial stretch F L / EA of the free part (L = 0.95 m behind the clamp).
    n, L, r, E = 21, 1.0, 0.01, 1e6
    F = 1.0
    params = TubeParams(density=1000.0, youngs_modulus=E, damping=60.0)
    tube = TubeSpec("/T", line(n, L), [n], np.full(n, r), params, pinned=[0, 1])
    pull = ForceSpec("/F", 0, n - 1, [0.0], [[F, 0.0, 0.0]], assistant_line=True)
    sim = run_with_energy_bound(Scene((tube,), (pull,), stage=stage(48)), 48)
    stretch = sim.centerline_points()[0][-1, 0] - L
    expected = F * 0.95 * L / (E * np.pi * r**2)
    # 1%: the settled stretch against the linear spring chain (exact for springs in series).
    assert abs(stretch / expected - 1) < 0.01
    assert np.abs(sim.centerline_points()[0][:, 1:]).max() < 1e-6 * L  # no sideways motion


def test_force_on_the_end_point_bends_towards_the_force():
    n = 21
    params = TubeParams(density=1000.0, youngs_modulus=1e6, damping=5.0)
    tube = TubeSpec("/T", line(n, 1.0), [n], np.full(n, 0.02), params, pinned=[0, 1])
    push = ForceSpec("/F", 0, n - 1, [0.0], [[0.0, 0.0, 0.05]], assistant_line=True)
    sim = run_with_energy_bound(Scene((tube,), (push,), stage=stage(24)), 24)
    q = sim.centerline_points()[0]
    assert q[-1, 2] > 0.01 and abs(q[-1, 1]) < 1e-6  # bends in +z only


def test_force_on_a_pinned_point_does_nothing():
    n = 11
    params = TubeParams(density=1000.0, youngs_modulus=1e6)
    tube = TubeSpec("/T", line(n, 1.0), [n], np.full(n, 0.02), params, pinned=[0, 1])
    push = ForceSpec("/F", 0, 1, [0.0], [[0.0, 100.0, 0.0]])
    sim = run_with_energy_bound(Scene((tube,), (push,), stage=stage(12)), 12)
    # Nothing moves but float32 round-off of the rest state (100 N on the pin would move the
    # free part by metres if it reached it).
    assert sim.max_displacement() < 1e-6


def test_force_reversing_every_frame_stays_bounded():
    n = 21
    params = TubeParams(density=1000.0, youngs_modulus=1e6, damping=1.0)
    tube = TubeSpec("/T", line(n, 1.0), [n], np.full(n, 0.02), params, pinned=[0, 1])
    times = np.arange(48) / FPS
    values = np.zeros((48, 3))
    values[:, 1] = 0.2 * np.where(np.arange(48) % 2 == 0, 1.0, -1.0)
    f = ForceSpec("/F", 0, 10, times + 0.5 / FPS, values, assistant_line=True)  # samples at frame middles
    sim = run_with_energy_bound(Scene((tube,), (f,), stage=stage(48)), 48)
    # The same force held would deflect the point by ~F a^3 / 3EI ~ 6 cm; reversing it every
    # frame (far above the first mode, 0.18 Hz) leaves a tiny jitter.
    assert sim.max_displacement() < 0.01


def test_impulsive_huge_force_then_release_returns_to_rest():
    # A stiff hose (E = 1 GPa, 4 cm across) held by returning springs of 1e6 N/m at every point.
    n, r = 21, 0.02
    params = TubeParams(density=1000.0, youngs_modulus=1e9, damping=10.0, anchor_stiffness=1e6)
    tube = TubeSpec("/T", line(n, 1.0), [n], np.full(n, r), params, anchors=np.arange(n))
    hit = ForceSpec("/F", 0, 10, [0.0, 1.0 / FPS, 1.0 / FPS + 1e-9], [[0, 1e6, 0], [0, 1e6, 0], [0, 0, 0]], assistant_line=False)
    sim = run_with_energy_bound(Scene((tube,), (hit,), stage=stage(6 * FPS)), 1)
    peak = sim.max_displacement()
    for _ in range(int(6 * FPS) - 1):
        sim.step()
        assert np.isfinite(sim.state.node_q.numpy()).all()
    back = sim.max_displacement()
    print(f"1e6 N for one frame: peak displacement {peak:.3f} m, after 6 s {back:.2e} m")
    assert peak > 10 * r  # a real blow
    assert back < 0.01 * r  # returned to rest within 1% of the radius


def test_impulsive_huge_force_on_a_soft_tube_switches_auto_to_implicit():
    # 1e6 N for one frame on a soft tube (E = 1 MPa, where semi-implicit is the cheaper choice):
    # its segments collapse and the bending forces (~1/l) become singular, which no semi-implicit
    # substep survives; auto redoes the frame with implicit Euler and keeps it.
    n, r = 21, 0.02
    params = TubeParams(density=1000.0, youngs_modulus=1e6, damping=10.0, anchor_stiffness=1e4)
    tube = TubeSpec("/T", line(n, 1.0), [n], np.full(n, r), params, anchors=np.arange(n))
    hit = ForceSpec("/F", 0, 10, [0.0, 1.0 / FPS, 1.0 / FPS + 1e-9], [[0, 1e6, 0], [0, 1e6, 0], [0, 0, 0]], assistant_line=False)
    sim = Simulation(Scene((tube,), (hit,), stage=stage(6 * FPS)), device="cpu", surface=False)
    assert sim.integrator == "semiImplicitEuler"
    peak = 0.0
    for _ in range(int(6 * FPS)):
        sim.step()
        assert np.isfinite(sim.state.node_q.numpy()).all()
        peak = max(peak, sim.max_displacement())
    print(f"soft tube, 1e6 N for one frame: peak {peak:.2f} m, after 6 s {sim.max_displacement():.1e} m; {sim.warnings}")
    assert sim.integrator == "implicitEuler" and any("switched to implicit" in w for w in sim.warnings)
    # the summary's reason keeps the substeps the frames before the switch ran with
    assert re.search(r"switched to implicitEuler at frame \d+ after a blow-up \(before: \d+ substeps a frame", sim.reason)
    assert peak > 10 * r and sim.max_displacement() < 0.01 * r


def test_auto_picks_the_cheaper_stable_integrator():
    # E from 1e3 to 1e9 Pa at 24 frames a second: soft tubes take a few semi-implicit substeps,
    # stiff ones would need thousands, where implicit Euler is cheaper. An assistant line (solved
    # with the centerline by both integrators) leaves the choice to the costs.
    chosen = {}
    for E in (1e3, 1e5, 1e7, 1e9):
        params = TubeParams(density=1000.0, youngs_modulus=E, damping=1.0)
        tube = TubeSpec("/T", line(41, 1.0), [41], np.full(41, 0.02), params, pinned=[0, 1])
        sim = Simulation(Scene((tube,), stage=stage(2)), device="cpu", surface=False)
        chosen[E] = sim.integrator
        sim.step()
        sim.step()
        assert np.isfinite(sim.state.node_q.numpy()).all()
        assert sim.reason.startswith("auto")
    print(chosen)
    assert chosen[1e3] == "semiImplicitEuler" and chosen[1e9] == "implicitEuler"
    push = ForceSpec("/F", 0, 20, [0.0], [[0, 1.0, 0]], assistant_line=True)
    for E, expected in ((1e3, "semiImplicitEuler"), (1e9, "implicitEuler")):
        params = TubeParams(density=1000.0, youngs_modulus=E, damping=1.0)
        tube = TubeSpec("/T", line(41, 1.0), [41], np.full(41, 0.02), params, pinned=[0, 1])
        sim = Simulation(Scene((tube,), (push,), stage=stage(2)), device="cpu", surface=False)
        assert sim.integrator == expected and sim.model.features.assistant_line
        sim.step()
        sim.step()
        assert np.isfinite(sim.state.node_q.numpy()).all() and np.isfinite(sim.state.al_q.numpy()).all()


@pytest.mark.parametrize("load", [1, 5])
def test_non_uniform_segments_keep_the_elastica_within_1_percent(load):
    rng = np.random.default_rng(7)
    L, r, E, rho = 1.0, 0.02, 1e6, 1000.0
    seg = rng.uniform(0.5, 1.5, 20)
    seg *= L / seg.sum()
    x = np.concatenate([[-seg[0], 0.0], np.cumsum(seg)])
    EI = E * np.pi * r**4 / 4
    w1 = 1.8751**2 * np.sqrt(EI / (rho * np.pi * r**2 * L**4))
    P = load * EI / L**2
    tube = TubeSpec("/T", np.stack([x, 0 * x, 0 * x], 1), [22], np.full(22, r), TubeParams(density=rho, youngs_modulus=E, damping=1.5 * w1), pinned=[0, 1])
    scene = Scene((tube,), (ForceSpec("/F", 0, 21, [0.0], [[0, -P, 0]], assistant_line=False),))
    model = build_model(scene, device="cpu")
    solver = SemiImplicitEulerSolver(model)
    dt = 0.5 * critical_time_step(model.host)
    control = model.control()
    fe = np.zeros((1, 22, 3))
    fe[0, -1] = [0, -P, 0]
    control.node_f_ext.assign(fe)
    q = settle(solver, model, model.state(), control, dt, int(2 * np.pi / w1 / dt / 10) + 1, tol=3e-6 * L)
    err = np.linalg.norm(q[0, -1, :2] - elastica_tip(load, P / (E * np.pi * r**2)) * L) / L
    print(f"segments 0.5x-1.5x, PL^2/EI={load}: tip error {err:.2e} L")
    assert err < 0.01  # requirement: within 1% at 20 segments


def test_ten_thousand_points_in_one_tube_fall_rigidly():
    # Free fall of a long straight tube: every point feels the same gravity and no spring is
    # strained, so semi-implicit Euler gives exactly y_n = -g h^2 n (n + 1) / 2 for every point.
    n = 10_000
    params = TubeParams(density=1000.0, youngs_modulus=1e6)
    tube = TubeSpec("/T", line(n, 100.0), [n], np.full(n, 0.02), params)
    g = 9.81
    scene = Scene((tube,), settings=SimulationSettings(gravity=(0.0, -g, 0.0)), stage=stage(6))
    sim = Simulation(scene, device="cpu", surface=False)
    for _ in range(6):
        sim.step()
    steps = 6 * sim.substeps
    y = sim.centerline_points()[0][:, 1]
    expected = -g * sim.dt**2 * steps * (steps + 1) / 2
    # float32 velocity sums over ~700 substeps: relative round-off ~ steps x 6e-8 = 4e-5.
    np.testing.assert_allclose(y, expected, rtol=1e-4)


def test_long_curved_tube_stays_still():
    # 10,000 points on a helix: the rest-curvature frames are carried over 10,000 edges every
    # substep; round-off in that scan must not make the tube move.
    n = 10_000
    t = np.linspace(0.0, 40 * np.pi, n)
    pts = np.stack([np.cos(t), np.sin(t), 0.1 * t], axis=1)
    params = TubeParams(density=1000.0, youngs_modulus=1e5, damping=2.0)
    tube = TubeSpec("/T", pts, [n], np.full(n, 0.005), params, pinned=[0, 1])
    sim = Simulation(Scene((tube,), stage=stage(4)), device="cpu", surface=False)
    for _ in range(4):
        sim.step()
    drift = np.abs(sim.centerline_points()[0] - pts).max()
    length = np.linalg.norm(np.diff(pts, axis=0), axis=1).sum()
    print(f"10,000-point helix, largest drift after 4 frames: {drift:.2e} m ({drift / length:.1e} of its length)")
    assert drift < 1e-6 * length


def test_near_zero_length_segments_are_rejected():
    pts = line(5, 1.0)
    pts[3] = pts[2] + [1e-9, 0.0, 0.0]
    with pytest.raises(SceneError, match=r"points\[2\] and points\[3\]"):
        TubeSpec("/T", pts, [5], np.full(5, 0.01), TubeParams(density=1000.0, youngs_modulus=1e6))


def test_hairpin_fold_warns_that_distant_parts_touch():
    # Both ends clamped side by side 1.2 radii apart: the tube folds into a hairpin whose bend has
    # radius x curvature > 1 and whose legs come closer than two radii.
    r, n, L, frames = 0.01, 41, 0.07, 60
    pts = line(n, L)
    c = np.array([L / 2, 0.6 * r, 0.0])
    track = []
    for k in range(frames + 1):
        th = np.pi * min(1.0, k / 48)
        rot = np.array([[np.cos(th), -np.sin(th), 0], [np.sin(th), np.cos(th), 0], [0, 0, 1]])
        track.append(np.concatenate([pts[[0, 1]], (pts[[n - 2, n - 1]] - c) @ rot.T + c]))
    params = TubeParams(density=1050.0, youngs_modulus=2e4, damping=5.0)
    tube = TubeSpec("/T", pts, [n], np.full(n, r), params, pinned=[0, 1, n - 2, n - 1], pin_track=np.array(track))
    sim = Simulation(Scene((tube,), stage=stage(frames)), device="cpu")
    for _ in range(frames):
        sim.step()
    q = sim.centerline_points()[0]
    a, b = q[1:-1] - q[:-2], q[2:] - q[1:-1]
    phi = np.arccos(np.clip(np.sum(a * b, 1) / np.linalg.norm(a, axis=1) / np.linalg.norm(b, axis=1), -1, 1))
    kappa = 2 * np.tan(phi / 2) / (0.5 * (np.linalg.norm(a, axis=1) + np.linalg.norm(b, axis=1)))
    print(f"hairpin: largest radius x curvature {r * kappa.max():.2f}; warnings: {sim.warnings}")
    assert r * kappa.max() > 1.0
    assert any("closer than the sum of their radii" in w for w in sim.warnings)
    # No local self-intersection: no two triangles from rings less than pi r apart along the
    # centerline cross (exhaustive; the check itself is shown to find crossings in test_surface).
    points = sim.surface()[0][0]
    builder = sim.surfaces[0]
    topo = builder.topology
    hub_of_vertex = np.empty(builder.vertex_count, dtype=int)
    for ring in range(len(topo.ring_hub)):
        count = 1 if topo.ring_kind[ring] == RING_POLE else tube.params.spokes
        hub_of_vertex[topo.ring_vertex[ring] : topo.ring_vertex[ring] + count] = topo.ring_hub[ring]
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
    # eps: test_surface's 1e-10 m^3 at r = 1 m, scaled by r^3.
    i, _ = intersecting_pairs(points.astype(np.float64), topo.faces, np.pi * r, arc[hub_of_vertex], eps=1e-16)
    assert len(i) == 0, f"{len(i)} crossing triangle pairs within pi r along the tube"


def test_short_wide_tube_pushed_hard_holds_no_more_energy_than_the_push_put_in():
    """A tube 2 cm long and 2 cm in radius (8 points, E = 100 kPa, anchored at both ends, as
    ``extract`` makes of a short wide mesh) pushed in its middle with 519 N (ramped over a second,
    held a second, released): auto takes implicit Euler, whose line search must not keep a step
    that raises the incremental potential. Keeping the shortest step tried along an ill-conditioned
    Newton direction once put a frame of this tube at 88 times its segment length."""
    n, r = 8, 0.02
    params = TubeParams(density=1050.0, youngs_modulus=1e5, damping=2.0, anchor_stiffness=4491.0)
    tube = TubeSpec("/T", line(n, 0.0198), [n], np.full(n, r), params, anchors=np.array([0, 1, 6, 7]))
    push = ForceSpec("/F", 0, 4, [0.0, 1.0, 2.0, 2.5], [[0, 0, 0], [0, 519.0, 0], [0, 519.0, 0], [0, 0, 0]], assistant_line=True)
    sim = run_with_energy_bound(Scene((tube,), (push,), stage=stage(4 * FPS)), int(4 * FPS))
    assert sim.integrator == "implicitEuler"
    rest = line(n, 0.0198)
    q = sim.state.node_q.numpy()[0]
    assert np.linalg.norm(q - rest, axis=1).max() < 0.1 * r  # released at 2.5 s: back near rest at 4 s


def test_a_time_step_not_taken_as_given_is_said_in_the_reason():
    """``auto`` takes a timeStep beyond the stability bound only through implicit Euler; a
    timeStep longer than a frame runs as one substep a frame: the reason names the value asked for."""
    from warp_tube.centerline.policy import choose_integrator

    frame = 1.0 / 24.0
    soft = choose_integrator(SimulationSettings(time_step=0.01), critical_dt=3e-3, frame_dt=frame)  # 28 semi-implicit substeps: cheaper
    assert soft.integrator == "semiImplicitEuler" and soft.dt == 1.5e-3
    assert "timeStep 0.01 s exceeds the stability bound" in soft.reason, soft.reason
    stiff = choose_integrator(SimulationSettings(time_step=0.01), critical_dt=1e-7, frame_dt=frame)
    assert stiff.integrator == "implicitEuler" and stiff.dt == 0.01 and "timeStep 0.01 s exceeds" in stiff.reason
    long = choose_integrator(SimulationSettings(integrator="implicitEuler", time_step=0.5), critical_dt=1e-3, frame_dt=frame)
    assert long.dt == frame and "timeStep 0.5 s is longer than a frame: one substep a frame" in long.reason, long.reason
    within = choose_integrator(SimulationSettings(time_step=1e-4), critical_dt=1e-3, frame_dt=frame)
    assert within.dt == 1e-4 and "within the stability bound" in within.reason
