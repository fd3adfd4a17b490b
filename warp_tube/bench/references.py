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


def planar_rod_tip(
    length: float,
    EI: float,
    EA: float,
    rest_curvature: float = 0.0,
    weight_per_length: float = 0.0,
    tip_force=(0.0, 0.0),
) -> np.ndarray:
    """Tip position (x, y) [m] of a planar rod clamped at the origin along +x, in equilibrium.

    The rod has reference length ``length`` [m], bending stiffness ``EI`` [N m^2], axial stiffness
    ``EA`` [N], a uniform rest curvature ``rest_curvature`` [1/m] (positive: bending towards +y),
    its weight ``weight_per_length`` [N/m] along -y and a dead force ``tip_force`` (Fx, Fy) [N] at
    its free end. With s the reference arclength, theta the tangent angle, n = (nx, ny) the force
    the distal part exerts on the proximal one and m the bending moment [N m]:

    ``x' = (1 + eps) cos(theta)``, ``y' = (1 + eps) sin(theta)``, ``eps = (n . t) / EA``,
    ``theta' = rest_curvature + m / EI``, ``m' = -(x' ny - y' nx)``, ``nx' = 0``,
    ``ny' = weight_per_length``, with ``x = y = theta = 0`` at s = 0 and ``m = 0``, ``n = tip_force``
    at s = length. Solved with scipy's boundary-value solver; the straight rod with no weight is
    :func:`elastica_tip` (times ``length``).
    """
    from scipy.integrate import solve_bvp

    fx, fy = (float(v) for v in tip_force)
    s = np.linspace(0.0, length, 2001)

    def rhs(_, y):
        _x, _y, th, m, nx, ny = y
        c, sn = np.cos(th), np.sin(th)
        eps = (nx * c + ny * sn) / EA
        dx, dy = (1.0 + eps) * c, (1.0 + eps) * sn
        return np.vstack([dx, dy, rest_curvature + m / EI, -(dx * ny - dy * nx), np.zeros_like(nx), np.full_like(ny, weight_per_length)])

    def bc(a, b):
        return np.array([a[0], a[1], a[2], b[3], b[4] - fx, b[5] - fy])

    guess = np.zeros((6, s.size))
    guess[2] = rest_curvature * s
    if rest_curvature != 0.0:
        guess[0] = np.sin(rest_curvature * s) / rest_curvature
        guess[1] = (1.0 - np.cos(rest_curvature * s)) / rest_curvature
    else:
        guess[0] = s
    sol = solve_bvp(rhs, bc, s, guess, tol=1e-10, max_nodes=200000)
    if not sol.success:
        raise RuntimeError(f"planar rod solve failed: {sol.message}")
    return sol.sol(length)[:2]
