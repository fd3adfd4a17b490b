"""Analytic and independent references used by the tests and benchmarks.

- :func:`elastica_tip`: the planar elastica of a clamped cantilever under a transverse dead tip
  load, solved with scipy's boundary-value solver (optionally extensible).
- :func:`cantilever_frequency`: the first natural frequency of an Euler-Bernoulli cantilever.
- :func:`mode1`: its first mode shape.
"""

from __future__ import annotations

import numpy as np

__all__ = ["elastica_tip", "cantilever_frequency", "mode1", "BETA1"]

#: first root of 1 + cos(b) cosh(b) = 0 (clamped-free beam)
BETA1 = 1.8751040687119611


def elastica_tip(load: float, eps_per_sin: float = 0.0) -> np.ndarray:
    """Tip position (x, y) / L of a clamped cantilever with a dead tip load along -y.

    With theta the tangent angle and s the reference arclength (s in [0, 1]), moment balance is
    ``theta'' = load (1 + eps) cos(theta)``, ``theta(0) = 0``, ``theta'(1) = 0``, where
    ``load = P L^2 / EI`` and the axial strain ``eps = -eps_per_sin sin(theta)``,
    ``eps_per_sin = P / EA`` (0: inextensible).
    """
    from scipy.integrate import solve_bvp

    s = np.linspace(0.0, 1.0, 2001)

    def stretch(th):
        return 1.0 - eps_per_sin * np.sin(th)

    def rhs(_, y):
        return np.vstack([y[1], load * stretch(y[0]) * np.cos(y[0])])

    sol = solve_bvp(rhs, lambda a, b: np.array([a[0], b[1]]), s, np.zeros((2, s.size)), tol=1e-10, max_nodes=200000)
    if not sol.success:
        raise RuntimeError(f"elastica solve failed: {sol.message}")
    th = sol.sol(s)[0]
    return np.array([np.trapezoid(stretch(th) * np.cos(th), s), np.trapezoid(stretch(th) * np.sin(th), s)])


def cantilever_frequency(EI: float, mass_per_length: float, length: float) -> float:
    """First natural frequency [Hz] of a clamped-free Euler-Bernoulli beam."""
    return BETA1**2 / (2.0 * np.pi) * np.sqrt(EI / (mass_per_length * length**4))


def mode1(s):
    """First clamped-free mode shape of the Euler-Bernoulli beam at s / L (max 1 at the tip)."""
    b = BETA1 * s
    sigma = (np.cosh(BETA1) + np.cos(BETA1)) / (np.sinh(BETA1) + np.sin(BETA1))
    phi = np.cosh(b) - np.cos(b) - sigma * (np.sinh(b) - np.sin(b))
    tip = np.cosh(BETA1) - np.cos(BETA1) - sigma * (np.sinh(BETA1) - np.sin(BETA1))
    return phi / tip
