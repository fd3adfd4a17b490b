"""Stability bound of semi-implicit Euler for a TubeModel, and the substep it implies.

For a linear system ``M x'' + C x' + K x = 0`` semi-implicit (symplectic) Euler is stable for
``h <= (2 / w_max) (sqrt(1 + z^2) - z)``, with ``w_max`` the highest natural frequency and
``z = beta w_max / 2`` the damping ratio that stiffness-proportional damping ``beta`` [s] gives it
(mass-proportional damping is integrated implicitly and does not limit ``h``).

``w_max^2`` is bounded above by Gershgorin's theorem on ``M^-1 K``: for each free node, the sum of
the absolute entries of its row of the stiffness matrix, divided by its mass. Each force term
defines what it adds to those rows next to its force and stiffness (``warp_tube.kernels.springs``):
structural and returning springs ``2 ke`` (diagonal plus neighbour), each assistant line a link
and a tractive spring beside every structural spring, a bending stencil of coefficient
``k = EI / l_v`` on edges ``la``, ``lb`` ``k |J_m| sum_n |J_n|`` on its node m, with the Jacobian
magnitudes ``(1/la, 1/la + 1/lb, 1/lb)``. On a uniform chain the bound is exact as the chain
grows: ``4 EA / (m l)`` axially and ``16 EI / (m l^3)`` in bending.
"""

from __future__ import annotations

import math

import numpy as np
import warp as wp

from warp_tube.kernels.springs import StabilityArrays, stability_rows_kernel

from ..model.host import HostArrays

__all__ = ["max_frequency", "critical_time_step", "critical_time_steps"]


def _row_sums(host: HostArrays, assistant_line: bool) -> np.ndarray:
    """Gershgorin row sums [N/m] of the stiffness, shape (node_count,), from each term's row
    function next to its force (``warp_tube.kernels.springs``: spring_rows, bend_rows, anchor_rows,
    al_rows), evaluated in float64 on the CPU."""
    start = np.asarray(host.tube_node_start, dtype=np.int32)
    lines = 0
    if assistant_line:
        lines = max(1, int((host.tube_al_force >= 0).sum(axis=1).max()))
    fields = StabilityArrays()
    for name in StabilityArrays.vars:
        # (read only: the host's own memory where it is contiguous float64)
        setattr(fields, name, wp.array(np.ascontiguousarray(getattr(host, name), dtype=np.float64), dtype=wp.float64,
                                       device="cpu", copy=False))  # fmt: skip
    rows = wp.zeros(len(host.seg_ke), dtype=wp.float64, device="cpu")
    wp.launch(stability_rows_kernel, len(start) - 1, device="cpu", inputs=[lines, wp.array(start, dtype=int, device="cpu"), fields], outputs=[rows])
    return rows.numpy()


def max_frequency(host: HostArrays, assistant_line: bool = False) -> float:
    """Upper bound of the highest natural frequency [rad/s] of the free nodes."""
    rows = _row_sums(host, assistant_line)
    free = host.node_inv_mass > 0
    if not free.any():
        return 0.0
    return float(math.sqrt(np.max(rows[free] * host.node_inv_mass[free])))


def critical_time_step(host: HostArrays, assistant_line: bool = False, spring_damping: float = 0.0) -> float:
    """Largest stable semi-implicit Euler step [s] (inf when nothing is free or stiff)."""
    w = max_frequency(host, assistant_line)
    if w <= 0.0:
        return math.inf
    z = 0.5 * spring_damping * w
    return (2.0 / w) * (math.sqrt(1.0 + z * z) - z)


def critical_time_steps(host: HostArrays, parts: int, assistant_line: bool, spring_damping: np.ndarray) -> np.ndarray:
    """:func:`critical_time_step` [s] of each of ``parts`` equal node ranges of one model at once.

    For a model whose nodes are ``parts`` copies of one layout (scenes of one batch group built
    together), part ``k`` being nodes ``k * n`` to ``(k + 1) * n``; the row sums come from one
    launch. ``spring_damping`` [1/s], shape (parts,). Returns shape (parts,), inf where a part has
    nothing free or stiff.
    """
    rows = _row_sums(host, assistant_line)
    inv_mass = np.asarray(host.node_inv_mass, dtype=np.float64)
    rate = np.where(inv_mass > 0, rows * inv_mass, 0.0).reshape(parts, -1)
    w = np.sqrt(np.maximum(rate.max(axis=1), 0.0))
    z = 0.5 * np.asarray(spring_damping, dtype=np.float64) * w
    with np.errstate(divide="ignore"):
        return np.where(w > 0.0, (2.0 / np.where(w > 0.0, w, 1.0)) * (np.sqrt(1.0 + z * z) - z), np.inf)
