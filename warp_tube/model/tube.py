"""TubeModel / TubeState / TubeControl: the arrays the solver works on, built from a Scene.

Layout: the curves of all tube prims are concatenated into one node list per world (prim order,
curve order); ``tube_node_start[t]`` is the first node of tube (curve) ``t``. State arrays are
shaped (world_count, node_count); parameter arrays (1, node_count), read by every world.
Segment ``i`` joins node ``i`` to node ``i + 1`` of the same tube (unused at a tube's last node).

Discretisation (SI units):

- Lumped masses: a segment of rest length ``l`` and mean radius ``r`` has mass ``rho pi r^2 l``,
  split equally between its ends.
- Structural springs: ``ke = EA / l`` [N/m].
- Angular (bending) springs at interior nodes: energy ``EI / (2 l_v) |kb - kb_rest|^2`` with ``kb``
  the discrete curvature binormal (length ``2 tan(phi/2)`` for turning angle ``phi``) and
  ``l_v`` the node's Voronoi length, half of each adjacent *elastic* segment. A segment between
  two pinned points is rigid (a clamp) and adds nothing to ``l_v``, so a clamped end's first
  elastic node integrates curvature over half a segment, as the continuum rod does from its clamp.
  This gives the elastica with second-order convergence in the segment length.
- Returning springs: ``anchor_stiffness`` [N/m] to each anchor point's rest position.
- Damping: mass-proportional ``alpha`` [1/s] (force ``-alpha m v``) and stiffness-proportional
  ``beta`` [s] along the structural and returning springs (``kd = beta ke``); the angular springs
  are not damped.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import repeat
from operator import attrgetter, is_

import numpy as np
import warp as wp

from warp_tube.kernels.springs import Features

from ..scene.spec import Scene
from .frames import cumulative_rotations, least_rotation_quaternions, quat_rotate, rotate_minimal, vcross, vdot, vscale
from .host import HostArrays

__all__ = ["TubeModel", "TubeState", "TubeControl", "HostArrays", "build_model", "first_edge_normal", "rest_curvature_coordinates", "rest_curvature_of_curves"]


def first_edge_normal(t: np.ndarray) -> np.ndarray:
    """The fixed perpendicular used for the first edge's rest frame (same as the kernel)."""
    u = np.array([0.0, 1.0, 0.0]) if abs(t[0]) > 0.6 else np.array([1.0, 0.0, 0.0])
    u = u - t * np.dot(u, t)
    return u / np.linalg.norm(u)


