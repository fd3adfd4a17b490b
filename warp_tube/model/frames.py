"""Twist-free frames along a polyline (NumPy reference).

These functions define the frame convention that the whole package shares: the surface kernels
(`warp_tube.kernels.frames`), the bending springs of curved rest shapes and the spoke measurement of
centerline extraction all follow it, and the tests compare the Warp kernels against it.

Convention, for the hubs x_0..x_{n-1} of one tube:

- Tangent at a hub: the normalised sum of the unit vectors of its two edges (the bisector), and the
  unit edge vector at the two ends.
- Frame of the first hub: ``(t_0, r_0, s_0)`` with ``r_0`` the reference normal projected onto the
  plane normal to ``t_0`` and ``s_0 = t_0 x r_0``. Without a reference normal, ``r_0`` is the world
  axis least aligned with ``t_0``, projected (deterministic).
- Later hubs: the double-reflection rotation-minimizing frame of Wang, Juttler, Zheng and Liu,
  "Computation of rotation minimizing frames", ACM TOG 27(1), 2008: reflect ``(r_i, t_i)`` in the
  bisecting plane of ``x_i x_{i+1}``, then in the plane that takes the reflected tangent onto
  ``t_{i+1}``.
- Spoke ``j`` of ``S`` at a body hub points along ``cos(phi_j) r_i + sin(phi_j) s_i`` with
  ``phi_j = 2 pi j / S``.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "hub_tangents",
    "initial_normal",
    "rotation_minimizing_frames",
    "rotation_minimizing_frames_many",
    "minimal_rotation",
    "rotate_minimal",
    "least_rotation_quaternions",
    "spoke_directions",
]


def _normalize(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(n > 0.0, n, 1.0)


def hub_tangents(points: np.ndarray) -> np.ndarray:
    """Unit tangents at the hubs of one polyline.

    Args:
        points: hub positions [any length unit], shape (n, 3), n >= 2, or (..., n, 3) for many
            polylines of n hubs.

    Returns:
        Unit tangents, shaped like ``points``: edge bisectors inside, edge directions at the ends.
    """
    p = np.asarray(points, dtype=np.float64)
    e = _normalize(p[..., 1:, :] - p[..., :-1, :])
    t = np.empty_like(p)
    t[..., 0, :] = e[..., 0, :]
    t[..., -1, :] = e[..., -1, :]
    t[..., 1:-1, :] = _normalize(e[..., :-1, :] + e[..., 1:, :])
    return t


def initial_normal(tangent: np.ndarray, reference: np.ndarray | None = None) -> np.ndarray:
    """Unit normal of the first hub: ``reference`` made perpendicular to ``tangent``.

    Without a reference (or one parallel to the tangent) the world axis least aligned with the
    tangent is used, so the choice is deterministic.
    """
    t = np.asarray(tangent, dtype=np.float64)
    if reference is not None:
        r = np.asarray(reference, dtype=np.float64)
        r = r - np.dot(r, t) * t
        if np.linalg.norm(r) > 1e-8 * max(1.0, np.linalg.norm(reference)):
            return r / np.linalg.norm(r)
    axis = np.zeros(3)
    axis[int(np.argmin(np.abs(t)))] = 1.0
    r = axis - np.dot(axis, t) * t
    return r / np.linalg.norm(r)


def rotation_minimizing_frames(
    points: np.ndarray, tangents: np.ndarray | None = None, normal0: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Double-reflection rotation-minimizing frames along one polyline.

    Args:
        points: hub positions, shape (n, 3).
        tangents: unit tangents, shape (n, 3); default :func:`hub_tangents`.
        normal0: reference normal of the first hub, shape (3,); see :func:`initial_normal`.

    Returns:
        ``(t, r, s)``, each shape (n, 3): tangent, normal (spoke 0) and ``s = t x r``.
    """
    x = np.asarray(points, dtype=np.float64)
    t = hub_tangents(x) if tangents is None else np.asarray(tangents, dtype=np.float64)
    n = len(x)
    r = np.empty_like(x)
    r[0] = initial_normal(t[0], normal0)
    for i in range(n - 1):
        v1 = x[i + 1] - x[i]
        c1 = float(np.dot(v1, v1))
        if c1 <= 0.0:
            r[i + 1] = r[i]
            continue
        r_l = r[i] - (2.0 / c1) * np.dot(v1, r[i]) * v1
        t_l = t[i] - (2.0 / c1) * np.dot(v1, t[i]) * v1
        v2 = t[i + 1] - t_l
        c2 = float(np.dot(v2, v2))
        r_n = r_l - (2.0 / c2) * np.dot(v2, r_l) * v2 if c2 > 1e-30 else r_l
        # Re-orthonormalise against round-off so long tubes keep an orthonormal frame.
        r_n = r_n - np.dot(r_n, t[i + 1]) * t[i + 1]
        r[i + 1] = r_n / np.linalg.norm(r_n)
    s = np.cross(t, r)
    return t, r, s


