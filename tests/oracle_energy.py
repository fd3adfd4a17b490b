"""Mechanical energy of a TubeModel state, in NumPy (float64), for checks and diagnostics.

This is the energy whose negative gradient the kernels apply (structural, bending and returning
springs, gravity), written independently of them; tests compare the two.
"""

from __future__ import annotations

import numpy as np

from warp_tube.model.host import HostArrays
from warp_tube.model.tube import curvature_binormal

__all__ = ["potential_energy", "kinetic_energy", "total_energy"]


def _kappa_targets(host: HostArrays, q: np.ndarray) -> np.ndarray:
    """Rest curvature carried into the current shape (same construction as the kernel)."""
    from warp_tube.model.frames import rotate_minimal
    from warp_tube.model.tube import first_edge_normal

    out = np.zeros_like(q)
    start = host.tube_node_start
    kr = host.node_kappa_rest
    rest = host.node_rest_q
    for t in range(len(start) - 1):
        s, e = start[t], start[t + 1]
        if e - s < 3 or not np.abs(kr[s:e]).max() > 0:
            continue
        t_rest = rest[s + 1] - rest[s]
        t_rest /= np.linalg.norm(t_rest)
        tc = q[s + 1] - q[s]
        tc /= np.linalg.norm(tc)
        u = rotate_minimal(t_rest, tc, first_edge_normal(t_rest))
        tangents = {}
        for j in range(s + 1, e - 1):
            c = kr[j]
            out[j] = tc * c[0] + u * c[1] + np.cross(tc, u) * c[2]
            tangents[j] = tc
            tn = q[j + 1] - q[j]
            tn /= np.linalg.norm(tn)
            u = rotate_minimal(tc, tn, u)
            u -= tn * np.dot(u, tn)
            u /= np.linalg.norm(u)
            tc = tn
        if host.node_inv_mass[s] > 0 or host.node_inv_mass[s + 1] > 0:
            # No clamp fixes the first frame's twist: the twist psi that minimises the bending
            # energy, sum k/2 |kb - T(psi)|^2 with every target turned by psi about its edge.
            idx = np.arange(s + 1, e - 1)
            tj = np.array([tangents[j] for j in idx])
            kb = curvature_binormal(q[idx] - q[idx - 1], q[idx + 1] - q[idx])
            perp = out[idx] - tj * np.sum(out[idx] * tj, axis=1)[:, None]
            k = host.node_bend_k[idx]
            a = np.sum(k * np.sum(kb * perp, axis=1))
            b = np.sum(k * np.sum(kb * np.cross(tj, perp), axis=1))
            if a != 0.0 or b != 0.0:
                psi = np.arctan2(b, a)
                out[idx] = out[idx] - perp + perp * np.cos(psi) + np.cross(tj, perp) * np.sin(psi)
    return out


def potential_energy(host: HostArrays, q: np.ndarray, gravity=None) -> float:
    """Elastic + gravitational potential energy [J] of positions ``q`` [m], shape (N, 3)."""
    q = np.asarray(q, dtype=np.float64)
    start = host.tube_node_start
    n = len(q)
    last = np.zeros(n, dtype=bool)
    last[start[1:] - 1] = True
    seg = np.nonzero(~last)[0]
    d = np.linalg.norm(q[seg + 1] - q[seg], axis=1)
    e = 0.5 * np.sum(host.seg_ke[seg] * (d - host.seg_rest_length[seg]) ** 2)
    bk = host.node_bend_k
    j = np.nonzero(bk > 0)[0]
    if len(j):
        kb = curvature_binormal(q[j] - q[j - 1], q[j + 1] - q[j])
        target = _kappa_targets(host, q)[j]
        e += 0.5 * np.sum(bk[j] * np.sum((kb - target) ** 2, axis=1))
    ka = host.node_anchor_k
    e += 0.5 * np.sum(ka * np.sum((q - host.node_rest_q) ** 2, axis=1))
    if gravity is not None:
        e -= np.sum(host.node_mass * (q @ np.asarray(gravity, dtype=np.float64)))
    return float(e)


def kinetic_energy(host: HostArrays, qd: np.ndarray) -> float:
    """Kinetic energy [J] of the free nodes with velocities ``qd`` [m/s], shape (N, 3)."""
    free = host.node_inv_mass > 0
    return float(0.5 * np.sum(host.node_mass[free] * np.sum(np.asarray(qd, dtype=np.float64)[free] ** 2, axis=1)))


def total_energy(host: HostArrays, q: np.ndarray, qd: np.ndarray, gravity=None) -> float:
    """Kinetic + potential energy [J]."""
    return kinetic_energy(host, qd) + potential_energy(host, q, gravity)

