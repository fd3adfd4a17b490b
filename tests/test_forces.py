"""The kernels' forces are the exact negative gradient of the energy (tests.oracle_energy, written
independently in NumPy/float64), checked by central finite differences."""

import numpy as np
import pytest

from .oracle_energy import potential_energy
from warp_tube.model.tube import build_model
from warp_tube.scene.spec import Scene, TubeParams, TubeSpec
from warp_tube.centerline.explicit import SemiImplicitEulerSolver


def kernel_force(model, q, onchip):
    """Force [N] on every node at positions q: one substep from rest with zero velocity gives
    v = dt f / m."""
    s0, s1 = model.state(), model.state()
    s0.node_q.assign(q[None].astype(np.float32))
    dt = 1e-4
    SemiImplicitEulerSolver(model, onchip=onchip).integrate(s0, s1, model.control(), dt, 1)
    return s1.node_qd.numpy()[0].astype(np.float64) * model.host.node_mass[:, None] / dt, s0.node_q.numpy()[0].astype(np.float64)


@pytest.mark.parametrize("shape", ["straight", "helix"])
@pytest.mark.parametrize("onchip", [False, True])
def test_forces_are_the_energy_gradient(shape, onchip):
    rng = np.random.default_rng(5)
    n = 12
    t = np.linspace(0.0, 3.0, n)
    rest = np.stack([t, 0 * t, 0 * t], 1) if shape == "straight" else np.stack([np.cos(t), np.sin(t), 0.3 * t], 1)
    tube = TubeSpec("/T", rest, [n], np.full(n, 0.05), TubeParams(density=1000.0, youngs_modulus=1e6))
    model = build_model(Scene((tube,)), device="cpu")
    assert model.features.curved == (shape == "helix")
    f, q = kernel_force(model, rest + rng.normal(scale=0.05, size=rest.shape), onchip)
    h = 1e-6
    grad = np.zeros_like(q)
    for i in range(n):
        for k in range(3):
            qp, qm = q.copy(), q.copy()
            qp[i, k] += h
            qm[i, k] -= h
            grad[i, k] = (potential_energy(model.host, qp) - potential_energy(model.host, qm)) / (2 * h)
    err = np.abs(f + grad).max() / np.abs(grad).max()
    # float32 forces (~1e-6 relative after the v = dt f / m round trip) against a float64
    # central difference (truncation ~h^2 ~ 1e-12): 1e-4 separates an exact gradient from one
    # missing the curved frames' terms (2% here).
    assert err < 1e-4, f"relative force error {err:.2e}"