ANTIPARALLEL_EPS = 1.0e-6
"""``1 + a.b`` below which two unit vectors are taken as opposite (a half turn): the threshold of
the kernels' ``rotate_minimal`` (float32), so that both take the half turn on the same inputs."""


def rotate_minimal(a: np.ndarray, b: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``x`` turned by the least rotation taking unit vector ``a`` to unit vector ``b``.

    ``R x = x + k x x + k x (k x x) / (1 + a.b)`` with ``k = a x b`` (Rodrigues). Where
    ``a.b < -1 + ANTIPARALLEL_EPS`` (a half turn, where the least rotation is not unique) the half
    turn about :func:`initial_normal` of ``a`` is taken, as the kernels do
    (:func:`warp_tube.kernels.frames.rotate_minimal`).

    Args:
        a, b: unit vectors, shape (3,).
        x: vectors to turn, shape (3,) or (..., 3).

    Returns:
        The turned vectors, shaped as ``x``, float64.
    """
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    x = np.asarray(x, dtype=np.float64)
    c = float(np.dot(a, b))
    if c < -1.0 + ANTIPARALLEL_EPS:
        k = initial_normal(a)
        return 2.0 * (x @ k)[..., None] * k - x
    v = np.cross(a, b)
    vx = np.cross(v, x)
    return x + vx + np.cross(v, vx) / (1.0 + c)


def least_rotation_quaternions(a, b):
    """The least rotations taking unit vectors ``a`` to unit vectors ``b``, many at once, as unit
    quaternions ``(w, x, y, z)``: :func:`rotate_minimal`'s rotation, half turns included.

    Args:
        a, b: unit vectors as component tuples ``(x, y, z)``, each an array of one shape.

    Returns:
        ``(w, x, y, z)``, each an array of that shape: ``(1 + a.b, a x b)`` normalised, or
        ``(0, k)`` with ``k`` the :func:`initial_normal` of ``a`` where ``a.b < -1 + ANTIPARALLEL_EPS``.
    """
    ax, ay, az = (np.asarray(c, dtype=np.float64) for c in a)
    bx, by, bz = (np.asarray(c, dtype=np.float64) for c in b)
    w = 1.0 + ax * bx + ay * by + az * bz
    x, y, z = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
    half = w < ANTIPARALLEL_EPS
    if half.any():
        # initial_normal(a): the world axis least aligned with a, made perpendicular to it
        axis = np.argmin(np.stack([np.abs(ax), np.abs(ay), np.abs(az)]), axis=0)
        ex, ey, ez = (axis == 0).astype(float), (axis == 1).astype(float), (axis == 2).astype(float)
        d = ex * ax + ey * ay + ez * az
        kx, ky, kz = ex - d * ax, ey - d * ay, ez - d * az
        w, x, y, z = np.where(half, 0.0, w), np.where(half, kx, x), np.where(half, ky, y), np.where(half, kz, z)
    n = np.sqrt(w * w + x * x + y * y + z * z)
    return w / n, x / n, y / n, z / n


def minimal_rotation(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Rotation matrix (3, 3) of :func:`rotate_minimal` from unit vector ``a`` to unit vector ``b``."""
    return rotate_minimal(a, b, np.eye(3)).T


def spoke_directions(r: np.ndarray, s: np.ndarray, spokes: int) -> np.ndarray:
    """Unit spoke directions of body hubs (90 degrees to the tangent).

    Args:
        r, s: frame normals, shape (n, 3).
        spokes: spokes per hub, S.

    Returns:
        Directions, shape (n, S, 3); spoke j at angle 2 pi j / S from ``r`` towards ``s``.
    """
    phi = 2.0 * np.pi * np.arange(spokes) / spokes
    return np.cos(phi)[None, :, None] * r[:, None, :] + np.sin(phi)[None, :, None] * s[:, None, :]


# Vectors and quaternions held as their component arrays ((x, y, z) or (w, x, y, z)), each shaped
# like the batch: component-wise arithmetic on contiguous arrays, for frames of many hubs at once.


def vdot(a, b):
    """Dot product of vectors given as component tuples ``(x, y, z)`` (arrays of one shape)."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def vcross(a, b):
    """Cross product of vectors given as component tuples."""
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def vscale(a, k):
    """Vector ``a`` (component tuple) times ``k`` (scalar or array of the components' shape)."""
    return (a[0] * k, a[1] * k, a[2] * k)


def quat_mul(a, b):
    """Hamilton product ``a b`` of quaternions given as component tuples ``(w, x, y, z)``."""
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    )


def quat_rotate(q, v):
    """Vector ``v`` (component tuple) turned by unit quaternion ``q`` (``(w, x, y, z)``):
    ``v + 2 (w u x v + u x (u x v))`` with ``u`` the vector part."""
    w, *u = q
    a1 = vcross(u, v)
    a2 = vcross(u, a1)
    return tuple(vc + 2.0 * (w * b1 + b2) for vc, b1, b2 in zip(v, a1, a2))


def quat_unit(q):
    """Quaternion ``q`` (component tuple ``(w, x, y, z)``) over its length."""
    k = 1.0 / np.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    return (q[0] * k, q[1] * k, q[2] * k, q[3] * k)


#: runs of at most this many rotations are composed one after another; longer runs in blocks
SCAN_RUN = 64


def identity_quat(shape):
    """Identity quaternions of ``shape``, as a component tuple."""
    return (np.ones(shape), np.zeros(shape), np.zeros(shape), np.zeros(shape))


def cumulative_rotations(q):
    """Running products ``q_k ... q_1 q_0`` of unit quaternions along the first axis.

    Args:
        q: component tuple ``(w, x, y, z)``, each shaped (m, ...), C-contiguous.

    Short runs are multiplied one after another (vectorised over the trailing axes, a contiguous
    row per step); a long run is cut into about ``sqrt(m)`` blocks of about ``sqrt(m)`` rotations,
    every block's running product found that way at once, the blocks' totals composed the same
    way (recursively), and each block's products multiplied by the total of the blocks before it:
    O(m) work in O(sqrt(m)) NumPy calls. Products are renormalised so that rounding does not let
    them drift off unit length.
    """
    m = q[0].shape[0]
    if m <= SCAN_RUN:
        out = tuple(np.empty_like(c) for c in q)
        acc = tuple(c[0] for c in q)
        for c, v in zip(out, acc):
            c[0] = v
        for k in range(1, m):
            acc = quat_unit(quat_mul(tuple(c[k] for c in q), acc))
            for c, v in zip(out, acc):
                c[k] = v
        return out
    trail = q[0].shape[1:]
    run = int(np.ceil(np.sqrt(m)))
    blocks = -(-m // run)
    pad = identity_quat((blocks * run - m,) + trail)  # rotations that do nothing
    # (run, blocks, ...): step k of every block is one contiguous row.
    qb = tuple(np.ascontiguousarray(np.concatenate([c, p]).reshape((blocks, run) + trail).swapaxes(0, 1))
               for c, p in zip(q, pad))  # fmt: skip
    inner = cumulative_rotations(qb)  # running products inside each block
    totals = cumulative_rotations(tuple(np.ascontiguousarray(c[-1]) for c in inner))  # through each block's end
    before = tuple(np.concatenate([i, c[:-1]]) for i, c in zip(identity_quat((1,) + trail), totals))
    out = quat_unit(quat_mul(inner, before))
    return tuple(np.ascontiguousarray(c.swapaxes(0, 1)).reshape((blocks * run,) + trail)[:m] for c in out)


def rotation_minimizing_frames_many(points: np.ndarray, normal0: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """:func:`rotation_minimizing_frames` of many polylines of ``n`` hubs at once.

    Args:
        points: hub positions, shape (B, n, 3), n >= 2.
        normal0: reference normal of each polyline's first hub, shape (B, 3), NaN rows for none
            (see :func:`initial_normal`); None: none for any.

    Returns:
        ``(t, r)``, each (B, n, 3): unit tangents and normals (spoke 0).

    Each double-reflection step is the rotation ``q = n2 n1`` (the product of the two reflections'
    unit plane normals as pure quaternions), and the normal of hub ``i`` is ``r_0`` carried by the
    running product of the steps before it (:func:`cumulative_rotations`), then made unit and
    normal to ``t_i``: O(n) array work in O(sqrt(n)) NumPy calls for all polylines together. The
    per-hub loop re-normalises after every step instead, so the two agree to round-off growing
    with ``n`` (about n x 1e-16). A polyline with a step where either reflection is undefined
    (coincident hubs, or a tangent reversed across a segment) takes the loop.
    """
    x = np.asarray(points, dtype=np.float64)
    B = len(x)
    t = hub_tangents(x)
    refs = None if normal0 is None else np.asarray(normal0, dtype=np.float64)

    def ref(k):
        return refs[k] if refs is not None and np.all(np.isfinite(refs[k])) else None

    r = np.empty_like(x)
    for k in range(B):
        r[k, 0] = initial_normal(t[k, 0], ref(k))
    # Steps i = 0 .. n - 2, components (n - 1, B) each.
    xc = tuple(np.ascontiguousarray(x[..., c].T) for c in range(3))
    tc = tuple(np.ascontiguousarray(t[..., c].T) for c in range(3))
    v1 = tuple(c[1:] - c[:-1] for c in xc)
    c1 = vdot(v1, v1)
    ti, tn = tuple(c[:-1] for c in tc), tuple(c[1:] for c in tc)
    with np.errstate(divide="ignore", invalid="ignore"):
        k1 = 2.0 / c1
        d1 = vdot(v1, ti) * k1
        v2 = tuple(a - (b - d1 * v) for a, b, v in zip(tn, ti, v1))  # t_{i+1} minus reflected t_i
        c2 = vdot(v2, v2)
        n1 = vscale(v1, 1.0 / np.sqrt(c1))
        n2 = vscale(v2, 1.0 / np.sqrt(c2))
    regular = np.all((c1 > 0.0) & (c2 > 1e-30), axis=0)  # (B,)
    w = -vdot(n2, n1)
    q = cumulative_rotations(tuple(np.ascontiguousarray(c) for c in (w, *vcross(n2, n1))))
    rk = quat_rotate(q, tuple(r[:, 0, c] for c in range(3)))
    d = vdot(rk, tn)
    rk = tuple(rc - tc_ * d for rc, tc_ in zip(rk, tn))
    rk = vscale(rk, 1.0 / np.sqrt(vdot(rk, rk)))
    for c in range(3):
        r[:, 1:, c] = rk[c].T
    for k in np.flatnonzero(~regular):
        t[k], r[k], _ = rotation_minimizing_frames(x[k], normal0=ref(k))
    return t, r