def curvature_binormal(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``2 a x b / (|a||b| + a.b)`` for edge vectors a, b, shape (..., 3)."""
    la = np.linalg.norm(a, axis=-1, keepdims=True)
    lb = np.linalg.norm(b, axis=-1, keepdims=True)
    den = np.maximum(la * lb + np.sum(a * b, axis=-1, keepdims=True), 1e-6 * la * lb + 1e-12)
    return 2.0 * np.cross(a, b) / den


def rest_curvature_coordinates(points: np.ndarray) -> np.ndarray:
    """Rest curvature binormals of tubes in their rest Bishop frames, shape (..., n, 3).

    Args:
        points: rest positions [m] of one tube, shape (n, 3), or of several tubes of n points
            each, shape (..., n, 3).

    Row ``j`` holds the components of ``kb_j`` along (tangent, u, v) of edge ``j - 1``'s frame; the
    first frame uses the fixed perpendicular of :func:`first_edge_normal`, and each later frame is
    the previous one carried by the least rotation between consecutive edges (parallel transport).
    Rows 0 and n-1 are 0. The transports are composed as quaternion products (a blocked running
    product, :func:`cumulative_rotations`), so a tube costs O(n) array work and O(sqrt(n)) NumPy
    calls, and many tubes of equal length cost the same number of calls as one.
    """
    x = np.asarray(points, dtype=np.float64)
    n = x.shape[-2]
    out = np.zeros(x.shape)
    if n < 3:
        return out
    # Components with the point axis first, each (n, ...) and contiguous.
    xc = tuple(np.ascontiguousarray(np.moveaxis(x[..., k], -1, 0)) for k in range(3))
    e = tuple(c[1:] - c[:-1] for c in xc)  # edges, (n - 1, ...)
    t = vscale(e, 1.0 / np.sqrt(vdot(e, e)))
    # First frame: the fixed perpendicular of first_edge_normal, for every tube at once.
    t0 = tuple(c[0] for c in t)
    pick_y = np.abs(t0[0]) > 0.6
    u0 = (np.where(pick_y, 0.0, 1.0), np.where(pick_y, 1.0, 0.0), np.zeros_like(t0[0]))
    d = vdot(u0, t0)
    u0 = tuple(uc - tc * d for uc, tc in zip(u0, t0))
    u0 = vscale(u0, 1.0 / np.sqrt(vdot(u0, u0)))
    m = n - 2  # frames of edges 0 .. n - 3 serve rows 1 .. n - 2
    u = tuple(np.empty((m,) + x.shape[:-2]) for _ in range(3))
    for c, v in zip(u, u0):
        c[0] = v
    if m > 1:
        # Least rotation from edge k to edge k + 1 as a unit quaternion.
        q = least_rotation_quaternions(tuple(c[: m - 1] for c in t), tuple(c[1:m] for c in t))
        uk = quat_rotate(cumulative_rotations(q), u0)  # carried from edge 0 to edge j + 1, (m - 1, ...) each
        tk = tuple(c[1:m] for c in t)
        d = vdot(uk, tk)
        uk = tuple(uc - tc * d for uc, tc in zip(uk, tk))
        uk = vscale(uk, 1.0 / np.sqrt(vdot(uk, uk)))
        for c, v in zip(u, uk):
            c[1:] = v
    tf = tuple(c[:m] for c in t)  # tangent of edge j - 1 for rows j = 1 .. n - 2
    v = vcross(tf, u)
    ea = tuple(c[:-1] for c in e)
    eb = tuple(c[1:] for c in e)
    # curvature_binormal(ea, eb), in components
    la, lb = np.sqrt(vdot(ea, ea)), np.sqrt(vdot(eb, eb))
    den = np.maximum(la * lb + vdot(ea, eb), 1e-6 * la * lb + 1e-12)
    kb = vscale(vcross(ea, eb), 2.0 / den)
    for k, frame in enumerate((tf, u, v)):
        out[..., 1:-1, k] = np.moveaxis(vdot(kb, frame), 0, -1)
    return out


def rest_curvature_of_curves(curves) -> list[np.ndarray]:
    """:func:`rest_curvature_coordinates` of each polyline in ``curves`` (a sequence of (n_i, 3)
    arrays [m]), as a list in the same order; curves of one length are done in one call."""
    out = [None] * len(curves)
    by_length: dict[int, list[int]] = {}
    for i, c in enumerate(curves):
        by_length.setdefault(len(c), []).append(i)
    for idx in by_length.values():
        kap = rest_curvature_coordinates(np.stack([curves[i] for i in idx]))
        for i, k in zip(idx, kap):
            out[i] = k
    return out


@dataclass
class TubeState:
    """Time-varying state.

    Attributes:
        node_q: node positions [m], shape (world_count, node_count), vec3.
        node_q_lo: low-order part of the positions [m] (compensated summation; the position is
            ``node_q + node_q_lo``, of which ``node_q`` is the float32 rounding), same shape.
        node_qd: node velocities [m/s], shape (world_count, node_count), vec3.
        al_q: assistant-line point positions [m], shape (world_count, al_slots), vec3.
        al_q_lo: low-order part of the assistant-line positions [m], same shape.
        al_qd: assistant-line point velocities [m/s], shape (world_count, al_slots), vec3.
    """

    node_q: wp.array
    node_q_lo: wp.array
    node_qd: wp.array
    al_q: wp.array
    al_q_lo: wp.array
    al_qd: wp.array

    def assign(self, other: "TubeState"):
        """Copy ``other`` into this state (same shapes)."""
        for name in ("node_q", "node_q_lo", "node_qd", "al_q", "al_q_lo", "al_qd"):
            wp.copy(getattr(self, name), getattr(other, name))


@dataclass
class TubeControl:
    """Inputs that change between frames.

    Attributes:
        node_f_ext: applied point forces [N], shape (world_count, node_count), vec3.
        pin_q_start, pin_q_end: pinned points' targets at the start and end of the integrated
            interval [m], shape (world_count, node_count), vec3 (read at pinned nodes only).
        al_active: 1 where force ``a``'s assistant line is built, shape (world_count, force_count).
        al_link_length, al_chord_length, al_fwd_length, al_bwd_length: rest lengths [m] of the
            assistant line's springs, set when it is built, shape (world_count, al_slots).
    """

    node_f_ext: wp.array
    pin_q_start: wp.array
    pin_q_end: wp.array
    al_active: wp.array
    al_link_length: wp.array
    al_chord_length: wp.array
    al_fwd_length: wp.array
    al_bwd_length: wp.array


@dataclass
class TubeModel:
    """Fixed per run: rest geometry, masses, stiffnesses and topology (see module docstring).

    Parameter arrays are (1, node_count); ``world_count`` copies of the scene run side by side.
    ``host`` keeps NumPy copies (float64) of the same quantities for host-side code
    (:class:`warp_tube.model.host.HostArrays`).
    """

    device: str
    world_count: int
    node_count: int
    tube_count: int
    force_count: int
    al_slots: int
    tube_node_start: wp.array  # (tube_count + 1,) int
    node_tube: wp.array  # (node_count,) int
    node_rest_q: wp.array  # (1, N) vec3 [m]
    node_mass: wp.array  # (1, N) [kg]
    node_inv_mass: wp.array  # (1, N) [1/kg], 0 for pinned nodes
    node_damping: wp.array  # (1, N) [1/s]
    seg_rest_length: wp.array  # (1, N) [m]
    seg_ke: wp.array  # (1, N) [N/m]
    seg_kd: wp.array  # (1, N) [N s/m]
    node_bend_k: wp.array  # (1, N) [N m]
    node_kappa_rest: wp.array  # (1, N) vec3 [1]
    node_anchor_k: wp.array  # (1, N) [N/m]
    node_anchor_kd: wp.array  # (1, N) [N s/m]
    gravity: wp.vec3  # [m/s^2]
    tube_force_start: wp.array  # (tube_count + 1,) int, forces sorted by tube
    force_node: wp.array  # (force_count,) int, global node of each force
    force_tube: wp.array  # (force_count,) int
    al_start: wp.array  # (force_count,) int, first AL slot of each force
    al_force_index: wp.array  # (al_slots,) int
    al_lines: int  # most assistant lines on one tube, K
    tube_al_force: wp.array  # (tube_count, max(K, 1)) int: the forces with a line on each tube, -1 padded
    features: Features  # which force terms the scene uses
    host: HostArrays  # NumPy (float64) copies of the above, for host-side code

    def state(self, rest_q: np.ndarray | None = None) -> TubeState:
        """A new state at rest: at ``rest_q`` [m] (world_count, node_count, 3), each world at its
        own rest positions, or by default at the model's in every world."""
        q = np.repeat(self.host.node_rest_q[None], self.world_count, axis=0) if rest_q is None else rest_q
        hi = q.astype(np.float32)
        shape_al = (self.world_count, max(self.al_slots, 1))
        # The low-order part starts at the rounding of the rest positions, so the compensated
        # positions are the rest shape and every spring starts unstrained.
        return TubeState(
            node_q=wp.array(hi, dtype=wp.vec3, device=self.device),
            node_q_lo=wp.array((q - hi).astype(np.float32), dtype=wp.vec3, device=self.device),
            node_qd=wp.zeros((self.world_count, self.node_count), dtype=wp.vec3, device=self.device),
            al_q=wp.zeros(shape_al, dtype=wp.vec3, device=self.device),
            al_q_lo=wp.zeros(shape_al, dtype=wp.vec3, device=self.device),
            al_qd=wp.zeros(shape_al, dtype=wp.vec3, device=self.device),
        )

    def control(self, rest_q: np.ndarray | None = None) -> TubeControl:
        """A new control: no forces, pins at rest (at ``rest_q`` [m] as :meth:`state` takes it), no
        assistant line."""
        q = np.repeat(self.host.node_rest_q[None], self.world_count, axis=0) if rest_q is None else rest_q.astype(np.float32)
        shape_al = (self.world_count, max(self.al_slots, 1))
        z = lambda: wp.zeros(shape_al, dtype=float, device=self.device)  # noqa: E731
        return TubeControl(
            node_f_ext=wp.zeros((self.world_count, self.node_count), dtype=wp.vec3, device=self.device),
            pin_q_start=wp.array(q, dtype=wp.vec3, device=self.device),
            pin_q_end=wp.array(q, dtype=wp.vec3, device=self.device),
            al_active=wp.zeros((self.world_count, max(self.force_count, 1)), dtype=int, device=self.device),
            al_link_length=z(),
            al_chord_length=z(),
            al_fwd_length=z(),
            al_bwd_length=z(),
        )


#: a tube prim's geometry arrays (TubeSpec fields): prims holding the same objects share them
_GEOMETRY = ("points", "radius", "curve_counts", "pinned", "anchors")
#: the TubeParams fields node_parameters reads, each prim's in one pass
MATERIALS = ("density", "youngs_modulus", "stretch_stiffness", "bend_stiffness", "damping", "spring_damping", "anchor_stiffness")


def node_parameters(scene: Scene, materials: np.ndarray | None = None) -> tuple[dict, bool]:
    """The per-node arrays of every curve of ``scene`` (prims in order, each prim's curves in
    order), for all curves at once, and whether any rest shape is curved.

    ``materials``: each prim's ``TubeParams`` fields :data:`MATERIALS` (NaN for None), (prims,
    len(MATERIALS)) float64, in place of the prims' own params (a batch's variants made by plain
    values, whose prims are the base scene's, repeated), or None to read them from the prims.

    Returns a dict of NumPy arrays, N = nodes, C = curves, T = prims: ``node_rest_q`` (N, 3) [m],
    ``node_mass`` [kg] (half of each adjacent segment's cylinder), ``node_inv_mass`` [1/kg] (0
    pinned), ``node_damping`` [1/s], ``seg_rest_length`` [m], ``seg_ke`` [N/m], ``seg_kd`` [N s/m]
    (segment i from node i to i + 1; 0 at a curve's last node), ``node_bend_k`` [N m] (EI over the
    node's Voronoi length of elastic segments; 0 at curve ends), ``node_kappa_rest`` (N, 3) [1],
    ``node_anchor_k`` [N/m], ``node_anchor_kd`` [N s/m], ``node_radius`` [m], each (N,);
    ``tube_node_start`` (C + 1,), ``node_tube`` (N,), ``prim_node_start`` (T,).
    """
    specs = scene.tubes
    # Prims that share their geometry arrays (a batch's variants made from one scene): the
    # arithmetic runs on rows, one per prim, over the first prim's geometry (the geometry's own
    # terms once, the materials' per row); otherwise on one row of every prim's nodes. Either way
    # each element goes through the same float64 operations in the same order as one curve alone.
    shared = len(specs) > 1 and all(all(map(is_, map(attrgetter(a), specs), repeat(getattr(specs[0], a)))) for a in _GEOMETRY)
    sizes = np.array([len(s.points) for s in specs], dtype=np.int64)
    prim_start = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    P = len(specs)
    if shared:
        s0 = specs[0]
        rows, row_counts = P, s0.curve_counts.astype(np.int64)
        x_row, r_row = s0.points, s0.radius
        counts = np.tile(row_counts, P)
        pinned_at, anchored_at = s0.pinned, s0.anchors
    else:
        rows = 1
        counts = row_counts = np.concatenate([s.curve_counts for s in specs]).astype(np.int64)
        x_row, r_row = np.concatenate([s.points for s in specs]), np.concatenate([s.radius for s in specs])
        pinned_at = np.concatenate([s.pinned + o for s, o in zip(specs, prim_start)])
        anchored_at = np.concatenate([s.anchors + o for s, o in zip(specs, prim_start)])
    tube_start = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    row_start = np.concatenate([[0], np.cumsum(row_counts)]).astype(np.int64)
    first, last = row_start[:-1], row_start[1:] - 1  # each curve's first and last node in a row
    m = len(x_row)  # nodes in a row
    pinned = np.zeros(m, dtype=bool)
    pinned[pinned_at] = True
    anchored = np.zeros(m, dtype=bool)
    anchored[anchored_at] = True

    def material(name: str):
        """Parameter ``name`` of each prim [its unit] (NaN for None): a scalar where every prim has
        the same value, else per row (rows, 1) where the rows are prims, or (1, nodes) over one row."""
        v = materials[:, MATERIALS.index(name)]
        if np.all((v == v[0]) | (np.isnan(v) & np.isnan(v[0]))):
            return v[0]
        return v[:, None] if shared else np.repeat(v, sizes)[None]

    def head(a):
        """``a`` at the first node of each segment (a scalar, or one value per row, as it is)."""
        return a[..., :-1] if np.ndim(a) and np.shape(a)[-1] == m else a

    def nodes(a) -> np.ndarray:
        """A row-wise array made here (broadcasting to (rows, m)) as every node's, (rows x m,)."""
        if np.shape(a) == (rows, m):
            return a.reshape(-1)
        return np.broadcast_to(a, (rows, m)).reshape(-1).copy()

    def tiled(a: np.ndarray) -> np.ndarray:
        """A row's array (m, ...) made here, repeated for every row."""
        return a if rows == 1 else np.tile(a, (rows,) + (1,) * (a.ndim - 1))

    def segments(a) -> np.ndarray:
        """A row-wise segment array (to (rows, m - 1)) as every node's, 0 at each row's last node."""
        out = np.zeros((rows, m))
        out[:, :-1] = a
        return out.reshape(-1)

    if materials is None:
        materials = np.array(list(map(attrgetter(*MATERIALS), (s.params for s in specs))), dtype=np.float64).reshape(P, -1)  # (None as NaN)
    density = material("density")
    youngs = material("youngs_modulus")
    stretch = material("stretch_stiffness")
    bend = material("bend_stiffness")
    spring_damping = material("spring_damping")

    # Segment i joins nodes i and i + 1 of a row; `inside` is False where they belong to different curves.
    inside = np.ones(m - 1, dtype=bool)
    inside[last[:-1]] = False
    seg = np.linalg.norm(x_row[1:] - x_row[:-1], axis=1)
    r_seg = 0.5 * (r_row[1:] + r_row[:-1])
    m_seg = np.where(inside, head(density) * np.pi * r_seg**2 * seg, 0.0)
    mass = np.zeros(np.broadcast_shapes((rows, m), np.shape(density)))
    mass[:, :-1] += 0.5 * m_seg
    mass[:, 1:] += 0.5 * m_seg
    elastic = inside & ~(pinned[1:] & pinned[:-1])
    l_el = np.where(elastic, seg, 0.0)
    l_v = np.zeros(m)
    l_v[1:-1] = 0.5 * (l_el[:-1] + l_el[1:])
    l_v[first] = 0.0
    l_v[last] = 0.0
    ei = np.where(np.isnan(bend), youngs * np.pi * r_row**4 / 4.0, bend)  # TubeParams.bending_stiffness
    bend_k = np.where(l_v > 0.0, ei / np.where(l_v > 0, l_v, 1.0), 0.0)
    bend_k[..., first] = 0.0
    bend_k[..., last] = 0.0
    ea = np.where(np.isnan(head(stretch)), head(youngs) * np.pi * r_seg**2, head(stretch))  # TubeParams.axial_stiffness
    k_ax = np.where(inside, ea / np.where(inside, seg, 1.0), 0.0)
    kappa_one = _curves_kappa(x_row, row_counts)  # (curved or not: from one row's)
    anchor_k = np.where(anchored, material("anchor_stiffness"), 0.0)
    mass = nodes(mass)
    per_node = dict(
        node_rest_q=tiled(x_row), node_mass=mass, node_inv_mass=np.where(nodes(pinned), 0.0, 1.0 / mass),
        node_damping=nodes(material("damping")),
        seg_rest_length=segments(np.where(inside, seg, 0.0)), seg_ke=segments(k_ax),
        seg_kd=segments(k_ax * head(spring_damping)), node_bend_k=nodes(bend_k), node_kappa_rest=tiled(kappa_one),
        node_anchor_k=nodes(anchor_k), node_anchor_kd=nodes(anchor_k * spring_damping), node_radius=tiled(r_row),
        tube_node_start=tube_start, node_tube=np.repeat(np.arange(len(counts), dtype=np.int64), counts),
        prim_node_start=prim_start[:-1],
    )  # fmt: skip
    return per_node, rest_is_curved(kappa_one)


def rest_is_curved(kappa: np.ndarray) -> bool:
    """Whether rest curvature coordinates ``kappa`` (..., 3) [1] make a curved rest shape (the
    model's ``curved`` feature)."""
    return bool(np.abs(kappa).max() > 1e-6)


def _curves_kappa(x: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """Rest curvature coordinates (N, 3) of the curves of ``counts`` points, one after another in
    ``x`` (N, 3) [m]; curves of one length (e.g. a batch's worlds) in one call."""
    if len(counts) and (counts == counts[0]).all():
        return rest_curvature_coordinates(x.reshape(len(counts), int(counts[0]), 3)).reshape(len(x), 3)
    starts = np.concatenate([[0], np.cumsum(counts)])
    return np.concatenate(rest_curvature_of_curves([x[a:b] for a, b in zip(starts[:-1], starts[1:])]))


def model_features(per_node: dict, curved: bool, gravity, external: bool, assistant_line: bool) -> Features:
    """The force terms a model needs, from its per-node arrays (:func:`node_parameters`),
    whether a rest shape is curved, the gravity [m/s^2] (or None), and whether it has point
    forces and assistant lines."""
    return Features(
        bending=bool((per_node["node_bend_k"] > 0).any()),
        curved=curved,
        anchors=bool((per_node["node_anchor_k"] > 0).any()),
        gravity=gravity is not None and any(v != 0.0 for v in gravity),
        mass_damping=bool((per_node["node_damping"] > 0).any()),
        spring_damping=bool((per_node["seg_kd"] > 0).any() or (per_node["node_anchor_kd"] > 0).any()),
        external=external,
        assistant_line=assistant_line,
    )


def build_model(scene: Scene, world_count: int = 1, device=None) -> TubeModel:
    """Discretise ``scene`` into a :class:`TubeModel` on ``device`` (Warp device or name)."""
    device = str(wp.get_device(device))
    per_node, curved = node_parameters(scene)
    tube_start = per_node["tube_node_start"]
    prim_node_start = per_node["prim_node_start"]
    t_index = len(tube_start) - 1
    n_nodes = tube_start[-1]
    # Forces sorted by tube, each with its global node and its assistant-line slots.
    # A force's node is its prim's first node plus its point; its tube (curve), that node's.
    n_forces = len(scene.forces)
    node_of_force = (prim_node_start[np.fromiter((f.tube for f in scene.forces), np.int64, n_forces)]
                     + np.fromiter((f.point for f in scene.forces), np.int64, n_forces))  # fmt: skip
    tube_of_force = per_node["node_tube"][node_of_force]
    order = np.argsort(tube_of_force, kind="stable")
    force_tube = tube_of_force[order].astype(np.int64)
    force_node = node_of_force[order]
    tube_force_start = np.searchsorted(force_tube, np.arange(t_index + 1)) if len(order) else np.zeros(t_index + 1, np.int64)
    uses_al = [scene.forces[k].assistant_line for k in order]
    al_start, al_force_index, slot = [], [], 0
    for a, t in enumerate(force_tube):
        al_start.append(slot)
        if uses_al[a]:
            n = int(tube_start[t + 1] - tube_start[t])
            al_force_index.extend([a] * n)
            slot += n
    lines = [[a for a in range(tube_force_start[t], tube_force_start[t + 1]) if uses_al[a]] for t in range(t_index)]
    al_lines = max((len(v) for v in lines), default=0)
    tube_al_force = np.full((t_index, max(al_lines, 1)), -1, dtype=np.int64)
    for t, v in enumerate(lines):
        tube_al_force[t, : len(v)] = v
    host = HostArrays(**per_node, force_order=order, force_tube=force_tube, force_node=force_node,
                      tube_force_start=np.asarray(tube_force_start, dtype=np.int64),
                      al_start=np.asarray(al_start, dtype=np.int64), force_uses_al=np.asarray(uses_al, dtype=bool),
                      tube_al_force=tube_al_force)  # fmt: skip
    g = scene.settings.gravity
    features = model_features(per_node, curved, g, external=len(scene.forces) > 0, assistant_line=slot > 0)

    def row(a, dtype=float):
        return wp.array(np.asarray(a)[None], dtype=dtype, device=device)

    def ints(a):
        a = np.asarray(a, dtype=np.int32)
        return wp.array(a if len(a) else np.zeros(1, np.int32), dtype=int, device=device)

    return TubeModel(
        device=device, world_count=int(world_count), node_count=int(n_nodes), tube_count=t_index,
        force_count=len(order), al_slots=slot,
        tube_node_start=ints(tube_start), node_tube=ints(host.node_tube),
        node_rest_q=row(host.node_rest_q, wp.vec3), node_mass=row(host.node_mass),
        node_inv_mass=row(host.node_inv_mass), node_damping=row(host.node_damping),
        seg_rest_length=row(host.seg_rest_length), seg_ke=row(host.seg_ke), seg_kd=row(host.seg_kd),
        node_bend_k=row(host.node_bend_k), node_kappa_rest=row(host.node_kappa_rest, wp.vec3),
        node_anchor_k=row(host.node_anchor_k), node_anchor_kd=row(host.node_anchor_kd),
        gravity=wp.vec3(*(g if g is not None else (0.0, 0.0, 0.0))),
        tube_force_start=ints(tube_force_start), force_node=ints(force_node), force_tube=ints(force_tube),
        al_start=ints(al_start), al_force_index=ints(al_force_index), al_lines=al_lines,
        tube_al_force=wp.array(tube_al_force.astype(np.int32), dtype=int, device=device),
        features=features, host=host,
    )  # fmt: skip
