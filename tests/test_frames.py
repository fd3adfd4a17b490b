"""Warp frames (kernels/frames.py) against the NumPy reference convention and the helix RMF."""

import numpy as np
import pytest
import warp as wp

from warp_tube.model import frames as ref
from warp_tube.surface.builder import SurfaceBuilder, rest_frames

DEVICE = "cpu"


def smooth_curve(rng, n, scale=1.0):
    """A random smooth space curve sampled at n points: a few random Fourier modes plus a drift."""
    s = np.linspace(0.0, 1.0, n)[:, None]
    x = s * rng.normal(size=3) * 2.0 * scale
    for k in range(1, 4):
        x += scale / k**2 * (np.sin(2 * np.pi * k * s + rng.uniform(0, 6.3, 3)) * rng.normal(size=3) * 0.3)
    return x


def rebuild_frames(mode, node_q, starts, rest, normals, node_offset=0):
    """Hub frames ``(t, r)`` of one world, each (N, 3) float64, as the surface rebuild finds them
    (:class:`SurfaceBuilder`, the world kernel, which calls the frame functions of
    kernels/frames.py): hubs at columns ``node_offset + starts`` of ``node_q`` (columns, 3), rest
    shape ``rest`` (N, 3) and each tube's reference normal ``normals`` (T, 3)."""
    b = SurfaceBuilder(node_offset + np.asarray(starts), rest, 8, np.full(len(rest), 0.01), normals, frames=mode, device=DEVICE)
    b.compute(wp.array(node_q[None].astype(np.float32), dtype=wp.vec3, device=DEVICE))
    t, r, _ = b.frames_numpy()
    return t, r


def reference_frames(mode, x, rest_t, rest_r):
    """Frames of one tube by warp_tube.model.frames, float64."""
    t = ref.hub_tangents(x)
    if mode == "rotationMinimizing":
        normal0 = ref.minimal_rotation(rest_t[0], t[0]) @ rest_r[0]
        return ref.rotation_minimizing_frames(x, t, normal0)[:2]
    r = np.array([ref.minimal_rotation(a, b) @ c for a, b, c in zip(rest_t, t, rest_r)])
    r -= np.sum(r * t, axis=1, keepdims=True) * t
    return t, r / np.linalg.norm(r, axis=1, keepdims=True)


@pytest.mark.parametrize("mode", ["rotationMinimizing", "local"])
def test_frames_match_numpy_reference(mode):
    """3 variants (worlds) of 2 tubes (40 + 25 hubs) after 5 columns of another prim's nodes."""
    rng = np.random.default_rng(7)
    W, offset, counts = 3, 5, (40, 25)
    starts = np.concatenate([[0], np.cumsum(counts)])
    N = starts[-1]
    node_q = rng.normal(size=(W, offset + N, 3))
    rest = np.empty((W, N, 3))
    normals = np.empty((W, len(counts), 3))
    rest_t = np.empty((W, N, 3))
    rest_r = np.empty((W, N, 3))
    for w in range(W):
        for tube, n in enumerate(counts):
            a, b = starts[tube], starts[tube + 1]
            rest[w, a:b] = smooth_curve(rng, n)
            normals[w, tube] = rng.normal(size=3)
            rest_t[w, a:b], rest_r[w, a:b], _ = ref.rotation_minimizing_frames(rest[w, a:b], normal0=normals[w, tube])
            node_q[w, offset + a : offset + b] = smooth_curve(rng, n)
    # The kernel sees float32 positions and rest frames: give the reference the same rounded inputs.
    node_q = node_q.astype(np.float32).astype(np.float64)
    rest_t = rest_t.astype(np.float32).astype(np.float64)
    rest_r = rest_r.astype(np.float32).astype(np.float64)
    frames = [rebuild_frames(mode, node_q[w], starts, rest[w], normals[w], node_offset=offset) for w in range(W)]
    t_w = np.stack([t for t, _ in frames])
    r_w = np.stack([r for _, r in frames])
    for w in range(W):
        for tube in range(len(counts)):
            a, b = starts[tube], starts[tube + 1]
            t_ref, r_ref = reference_frames(mode, node_q[w, offset + a : offset + b], rest_t[w, a:b], rest_r[w, a:b])
            # float32 round-off: tangents from differences of O(1) coordinates over edges ~0.05
            # long (~1e-6 relative), carried through <= 40 reflections: 2e-5 is ~10x the observed.
            np.testing.assert_allclose(t_w[w, a:b], t_ref, atol=2e-5)
            np.testing.assert_allclose(r_w[w, a:b], r_ref, atol=2e-5)
            # and (t, r) orthonormal to the same round-off
            np.testing.assert_allclose(np.sum(t_w[w, a:b] * r_w[w, a:b], axis=1), 0.0, atol=2e-6)


