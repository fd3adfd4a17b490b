"""The on-chip kernel (a block per group of tubes, substeps in shared memory) against the per-tube
kernel, on the CPU: Warp runs a tiled kernel's block there as cooperative fibers, so the
shared-memory exchanges, the scans along tubes and their barriers are exercised as on a GPU."""

import numpy as np
import pytest
import warp as wp

from warp_tube.model.tube import build_model
from warp_tube.scene.spec import ForceSpec, Scene, SimulationSettings, TubeParams, TubeSpec
from warp_tube.centerline.explicit import SemiImplicitEulerSolver, twist_free
from warp_tube.centerline.stability import critical_time_step

WORLDS = 5
LENGTHS = (16, 11, 3, 40)  # curves of one prim: a 3-point tube, and one longer than a 32-thread block


def batch_model(world_count=WORLDS, lengths=LENGTHS, curved=False, spring_damping=0.0, assistant_line=False, device="cpu",
                curve_all=False, clamp_all=False, force_at=None):  # fmt: skip
    """Straight tubes of different lengths in one prim, with pins at both ends of the first, an
    anchor, gravity, mass damping and a point force; segment stiffness and damping vary by world.
    ``clamp_all``: every tube's first two points pinned too (curved tubes that cannot turn, whose
    first frames the clamps fix: what every exchange runs). ``force_at``: the pushed point's index
    in the last tube (default its middle)."""
    pts = []
    for k, n in enumerate(lengths):
        s = np.linspace(0.0, 0.02 * (n - 1), n)
        bend = 0.05 * np.sin(8 * s) if curved and (k == 0 or curve_all) else 0 * s
        pts.append(np.stack([s, 0.1 * k + bend, 0.02 * np.cos(5 * s) * (curve_all and curved)], axis=1))
    starts = np.cumsum((0,) + lengths)
    params = TubeParams(density=1050.0, youngs_modulus=5e4, damping=2.0, spring_damping=spring_damping, anchor_stiffness=40.0)
    anchors = [int(starts[k] + lengths[k] // 3) for k in range(min(1, len(lengths) - 1), len(lengths))]
    tube = TubeSpec(
        "/World/T", np.concatenate(pts), list(lengths), np.full(starts[-1], 0.01), params,
        pinned=sorted({0, 1, int(starts[1] - 1)} | ({int(p) for a in starts[1:-1] for p in (a, a + 1)} if clamp_all else set())),
        anchors=anchors,
    )  # fmt: skip
    at = lengths[-1] // 2 if force_at is None else force_at
    force = ForceSpec("/World/F", 0, int(starts[-2] + at), [0.0], [[0.0, 0.0, 0.01]], assistant_line=assistant_line)
    scene = Scene((tube,), (force,), settings=SimulationSettings(gravity=(0.0, -9.81, 0.0)))
    model = build_model(scene, world_count=world_count, device=device)
    # Parameters per world (rows read at w % rows): both kernels must pick the world's row.
    rng = np.random.default_rng(7)
    scale = rng.uniform(0.5, 1.5, (world_count, 1))
    model.seg_ke = wp.array(model.host.seg_ke[None] * scale, dtype=float, device=device)
    model.node_damping = wp.array(model.host.node_damping[None] * scale, dtype=float, device=device)
    return model


def batch_inputs(model, seed=3):
    """A state with random velocities and a control with per-world forces and moving pins."""
    rng = np.random.default_rng(seed)
    W, N = model.world_count, model.node_count
    state = model.state()
    state.node_qd.assign(rng.normal(0.0, 0.05, (W, N, 3)).astype(np.float32))
    control = model.control()
    control.node_f_ext.assign(rng.normal(0.0, 2e-3, (W, N, 3)).astype(np.float32))
    q = model.host.node_rest_q[None].repeat(W, axis=0)
    control.pin_q_start.assign(q.astype(np.float32))
    control.pin_q_end.assign((q + rng.normal(0.0, 5e-3, (W, 1, 3))).astype(np.float32))
    return state, control


def lay_line(state, control, slots: slice, x, xp, xd):
    """Lay a line in ``slots`` of every world at ``xp`` beside tube points ``x`` (float64, (W, n, 3)
    [m]), moving with ``xd``, its springs unstrained (rest lengths from these positions)."""
    al_q, al_lo, al_qd = state.al_q.numpy(), state.al_q_lo.numpy(), state.al_qd.numpy()
    hi = xp.astype(np.float32)
    al_q[:, slots], al_lo[:, slots], al_qd[:, slots] = hi, (xp - hi).astype(np.float32), xd
    p0, n = slots.start, slots.stop - slots.start
    lengths = {name: getattr(control, name).numpy() for name in ("al_link_length", "al_chord_length", "al_fwd_length", "al_bwd_length")}
    lengths["al_link_length"][:, slots] = np.linalg.norm(xp - x, axis=-1)
    lengths["al_chord_length"][:, p0 : p0 + n - 1] = np.linalg.norm(xp[:, 1:] - xp[:, :-1], axis=-1)
    lengths["al_fwd_length"][:, p0 : p0 + n - 1] = np.linalg.norm(x[:, 1:] - xp[:, :-1], axis=-1)
    lengths["al_bwd_length"][:, p0 + 1 : p0 + n] = np.linalg.norm(x[:, :-1] - xp[:, 1:], axis=-1)
    for array, values in ((state.al_q, al_q), (state.al_q_lo, al_lo), (state.al_qd, al_qd)):
        array.assign(values)
    for name, values in lengths.items():
        getattr(control, name).assign(values)


def integrated(model, substeps, frames, lines, solver_args):
    """The state after ``frames`` frames of ``substeps`` from :func:`batch_inputs` (with
    ``lines``, the force's assistant line laid beside its tube in every world, 1 cm off the axis,
    and active), and the solver. The pins move on at the same speed frame after frame (each
    frame's targets start where the last ended, as a scene's moving pins do: a target that jumped
    back each frame would jolt the pinned nodes, and a line beside them makes that motion so
    sensitive that a 1e-7 change of a stiffness moves it by millimetres)."""
    solver = SemiImplicitEulerSolver(model, **solver_args)
    s0, control = batch_inputs(model)
    pin_a, pin_b = control.pin_q_start.numpy().copy(), control.pin_q_end.numpy().copy()  # (on the CPU: views, which assign would change)
    h = model.host
    if lines and model.al_slots:
        t = int(h.force_tube[0])
        s, e, p0 = int(h.tube_node_start[t]), int(h.tube_node_start[t + 1]), int(h.al_start[0])
        q = s0.node_q.numpy().astype(np.float64) + s0.node_q_lo.numpy()
        lay_line(s0, control, slice(p0, p0 + e - s), q[:, s:e], q[:, s:e] + np.array([0.0, 0.0, 0.01]), s0.node_qd.numpy()[:, s:e])
        control.al_active.fill_(1)
    s1 = model.state()
    dt = 0.5 * critical_time_step(model.host)
    for f in range(frames):
        control.pin_q_start.assign(pin_a + f * (pin_b - pin_a))
        control.pin_q_end.assign(pin_a + (f + 1) * (pin_b - pin_a))
        solver.integrate(s0, s1, control, dt, substeps)
        s0, s1 = s1, s0
    return s0, solver


def run(model, substeps=150, frames=2, **solver_args):
    """Positions (compensated, float64) and velocities after ``frames`` frames of ``substeps``."""
    s0, solver = integrated(model, substeps, frames, False, solver_args)
    q = s0.node_q.numpy().astype(np.float64) + s0.node_q_lo.numpy()
    return q, s0.node_qd.numpy(), solver


@pytest.fixture(scope="module")
def reference():
    model = batch_model()
    q, qd, _ = run(model, onchip=False)
    return model, q, qd


@pytest.mark.parametrize("block_dim", [32, 256])
def test_onchip_matches_per_tube(reference, block_dim):
    model, q_ref, qd_ref = reference
    assert model.features == model.features._replace(
        bending=True, curved=False, anchors=True, gravity=True, mass_damping=True, spring_damping=False, external=True, assistant_line=False
    )
    q, qd, solver = run(model, onchip=True, block_dim=block_dim)
    assert solver.onchip
    if block_dim == 32:
        # The 40-point tube widens the block to 64; the tubes split into two groups.
        assert (solver.onchip_block_dim, solver._onchip_dim[1], solver._onchip_worlds_per_block) == (64, 2, 1)
    else:
        # One group of all 70 nodes, three worlds per block, the second block partly idle.
        assert (solver.onchip_block_dim, solver._onchip_dim, solver._onchip_worlds_per_block) == (256, (2, 1), 3)
    moved = np.abs(q_ref - model.host.node_rest_q[None]).max()
    assert moved > 5e-3  # it really moved
    # The same forces, each spring and stencil summed onto its nodes in another order (exchanged
    # through shared memory against added in a loop), so the runs differ by float32 round-off (a
    # few 1e-8 m per substep at positions of ~0.1 m) carried through 300 damped substeps: 1e-6 m
    # is ~30 ulp, 1e-4 of the motion; velocities (~0.05 m/s) to the same relative size.
    np.testing.assert_allclose(q, q_ref, rtol=0, atol=1e-6)
    np.testing.assert_allclose(qd, qd_ref, rtol=0, atol=1e-5 * np.abs(qd_ref).max())


@pytest.mark.parametrize("block_dim", [32, 256])
def test_onchip_curved_and_spring_damped_matches_per_tube(block_dim):
    # A curved tube (the scan of frame transports and of holonomy weights along it, over a
    # 40-point tube: six rounds) with spring damping, per-world stiffness and damping.
    model = batch_model(curved=True, spring_damping=1e-4, curve_all=True)
    assert model.features.curved and model.features.spring_damping
    q_ref, qd_ref, _ = run(model, onchip=False)
    q, qd, solver = run(model, onchip=True, block_dim=block_dim)
    assert solver.onchip
    assert np.abs(q_ref - model.host.node_rest_q[None]).max() > 5e-3
    # As above (measured 7e-8 m, velocities 1e-6 of their size).
    np.testing.assert_allclose(q, q_ref, rtol=0, atol=1e-6)
    np.testing.assert_allclose(qd, qd_ref, rtol=0, atol=1e-5 * np.abs(qd_ref).max())


@pytest.mark.skipif(not wp.get_cuda_device_count(), reason="no CUDA device")
def test_onchip_cuda_matches_cpu(reference):
    _, q_ref, _ = reference
    q, _, solver = run(batch_model(device="cuda:0"), onchip=True)
    assert solver.onchip
    # Fast math (approximate division and square root) and FMA on the GPU against the CPU's
    # per-tube kernel: a few float32 ulp per substep.
    np.testing.assert_allclose(q, q_ref, rtol=0, atol=1e-5)


def test_onchip_pins_reach_their_targets_and_input_is_kept():
    model = batch_model(world_count=2, lengths=(9, 5))
    solver = SemiImplicitEulerSolver(model, onchip=True, block_dim=32)
    s0, control = batch_inputs(model)
    before = s0.node_q.numpy().copy()
    s1 = model.state()
    solver.integrate(s0, s1, control, 1e-4, 7)
    np.testing.assert_array_equal(s0.node_q.numpy(), before)
    pinned = model.host.node_inv_mass == 0.0
    # lerp(a, b, 1) = a + (b - a): within an ulp of b (positions ~0.2 m, ulp ~1.5e-8 m).
    np.testing.assert_allclose(s1.node_q.numpy()[:, pinned], control.pin_q_end.numpy()[:, pinned], rtol=0, atol=1e-7)
    np.testing.assert_array_equal(s1.node_q_lo.numpy()[:, pinned], 0.0)


def test_onchip_falls_back_for_tubes_longer_than_a_block():
    # A tube longer than the largest block takes the per-tube kernel (correct, sequential along
    # the tube), whatever was asked.
    model = batch_model(world_count=1, lengths=(1100,))
    solver = SemiImplicitEulerSolver(model, onchip=True)
    assert not solver.onchip and solver.onchip_block_dim is None


def test_warp_alignment_of_layouts():
    from warp_tube.centerline.explicit import warp_aligned

    # two 32-point tubes in a group of 64 nodes, two copies of it a block: each tube in a warp
    assert warp_aligned(np.array([0, 32, 64]), np.array([0, 64]), 64, 2)
    # 20-point tubes, six copies a block (lanes 20-39 cross the warp boundary at 32): not
    assert not warp_aligned(np.array([0, 20]), np.array([0, 20]), 20, 6)
    assert warp_aligned(np.array([0, 20]), np.array([0, 20]), 20, 1)
    # a 16- and an 11-point tube: the second copy of the group starts at lane 27
    assert not warp_aligned(np.array([0, 16, 27]), np.array([0, 27]), 27, 4)
    # the CPU has no warps: shuffles are refused, "auto" exchanges through shared memory
    model = batch_model(world_count=2, lengths=(32, 16, 8, 8))
    with pytest.raises(ValueError, match="CUDA device"):
        SemiImplicitEulerSolver(model, onchip=True, exchange="shuffle")
    assert SemiImplicitEulerSolver(model, onchip=True).onchip_exchange == "shared"


def test_auto_pads_curved_tubes_to_whole_warps():
    # Tubes that would cross a warp boundary in the compact layout are padded to shuffles on
    # request, and under "auto" only when curved (measured faster there, slower when straight)
    from warp_tube.centerline.explicit import pads_to_warps

    assert pads_to_warps("shuffle", False) and pads_to_warps("shuffle", True)
    assert pads_to_warps("auto", True) and not pads_to_warps("auto", False)
    assert not pads_to_warps("shared", True) and not pads_to_warps("mixed", True)


def run_with_lines(model, substeps=150, frames=2, **solver_args):
    """As :func:`run`, with the force's assistant line active from the start; also the lines'
    positions."""
    s0, solver = integrated(model, substeps, frames, True, solver_args)
    q = s0.node_q.numpy().astype(np.float64) + s0.node_q_lo.numpy()
    return q, s0.node_qd.numpy(), s0.al_q.numpy(), solver


@pytest.mark.parametrize("clamp_all", [False, True])
def test_onchip_with_active_lines_matches_per_tube(clamp_all):
    # Curved tubes with every feature and the force's assistant line active from the start, on
    # the CPU's blocks: the line points' exchange and springs against the per-tube kernel.
    # Measured 4e-8 m (tube) and 8e-8 m (line points, ~0.3 m); 1e-6 m as above. ``clamp_all``:
    # the force's tube clamped too, its line beside moving pins (measured 4.9e-8 / 7.3e-8 m).
    kw = dict(lengths=(32, 16, 8, 8), curved=True, spring_damping=1e-4, assistant_line=True, curve_all=True,
              clamp_all=clamp_all)
    q_ref, _, al_ref, _ = run_with_lines(batch_model(**kw), onchip=False)
    q, _, al, solver = run_with_lines(batch_model(**kw), onchip=True)
    assert solver.onchip and np.abs(al_ref).max() > 0.1  # the lines exist (not the zeros of unused slots)
    np.testing.assert_allclose(q, q_ref, rtol=0, atol=1e-6)
    np.testing.assert_allclose(al, al_ref, rtol=0, atol=1e-6)


@pytest.mark.parametrize("force_at", [0, 1, 6, 7])
def test_onchip_line_springs_at_a_tube_s_ends_match_per_tube(force_at):
    # The on-chip kernel evaluates each tractive spring on the thread of the edge it crosses
    # (forward at and after the force point, the next point's backward spring before it), the
    # per-tube kernel by line point; a push at a tube's first or last point (and next to them)
    # makes every tractive spring of the tube forward or backward, and the force point's own
    # four springs sit at the tube's end. Curved, spring-damped, unclamped 8-point tube with its
    # line active from the start, on the CPU's blocks, 150 substeps: the same positions to
    # float32 round-off (measured 3e-8 to 9e-8 m, positions ~0.3 m); 1e-6 m as above.
    kw = dict(lengths=(16, 8), curved=True, spring_damping=1e-4, assistant_line=True, curve_all=True, force_at=force_at)
    q_ref, _, al_ref, _ = run_with_lines(batch_model(**kw), onchip=False)
    q, _, al, solver = run_with_lines(batch_model(**kw), onchip=True)
    assert solver.onchip and np.abs(al_ref).max() > 0.1
    moved = np.abs(q_ref - batch_model(**kw).host.node_rest_q[None]).max()
    assert moved > 1e-4, moved  # the push and the line moved the tube: the comparison is not of rest states
    np.testing.assert_allclose(q, q_ref, rtol=0, atol=1e-6)
    np.testing.assert_allclose(al, al_ref, rtol=0, atol=1e-6)


@pytest.mark.gpu
@pytest.mark.skipif(not wp.get_cuda_device_count(), reason="no CUDA device")
@pytest.mark.parametrize("features", ["straight", "every", "every, padded"])
def test_onchip_shuffle_exchange_matches_shared_memory_on_cuda(features):
    # Tubes laid out so that each lies within one warp (groups of 64 nodes, two a block): the
    # neighbours' values pass through warp shuffles instead of shared memory. The values
    # exchanged (bit for bit) and the arithmetic on them are the same; the compiler contracts
    # products and sums into FMAs differently in the two kernels, so they differ by float32
    # round-off: measured 2.5e-8 m after 300 substeps (positions ~0.1 m, ulp ~7e-9 m); 1e-6 m
    # allows the same ~30 ulp as the CPU comparisons above.
    # "padded": a 20-point tube a world, six worlds to a 128-thread block in the compact layout
    # (crossing warp boundaries): shuffles take a layout of one world a warp.
    # Every tube clamped, the force's tube too (its line points beside the moving clamps); "free to
    # turn": only the first tube clamped, the others' first frames twisted to the energy's minimum
    # (a sum over each tube, through shuffles or shared memory).
    every = features.startswith("every")
    free = features.endswith("free to turn")
    lengths = (20,) if features.endswith("padded") else (32, 16, 8, 8)
    kw = dict(lengths=lengths, curved=every, spring_damping=1e-4 if every else 0.0, assistant_line=every, curve_all=every,
              clamp_all=not free)
    model = batch_model(device="cuda:0", **kw)
    assert model.features.assistant_line == every and model.features.curved == every
    assert twist_free(model) == free
    out = {}
    for exchange in ("shuffle", "shared"):
        q, qd, al, solver = run_with_lines(model, onchip=True, exchange=exchange)
        assert solver.onchip_exchange == exchange
        if lengths == (20,):
            assert solver._onchip_slot == (32 if exchange == "shuffle" else 20)
        out[exchange] = (q, qd, al)
    assert np.abs(out["shared"][0] - model.host.node_rest_q[None]).max() > 5e-3  # it moved
    q_sh, qd_sh, al_sh = out["shuffle"]
    q_sm, qd_sm, al_sm = out["shared"]
    np.testing.assert_allclose(q_sh, q_sm, rtol=0, atol=1e-6)
    # Velocities and the line points (held only by their tractive springs) grow the round-off
    # faster than the tube's positions: measured 4.2e-5 m/s (velocities up to 0.63 m/s) and
    # 1.5e-6 m in the 20-point tube with every feature; bounds: 1e-4 of the largest velocity,
    # and for the line points the 1e-5 m of the CUDA-CPU comparisons.
    np.testing.assert_allclose(qd_sh, qd_sm, rtol=0, atol=1e-4 * np.abs(qd_sm).max())
    np.testing.assert_allclose(al_sh, al_sm, rtol=0, atol=1e-5)
    # and against the per-tube kernel on the CPU: fast math and FMA on the GPU, a few float32
    # ulp per substep (as test_onchip_cuda_matches_cpu)
    q_cpu, _, _, _ = run_with_lines(batch_model(**kw), onchip=False)
    np.testing.assert_allclose(out["shuffle"][0], q_cpu, rtol=0, atol=1e-5)


@pytest.mark.gpu
@pytest.mark.skipif(not wp.get_cuda_device_count(), reason="no CUDA device")
@pytest.mark.parametrize("block_dim", [32, 128])
def test_onchip_mixed_exchange_matches_shared_memory_on_cuda(block_dim):
    # Curved tubes of 16, 11, 3 and 40 points: with 128 threads a block they sit at lanes 0-15,
    # 16-26, 27-29 and 30-69 (the last spans three warps); with 32 the 40-point tube widens the
    # block to 64 and spans two. The scans run within warps by shuffles and are carried between
    # warps through shared memory: the same products and sums in another order, so float32
    # round-off apart (bounds as in the shuffle test above).
    kw = dict(curved=True, spring_damping=1e-4, assistant_line=True, curve_all=True, clamp_all=True)  # (every tube clamped: as above)
    model = batch_model(device="cuda:0", **kw)
    out = {}
    for exchange in ("mixed", "shared"):
        q, qd, al, solver = run_with_lines(model, onchip=True, exchange=exchange, block_dim=block_dim)
        assert solver.onchip_exchange == exchange
        out[exchange] = (q, qd, al)
    # by request only: "auto" keeps shared memory here (the scans' order would depend on where a
    # world sits against warp boundaries)
    assert SemiImplicitEulerSolver(model, onchip=True, block_dim=block_dim).onchip_exchange == "shared"
    q_mx, qd_mx, al_mx = out["mixed"]
    q_sm, qd_sm, al_sm = out["shared"]
    assert np.abs(q_sm - model.host.node_rest_q[None]).max() > 5e-3  # it moved
    np.testing.assert_allclose(q_mx, q_sm, rtol=0, atol=1e-6)
    np.testing.assert_allclose(qd_mx, qd_sm, rtol=0, atol=1e-4 * np.abs(qd_sm).max())
    np.testing.assert_allclose(al_mx, al_sm, rtol=0, atol=1e-5)
