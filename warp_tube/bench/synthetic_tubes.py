"""Synthetic tube meshes around known smooth 3D curves: the oracle of centerline extraction.

Each curve is integrated from a prescribed curvature ``kappa(s)`` and torsion ``tau(s)`` (the
Frenet-Serret equations, fourth-order Runge-Kutta on a fine arclength grid), so it is smooth and its
curvature and torsion are known. The tube is the sweep of a circle of radius ``r(s)`` in the plane
normal to the curve (rings of ``ring`` vertices, joined by triangle strips), so the centre of every
normal cross-section lies exactly on the curve and its radius is exactly ``r(s)``. Ends are open
(boundary loops), closed by a flat cap (a fan in the end ring's plane, like a tube cut and sealed)
or by a round cap (a hemisphere of the end radius, like a vessel's blind tip).

:func:`synthetic_cases` gives the standard set (24 tubes: straight, arcs, helices of low and high
torsion, S-curves, 3D wiggles, hairpins, spirals; radius constant, tapering, waisted or wavy;
``radius x curvature`` up to 0.85). :func:`check_case` verifies that a case is a valid tube (no
self-intersection of the swept surface).

Lengths are in the tube's own units (radius about 1 before ``scale``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
import trimesh

__all__ = ["SyntheticTube", "frenet_curve", "sweep_mesh", "synthetic_cases", "check_case"]


@dataclass(frozen=True)
class SyntheticTube:
    """A tube mesh with its true centre curve.

    Attributes:
        name: short label.
        mesh: the tube surface [units], V vertices.
        curve: the true centre curve, densely sampled [units], shape (K, 3).
        radius: the true radius at each curve sample [units], shape (K,).
        curvature: curvature at each sample [1/units], shape (K,).
        torsion: torsion at each sample [1/units], shape (K,).
        ends: ``(first, last)`` end kinds: "open", "flat" or "round".
    """

    name: str
    mesh: trimesh.Trimesh
    curve: np.ndarray
    radius: np.ndarray
    curvature: np.ndarray
    torsion: np.ndarray
    ends: tuple[str, str]

    @property
    def length(self) -> float:
        """Length of the centre curve [units]."""
        return float(np.linalg.norm(np.diff(self.curve, axis=0), axis=1).sum())


def frenet_curve(kappa: Callable, tau: Callable, length: float, step: float = 0.01):
    """Curve with curvature ``kappa(s)`` and torsion ``tau(s)`` (vectorised callables of arclength).

    Starts at the origin heading along +x with normal +y; integrates ``T' = k N``,
    ``N' = -k T + tau B``, ``B' = -tau N`` by fourth-order Runge-Kutta with step ``step`` and
    ``x' = T`` by the trapezoidal rule of the same steps (both re-orthonormalised each step).

    Returns:
        ``(s (K,), points (K, 3), tangents (K, 3))``.
    """
    n = max(2, int(np.ceil(length / step)) + 1)
    s = np.linspace(0.0, length, n)
    h = s[1] - s[0]

    def deriv(si, f):
        k, t = float(kappa(si)), float(tau(si))
        T, N, B = f
        return np.stack([k * N, -k * T + t * B, -t * N])

    f = np.eye(3)
    x = np.zeros((n, 3))
    tangents = np.zeros((n, 3))
    tangents[0] = f[0]
    for i in range(n - 1):
        k1 = deriv(s[i], f)
        k2 = deriv(s[i] + 0.5 * h, f + 0.5 * h * k1)
        k3 = deriv(s[i] + 0.5 * h, f + 0.5 * h * k2)
        k4 = deriv(s[i] + h, f + h * k3)
        g = f + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        T = g[0] / np.linalg.norm(g[0])
        N = g[1] - np.dot(g[1], T) * T
        N /= np.linalg.norm(N)
        f = np.stack([T, N, np.cross(T, N)])
        tangents[i + 1] = T
        x[i + 1] = x[i] + 0.5 * h * (tangents[i] + T)
    return s, x, tangents


def _ring_frames(tangents: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Normals ``u`` and binormals ``v`` normal to each tangent, without twist (parallel transport)."""
    u = np.zeros_like(tangents)
    a = np.zeros(3)
    a[int(np.argmin(np.abs(tangents[0])))] = 1.0
    u[0] = a - np.dot(a, tangents[0]) * tangents[0]
    u[0] /= np.linalg.norm(u[0])
    for i in range(1, len(tangents)):
        w = u[i - 1] - np.dot(u[i - 1], tangents[i]) * tangents[i]
        u[i] = w / np.linalg.norm(w)
    return u, np.cross(tangents, u)


