"""Statics against the exact elastica: a clamped cantilever under a transverse dead tip load.

Reference: the planar elastica solved here with scipy (no hard-coded answer). The rod is clamped
at s = 0 (points 0 and 1 pinned; the rigid segment between them lies behind the clamp and is not
part of the elastic length L) and loaded by P at s = L. With theta the tangent angle and s the
reference arclength, moment balance gives EI theta'' = P (1 + eps) cos(theta), theta(0) = 0,
theta'(L) = 0, with axial strain eps = -P sin(theta) / EA (the simulated centerline is
extensible; for PL^2/EI = 5 and r/L = 0.01 that strain is 1.25e-4, the same size as the 40-segment
discretisation error, so an inextensible reference would hide the convergence order).
"""

import numpy as np
import pytest

from warp_tube.model.tube import build_model
from warp_tube.bench.references import elastica_tip
from warp_tube.scene.spec import ForceSpec, Scene, TubeParams, TubeSpec
from warp_tube.centerline.explicit import SemiImplicitEulerSolver
from warp_tube.centerline.stability import critical_time_step

from .conftest import settle, straight_points

E, RHO, L = 1.0e6, 1000.0, 1.0


def cantilever_scene(segments, load, r_over_l, damping=None, assistant_line=False):
    r = r_over_l * L
    EI = E * np.pi * r**4 / 4.0
    w1 = 1.8751**2 * np.sqrt(EI / (RHO * np.pi * r**2 * L**4))
    pts = straight_points(segments + 2, L)
    params = TubeParams(density=RHO, youngs_modulus=E, damping=1.5 * w1 if damping is None else damping)
    tube = TubeSpec("/World/Rod", pts, [len(pts)], np.full(len(pts), r), params, pinned=[0, 1])
    P = load * EI / L**2
    force = ForceSpec("/World/Load", 0, len(pts) - 1, [0.0], [[0.0, -P, 0.0]], assistant_line=assistant_line)
    return Scene((tube,), (force,)), P, w1


def static_tip(segments, load, r_over_l, assistant_line=False):
    scene, P, w1 = cantilever_scene(segments, load, r_over_l, assistant_line=assistant_line)
    model = build_model(scene, device="cpu")
    solver = SemiImplicitEulerSolver(model)
    dt = 0.5 * critical_time_step(model.host, model.features.assistant_line)
    state, control = model.state(), model.control()
    f = np.zeros((1, model.node_count, 3))
    f[0, -1] = [0.0, -P, 0.0]
    control.node_f_ext.assign(f)
    chunk = int(2 * np.pi / w1 / dt / 10) + 1
    # Stop when no point moves 3e-6 L in a tenth of a period (the float32 jitter is ~1e-6 L), then
    # average: the result sits within ~1e-6 L of equilibrium, below the errors measured (>= 4e-5 L).
    q = settle(solver, model, state, control, dt, chunk, tol=3e-6 * L)
    tip = q[0, -1, :2]
    r = r_over_l * L
    ref = elastica_tip(load, P / (E * np.pi * r**2)) * L
    return tip, ref


def test_reference_matches_bisshopp_drucker():
    # Checks the oracle itself: inextensible tip deflection / L for PL^2/EI = 1, 2, 5 is 0.3017,
    # 0.4935, 0.7138 (Bisshopp & Drucker 1945, 4 digits).
    for load, value in ((1, 0.3017), (2, 0.4935), (5, 0.7138)):
        assert abs(-elastica_tip(load)[1] - value) < 1e-4


@pytest.mark.parametrize("load", [1, 2, 5])
def test_cantilever_tip_within_0p2_percent_at_20_segments(load):
    tip, ref = static_tip(20, load, 0.02)
    err = np.linalg.norm(tip - ref) / L
    # Requirement: tip position error <= 0.2% of L with 20 free segments (measured 0.02-0.06%).
    assert err <= 2e-3, f"tip {tip} vs elastica {ref}: error {err:.2e} L"


@pytest.mark.parametrize("load", [1, 2, 5])
def test_cantilever_converges_at_second_order(load):
    errs = []
    for n in (20, 40):
        tip, ref = static_tip(n, load, 0.01)
        errs.append(np.linalg.norm(tip - ref) / L)
    ratio = errs[0] / errs[1]
    print(f"PL^2/EI={load}: error 20 seg {errs[0]:.3e} L, 40 seg {errs[1]:.3e} L, ratio {ratio:.2f}")
    # Second order halves the segment and quarters the error; 3.5 leaves room for the float32
    # state (error floor ~1e-6 L) while excluding first order (ratio 2).
    assert ratio >= 3.5
