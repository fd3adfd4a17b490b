"""Stability bound of semi-implicit Euler for a TubeModel, and the substep it implies.

For a linear system ``M x'' + C x' + K x = 0`` semi-implicit (symplectic) Euler is stable for
``h <= (2 / w_max) (sqrt(1 + z^2) - z)``, with ``w_max`` the highest natural frequency and
``z = beta w_max / 2`` the damping ratio that stiffness-proportional damping ``beta`` [s] gives it
(mass-proportional damping is integrated implicitly and does not limit ``h``).

``w_max^2`` is bounded above by Gershgorin's theorem on ``M^-1 K``: for each free node, the sum of
the absolute entries of its row of the stiffness matrix, divided by its mass. Structural and
returning springs contribute ``2 ke`` (diagonal plus neighbour); a bending stencil of coefficient
``k = EI / l_v`` on edges ``la``, ``lb`` has Jacobian magnitudes ``(1/la, 1/la + 1/lb, 1/lb)`` on its
three nodes, so node m's row gets ``k |J_m| sum_n |J_n|``. On a uniform chain the bound is exact as
the chain grows: ``4 EA / (m l)`` axially and ``16 EI / (m l^3)`` in bending.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["max_frequency", "critical_time_step"]


def _row_sums(host: dict, assistant_line: bool) -> np.ndarray:
    start = host["tube_node_start"]
    ke = host["seg_ke"]
    l = host["seg_rest_length"]
    bk = host["node_bend_k"]
    n = len(ke)
    rows = np.zeros(n)
    last = np.zeros(n, dtype=bool)
    last[start[1:] - 1] = True
    seg_ok = ~last  # segment i exists where node i is not its tube's last node
    axial = np.where(seg_ok, 2.0 * ke, 0.0)
    rows += axial
    rows[1:] += axial[:-1]
    if assistant_line:
        rows += 2.0 * rows  # a link and a tractive spring beside every structural one
    inv_l = np.where(seg_ok & (l > 0), 1.0 / np.where(l > 0, l, 1.0), 0.0)
    for j in np.nonzero(bk > 0)[0]:
        ja, jb = inv_l[j - 1], inv_l[j]
        jac = np.array([ja, ja + jb, jb])
        rows[j - 1 : j + 2] += bk[j] * jac * jac.sum()
    rows += 2.0 * host["node_anchor_k"]
    return rows


def max_frequency(host: dict, assistant_line: bool = False) -> float:
    """Upper bound of the highest natural frequency [rad/s] of the free nodes."""
    rows = _row_sums(host, assistant_line)
    free = host["node_inv_mass"] > 0
    if not free.any():
        return 0.0
    return float(math.sqrt(np.max(rows[free] * host["node_inv_mass"][free])))


def critical_time_step(host: dict, assistant_line: bool = False, spring_damping: float = 0.0) -> float:
    """Largest stable semi-implicit Euler step [s] (inf when nothing is free or stiff)."""
    w = max_frequency(host, assistant_line)
    if w <= 0.0:
        return math.inf
    z = 0.5 * spring_damping * w
    return (2.0 / w) * (math.sqrt(1.0 + z * z) - z)