def sweep_mesh(points, tangents, radii, ends=("open", "open"), ring: int = 48, cap_rings: int = 8) -> trimesh.Trimesh:
    """Rings of ``ring`` vertices of radius ``radii`` normal to ``tangents`` around ``points``.

    Args:
        points: ring centres [units], shape (K, 3); tangents: unit, shape (K, 3); radii: shape (K,).
        ends: per end "open", "flat" (a fan to the end ring's centre) or "round" (a hemisphere of
            ``cap_rings`` rings and a pole).
        ring: vertices per ring.

    Returns:
        The surface, consistently wound (outward normals).
    """
    p = np.asarray(points, dtype=np.float64)
    t = np.asarray(tangents, dtype=np.float64)
    r = np.asarray(radii, dtype=np.float64)
    u, v = _ring_frames(t)
    phi = 2.0 * np.pi * np.arange(ring) / ring
    c, s_ = np.cos(phi), np.sin(phi)
    rings = [p[:, None] + r[:, None, None] * (c[None, :, None] * u[:, None] + s_[None, :, None] * v[:, None])]
    k = len(p)
    j = np.arange(ring)
    i = np.arange(k - 1)[:, None]
    a0, a1 = i * ring + j, i * ring + (j + 1) % ring
    faces = [np.stack([a0, a1, a1 + ring], -1).reshape(-1, 3), np.stack([a0, a1 + ring, a0 + ring], -1).reshape(-1, 3)]
    count = k * ring
    verts = [rings[0].reshape(-1, 3)]
    for end, idx, sign in ((ends[0], 0, -1.0), (ends[1], k - 1, 1.0)):
        base = idx * ring
        if end == "open":
            continue
        if end == "flat":
            levels = [(0.0, 0.0)]  # the pole (centre of the end ring)
        elif end == "round":
            beta = 0.5 * np.pi * np.arange(1, cap_rings + 1) / (cap_rings + 1)
            levels = [(np.sin(b), np.cos(b)) for b in beta] + [(1.0, 0.0)]
        else:
            raise ValueError(f"end kind {end!r}: expected 'open', 'flat' or 'round'")
        prev = base
        for axial, radial in levels:
            centre = p[idx] + sign * axial * r[idx] * t[idx]
            if radial > 0.0:
                pts = centre + radial * r[idx] * (c[:, None] * u[idx] + s_[:, None] * v[idx])
                verts.append(pts)
                b0, b1 = count + j, count + (j + 1) % ring
                q0, q1 = prev + j, prev + (j + 1) % ring
                quad = [np.stack([q0, q1, b1], -1), np.stack([q0, b1, b0], -1)]
                faces += quad if sign > 0 else [f[:, ::-1] for f in quad]
                prev = count
                count += ring
            else:
                verts.append(centre[None])
                q0, q1 = prev + j, prev + (j + 1) % ring
                fan = np.stack([q0, q1, np.full(ring, count)], -1)
                faces.append(fan if sign > 0 else fan[:, ::-1])
                count += 1
    return trimesh.Trimesh(np.concatenate(verts), np.concatenate(faces), process=False)


def _bump(centre: float, width: float):
    """Smooth bump of height 1 (a cos^2 window) over ``centre +- width / 2``, 0 outside."""

    def f(s):
        x = np.clip((np.asarray(s, dtype=np.float64) - centre) / width, -0.5, 0.5)
        return np.cos(np.pi * x) ** 2

    return f


def _const(value: float):
    return lambda s: np.full(np.shape(s), value, dtype=np.float64)


def _u_turn(peak: float, centre: float):
    """Curvature of a U-turn: a cos^2 bump of height ``peak`` whose integral is pi (the bump of
    height 1 and width w integrates to w / 2, so w = 2 pi / peak)."""
    return lambda s: peak * _bump(centre, 2.0 * np.pi / peak)(s)


# name, kappa(s), tau(s) [1 / radius unit], length, radius(u) of u = s / length in [0, 1]
_CURVES = [
    ("straight_taper", _const(0.0), _const(0.0), 12.0, lambda u: 1.2 - 0.5 * u),
    ("arc_gentle", _const(0.25), _const(0.0), 16.0, lambda u: 1.0 + 0.0 * u),
    ("arc_tight_wavy", _const(0.65), _const(0.0), 6.5, lambda u: 1.0 + 0.2 * np.sin(2.0 * np.pi * u)),
    ("helix_low_torsion", _const(0.45), _const(0.12), 20.0, lambda u: 0.9 + 0.2 * np.sin(3.0 * np.pi * u)),
    ("helix_high_torsion", _const(0.35), _const(0.45), 24.0, lambda u: 1.0 + 0.15 * np.cos(4.0 * np.pi * u)),
    ("helix_tight", _const(0.75), _const(0.3), 7.5, lambda u: 1.05 + 0.0 * u),
    ("s_curve_waisted", lambda s: 0.6 * np.sin(2.0 * np.pi * s / 12.0), _const(0.0), 24.0,
     lambda u: 1.0 - 0.25 * np.sin(np.pi * u)),
    ("wiggle_3d", lambda s: 0.35 + 0.3 * np.sin(2.0 * np.pi * s / 9.0), lambda s: 0.35 * np.cos(2.0 * np.pi * s / 13.0),
     20.0, lambda u: 1.0 + 0.25 * np.sin(5.0 * np.pi * u)),
    ("hairpin", _u_turn(0.8, 8.0), _const(0.0), 16.0, lambda u: 1.0 + 0.0 * u),
    ("hairpin_twisted", _u_turn(0.7, 9.0), lambda s: 0.25 * _bump(9.0, 6.0)(s), 18.0,
     lambda u: 0.95 + 0.1 * np.sin(2.0 * np.pi * u)),
    ("spiral", lambda s: 0.7 - 0.55 * np.asarray(s) / 26.0, _const(0.15), 26.0, lambda u: 1.1 - 0.3 * u),
    ("taper_bend_3d", lambda s: 0.5 * _bump(9.0, 8.0)(s), lambda s: 0.3 * _bump(9.0, 8.0)(s), 18.0,
     lambda u: 1.4 - 0.8 * u),
]  # fmt: skip