def test_rest_shape_gives_rest_frames():
    """At rest both modes reproduce the rest frames (reference normal honoured at hub 0)."""
    rng = np.random.default_rng(3)
    rest = smooth_curve(rng, 30)
    normal = np.array([0.3, -1.0, 0.2])
    t_rest, r_rest = rest_frames(rest, [0, 30], normal)
    r0 = normal - np.dot(normal, t_rest[0]) * t_rest[0]
    np.testing.assert_allclose(r_rest[0], r0 / np.linalg.norm(r0), atol=1e-12)
    for mode in ("rotationMinimizing", "local"):
        b = SurfaceBuilder([0, 30], rest, 8, np.full(30, 0.05), normal, frames=mode, device=DEVICE)
        b.compute(wp.array(rest[None].astype(np.float32), dtype=wp.vec3, device=DEVICE))
        t, r, _ = b.frames_numpy()
        np.testing.assert_allclose(t, t_rest, atol=2e-5)  # float32 round-off, as above
        np.testing.assert_allclose(r, r_rest, atol=2e-5)


def helix_twist_error(n, mode):
    """Largest angle [rad] between the transported normals and the analytic RMF of a helix.

    Helix x = cos u, y = sin u, z = 0.5 u over two turns, n hubs uniform in u; rest shape: a
    straight line along the first chord with the same spacing. The analytic rotation-minimizing
    frame turns against the Frenet frame at -tau per unit length, tau = c / (a^2 + c^2), so its angle
    from the Frenet normal N = (-cos u, -sin u, 0) is psi_0 - tau |x'| u. Each discrete normal is carried
    onto the analytic normal plane by the least rotation taking the discrete tangent (estimated from
    the hubs) to the analytic one; its angle there, against the analytic RMF started from hub 0's.
    """
    a, c = 1.0, 0.5
    u = np.linspace(0.0, 4.0 * np.pi, n)
    x = np.stack([a * np.cos(u), a * np.sin(u), c * u], 1)
    chord = x[1] - x[0]
    rest = x[0] + np.outer(np.arange(n), chord)
    b = SurfaceBuilder([0, n], rest, 8, np.full(n, 0.1), frames=mode, device=DEVICE)
    b.compute(wp.array(x[None].astype(np.float32), dtype=wp.vec3, device=DEVICE))
    t, r, _ = b.frames_numpy()
    T = np.stack([-a * np.sin(u), a * np.cos(u), np.full(n, c)], 1) / np.hypot(a, c)
    N = np.stack([-np.cos(u), -np.sin(u), np.zeros(n)], 1)
    B = np.cross(T, N)
    rr = np.array([ref.minimal_rotation(ti / np.linalg.norm(ti), Ti) @ ri for ti, Ti, ri in zip(t, T, r)])
    psi = np.arctan2(np.sum(rr * B, 1), np.sum(rr * N, 1))
    tau = c / (a * a + c * c)
    analytic = psi[0] - tau * np.hypot(a, c) * u
    return float(np.max(np.abs(np.angle(np.exp(1j * (psi - analytic))))))