# End kinds of the two variants of each curve (cycled through the curves).
_END_VARIANTS = [
    (("open", "open"), ("flat", "flat")),
    (("round", "round"), ("open", "open")),
    (("flat", "flat"), ("round", "round")),
    (("open", "round"), ("flat", "open")),
]


def _rotation(seed: int) -> np.ndarray:
    """A rotation matrix drawn from a seeded generator (tubes in general position)."""
    q = np.random.default_rng(seed).normal(size=4)
    a, b, c, d = q / np.linalg.norm(q)
    return np.array([
        [a * a + b * b - c * c - d * d, 2 * (b * c - a * d), 2 * (b * d + a * c)],
        [2 * (b * c + a * d), a * a - b * b + c * c - d * d, 2 * (c * d - a * b)],
        [2 * (b * d - a * c), 2 * (c * d + a * b), a * a - b * b - c * c + d * d],
    ])  # fmt: skip


def synthetic_cases(step: float = 0.25, ring: int = 48) -> list[SyntheticTube]:
    """The standard set: 12 curves x 2 end variants = 24 tubes.

    Each tube is rotated into general position and shifted; every third one is scaled by 0.01
    (a tube of radius 1 cm in metres) and placed 0.5 m from the origin, like a vessel mesh in metres.

    Args:
        step: spacing of the mesh's rings along the curve [radius units].
        ring: vertices per ring.
    """
    out = []
    for k, (name, kappa, tau, length, radius) in enumerate(_CURVES):
        s, x, t = frenet_curve(kappa, tau, length)
        r = radius(s / length)
        kap = np.asarray(kappa(s), dtype=np.float64) + 0.0 * s
        tor = np.asarray(tau(s), dtype=np.float64) + 0.0 * s
        stations = np.unique(np.concatenate([np.arange(0, len(s), max(1, int(round(step / (s[1] - s[0]))))),
                                             [len(s) - 1]]))  # fmt: skip
        for v, ends in enumerate(_END_VARIANTS[k % len(_END_VARIANTS)]):
            case = 2 * k + v
            rot = _rotation(case)
            scale = 0.01 if case % 3 == 2 else 1.0
            origin = np.array([0.3, 0.5, -0.2]) if scale < 1.0 else np.array([3.0 * case, 2.0, -1.0])
            xs = (x @ rot.T) * scale + origin
            ts = t @ rot.T
            mesh = sweep_mesh(xs[stations], ts[stations], r[stations] * scale, ends, ring=ring)
            out.append(SyntheticTube(f"{name}_{ends[0]}_{ends[1]}", mesh, xs, r * scale, kap / scale, tor / scale, ends))
    return out


def check_case(case: SyntheticTube, margin: float = 0.1) -> str | None:
    """Why ``case`` is not a valid tube, or None.

    Valid: ``radius x curvature < 1`` everywhere (rings normal to the curve do not cross), and any
    two curve samples farther apart along the curve than ``pi`` times the larger radius lie farther
    apart in space than the sum of their radii plus ``margin`` times the smaller (the walls of
    different parts of the tube do not touch).
    """
    rk = case.radius * np.abs(case.curvature)
    if rk.max() >= 1.0:
        return f"{case.name}: radius x curvature reaches {rk.max():.3f}"
    sub = slice(None, None, 8)
    x, r = case.curve[sub], case.radius[sub]
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(case.curve, axis=0), axis=1))])[sub]
    d = np.linalg.norm(x[:, None] - x[None], axis=-1)
    far = np.abs(s[:, None] - s[None]) > np.pi * np.maximum(r[:, None], r[None])
    need = r[:, None] + r[None] + margin * np.minimum(r[:, None], r[None])
    bad = far & (d < need)
    if bad.any():
        i, j = np.argwhere(bad)[0]
        return f"{case.name}: the walls at s = {s[i]:.3g} and {s[j]:.3g} touch ({d[i, j]:.3g} < {need[i, j]:.3g})"
    return None