def test_helix_rotation_minimizing_twist():
    # The bounds are the task's: 5e-3 rad with 32 hubs, 2e-3 with 64 (the double reflection is 4th
    # order with exact tangents; here the tangents are the hubs' bisectors).
    e32 = helix_twist_error(32, "rotationMinimizing")
    e64 = helix_twist_error(64, "rotationMinimizing")
    print(f"helix twist error, rotationMinimizing: 32 hubs {e32:.3e} rad, 64 hubs {e64:.3e} rad")
    assert e32 < 5e-3
    assert e64 < 2e-3
    # and it converges (fourth order would give 16x; two halvings of the spacing must give > 4x)
    assert e64 < e32 / 4


def test_helix_local_twist_is_reported():
    """The paper's local rotation ignores the path: on a helix it does not follow the RMF's twist."""
    e32 = helix_twist_error(32, "local")
    e64 = helix_twist_error(64, "local")
    print(f"helix twist error, local: 32 hubs {e32:.3e} rad, 64 hubs {e64:.3e} rad")
    # The RMF turns by tau * length = 0.4 * 4 pi * 1.118 = 5.6 rad over two turns; the local
    # rotation from a straight rest shape stays a fixed rotation of the rest frame per hub, so its
    # error is O(1) and does not shrink with refinement.
    assert e32 > 0.1 and e64 > 0.1


@pytest.mark.parametrize("n", [2, 3, 4, 20, 65, 66, 500, 5000])
def test_many_frames_match_the_hub_loop(n):
    rng = np.random.default_rng(n)
    pts = np.stack([smooth_curve(rng, n) + 0.002 * rng.normal(size=(n, 3)) for _ in range(4)])
    normals = np.array([[0.0, 0.0, 1.0], [np.nan] * 3, [1.0, 1.0, 0.0], [np.nan] * 3])
    t, r = ref.rotation_minimizing_frames_many(pts, normals)
    for k in range(4):
        tl, rl, _ = ref.rotation_minimizing_frames(pts[k], normal0=None if np.isnan(normals[k]).any() else normals[k])
        # Tangents: the same NumPy operations, element for element.
        assert np.array_equal(t[k], tl)
        # Normals: the loop re-normalises after each of the n - 1 reflection steps, the batch
        # composes the steps as quaternions and normalises once; each step rounds at ~1.1e-16, so
        # the two unit vectors agree to n x 2.2e-16 (measured: 1.4e-14 at n = 5000).
        assert np.abs(r[k] - rl).max() <= max(n, 4) * 2.2e-16


def test_many_frames_take_the_loop_where_a_reflection_is_undefined():
    rng = np.random.default_rng(5)
    good = smooth_curve(rng, 12)
    bad = good.copy()
    bad[6] = bad[5]  # coincident hubs: no first reflection at that step
    t, r = ref.rotation_minimizing_frames_many(np.stack([good, bad]))
    tl, rl, _ = ref.rotation_minimizing_frames(bad)
    assert np.array_equal(t[1], tl) and np.array_equal(r[1], rl)  # the loop's own result
    assert np.abs(r[0] - ref.rotation_minimizing_frames(good)[1]).max() <= 12 * 2.2e-16


def test_rest_frames_of_tubes_of_several_lengths():
    rng = np.random.default_rng(11)
    curves = [smooth_curve(rng, n) for n in (7, 30, 7, 2, 30)]
    starts = np.concatenate([[0], np.cumsum([len(c) for c in curves])])
    normals = np.array([[np.nan] * 3, [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [np.nan] * 3, [np.nan] * 3])
    t, r = rest_frames(np.concatenate(curves), starts, normals)
    for k, c in enumerate(curves):
        tl, rl, _ = ref.rotation_minimizing_frames(c, normal0=None if np.isnan(normals[k]).any() else normals[k])
        a, b = starts[k], starts[k + 1]
        # Grouped by length, each tube must get its own frames and its own reference normal.
        assert np.array_equal(t[a:b], tl)
        assert np.abs(r[a:b] - rl).max() <= len(c) * 2.2e-16
