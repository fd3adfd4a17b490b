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
  ``beta`` [s] along every spring (``kd = beta ke``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import warp as wp

from ..scene.spec import Scene

__all__ = ["TubeModel", "TubeState", "TubeControl", "build_model", "rest_curvature_coordinates"]


def _first_edge_normal(t: np.ndarray) -> np.ndarray:
    """The fixed perpendicular used for the first edge's rest frame (same as the kernel)."""
    u = np.array([0.0, 1.0, 0.0]) if abs(t[0]) > 0.6 else np.array([1.0, 0.0, 0.0])
    u = u - t * np.dot(u, t)
    return u / np.linalg.norm(u)


def _rotate_minimal(x, a, b):
    v = np.cross(a, b)
    c = float(np.dot(a, b))
    vx = np.cross(v, x)
    return x + vx + np.cross(v, vx) / max(1.0 + c, 1e-6)


def curvature_binormal(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``2 a x b / (|a||b| + a.b)`` for edge vectors a, b, shape (..., 3)."""
    la = np.linalg.norm(a, axis=-1, keepdims=True)
    lb = np.linalg.norm(b, axis=-1, keepdims=True)
    den = np.maximum(la * lb + np.sum(a * b, axis=-1, keepdims=True), 1e-6 * la * lb + 1e-12)
    return 2.0 * np.cross(a, b) / den


def rest_curvature_coordinates(points: np.ndarray) -> np.ndarray:
    """Rest curvature binormals of one tube in its rest Bishop frames, shape (n, 3).

    Row ``j`` holds the components of ``kb_j`` along (tangent, u, v) of edge ``j - 1``'s frame; the
    first frame uses the fixed perpendicular of :func:`_first_edge_normal`. Rows 0 and n-1 are 0.
    """
    x = np.asarray(points, dtype=np.float64)
    n = len(x)
    out = np.zeros((n, 3))
    if n < 3:
        return out
    t = (x[1] - x[0]) / np.linalg.norm(x[1] - x[0])
    u = _first_edge_normal(t)
    for j in range(1, n - 1):
        kb = curvature_binormal(x[j] - x[j - 1], x[j + 1] - x[j])
        v = np.cross(t, u)
        out[j] = [np.dot(kb, t), np.dot(kb, u), np.dot(kb, v)]
        t_next = (x[j + 1] - x[j]) / np.linalg.norm(x[j + 1] - x[j])
        u = _rotate_minimal(u, t, t_next)
        u = u - t_next * np.dot(u, t_next)
        u /= np.linalg.norm(u)
        t = t_next
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
    ``host`` keeps NumPy copies (float64) of the same quantities for host-side checks.
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
    features: object  # kernels.springs.Features
    host: dict

    def state(self) -> TubeState:
        """A new state at rest."""
        q = np.repeat(self.host["node_rest_q"][None], self.world_count, axis=0)
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

    def control(self) -> TubeControl:
        """A new control: no forces, pins at rest, no assistant line."""
        q = np.repeat(self.host["node_rest_q"][None], self.world_count, axis=0)
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


def build_model(scene: Scene, world_count: int = 1, device=None) -> TubeModel:
    """Discretise ``scene`` into a :class:`TubeModel` on ``device`` (Warp device or name)."""
    from warp_tube.kernels.springs import Features

    device = str(wp.get_device(device))
    pts, tube_start, node_tube = [], [0], []
    mass, inv_mass, damping, rest_len, ke, kd, bend_k, kappa, anchor_k, anchor_kd, radius = ([] for _ in range(11))
    prim_node_start = []
    curved = False
    t_index = 0
    for spec in scene.tubes:
        prim_node_start.append(tube_start[-1])
        p = spec.params
        pinned = np.zeros(len(spec.points), dtype=bool)
        pinned[spec.pinned] = True
        anchored = np.zeros(len(spec.points), dtype=bool)
        anchored[spec.anchors] = True
        for c0, cn in zip(spec.curve_starts, spec.curve_counts):
            x = spec.points[c0 : c0 + cn]
            r = spec.radius[c0 : c0 + cn]
            pin = pinned[c0 : c0 + cn]
            seg = np.linalg.norm(x[1:] - x[:-1], axis=1)
            r_seg = 0.5 * (r[1:] + r[:-1])
            m_seg = p.density * np.pi * r_seg**2 * seg
            m = np.zeros(cn)
            m[:-1] += 0.5 * m_seg
            m[1:] += 0.5 * m_seg
            elastic = ~(pin[1:] & pin[:-1])
            l_el = np.where(elastic, seg, 0.0)
            l_v = np.zeros(cn)
            l_v[1:-1] = 0.5 * (l_el[:-1] + l_el[1:])
            ei = p.bending_stiffness(r)
            bk = np.where(l_v > 0.0, ei / np.where(l_v > 0, l_v, 1.0), 0.0)
            bk[0] = bk[-1] = 0.0
            k_ax = p.axial_stiffness(r_seg) / seg
            pts.append(x)
            radius.append(r)
            mass.append(m)
            inv_mass.append(np.where(pin, 0.0, 1.0 / m))
            damping.append(np.full(cn, p.damping))
            rest_len.append(np.append(seg, 0.0))
            ke.append(np.append(k_ax, 0.0))
            kd.append(np.append(k_ax * p.spring_damping, 0.0))
            bend_k.append(bk)
            kap = rest_curvature_coordinates(x)
            if float(np.abs(kap).max()) > 1e-6:
                curved = True
            kappa.append(kap)
            ka = np.where(anchored[c0 : c0 + cn], p.anchor_stiffness, 0.0)
            anchor_k.append(ka)
            anchor_kd.append(ka * p.spring_damping)
            node_tube.append(np.full(cn, t_index))
            t_index += 1
            tube_start.append(tube_start[-1] + cn)
    cat = lambda a: np.concatenate(a)  # noqa: E731
    host = dict(
        node_rest_q=cat(pts), node_mass=cat(mass), node_inv_mass=cat(inv_mass), node_damping=cat(damping),
        seg_rest_length=cat(rest_len), seg_ke=cat(ke), seg_kd=cat(kd), node_bend_k=cat(bend_k),
        node_kappa_rest=cat(kappa), node_anchor_k=cat(anchor_k), node_anchor_kd=cat(anchor_kd), node_radius=cat(radius),
        tube_node_start=np.array(tube_start), node_tube=cat(node_tube), prim_node_start=np.array(prim_node_start),
    )  # fmt: skip
    n_nodes = tube_start[-1]
    # Forces sorted by tube, each with its global node and its assistant-line slots.
    tube_of_force, node_of_force = [], []
    for f in scene.forces:
        spec = scene.tubes[f.tube]
        c = int(np.searchsorted(spec.curve_starts, f.point, side="right") - 1)
        t = int(host["node_tube"][prim_node_start[f.tube] + spec.curve_starts[c]])
        tube_of_force.append(t)
        node_of_force.append(prim_node_start[f.tube] + f.point)
    order = np.argsort(np.asarray(tube_of_force, dtype=np.int64), kind="stable")
    host["force_order"] = order  # scene force index of each model force
    force_tube = np.asarray(tube_of_force, dtype=np.int64)[order] if len(order) else np.zeros(0, np.int64)
    force_node = np.asarray(node_of_force, dtype=np.int64)[order] if len(order) else np.zeros(0, np.int64)
    tube_force_start = np.searchsorted(force_tube, np.arange(t_index + 1)) if len(order) else np.zeros(t_index + 1, np.int64)
    uses_al = [scene.forces[k].assistant_line for k in order]
    al_start, al_force_index, slot = [], [], 0
    for a, t in enumerate(force_tube):
        al_start.append(slot)
        if uses_al[a]:
            n = tube_start[t + 1] - tube_start[t]
            al_force_index.extend([a] * n)
            slot += n
    lines = [[a for a in range(tube_force_start[t], tube_force_start[t + 1]) if uses_al[a]] for t in range(t_index)]
    al_lines = max((len(v) for v in lines), default=0)
    tube_al_force = np.full((t_index, max(al_lines, 1)), -1, dtype=np.int64)
    for t, v in enumerate(lines):
        tube_al_force[t, : len(v)] = v
    host.update(force_tube=force_tube, force_node=force_node, tube_force_start=tube_force_start,
                al_start=np.asarray(al_start, dtype=np.int64), force_uses_al=np.asarray(uses_al, dtype=bool),
                tube_al_force=tube_al_force)  # fmt: skip
    g = scene.settings.gravity
    features = Features(
        bending=bool((host["node_bend_k"] > 0).any()),
        curved=curved,
        anchors=bool((host["node_anchor_k"] > 0).any()),
        gravity=g is not None and any(v != 0.0 for v in g),
        mass_damping=bool((host["node_damping"] > 0).any()),
        spring_damping=bool((host["seg_kd"] > 0).any() or (host["node_anchor_kd"] > 0).any()),
        external=len(scene.forces) > 0,
        assistant_line=slot > 0,
    )

    def row(a, dtype=float):
        return wp.array(np.asarray(a)[None], dtype=dtype, device=device)

    def ints(a):
        a = np.asarray(a, dtype=np.int32)
        return wp.array(a if len(a) else np.zeros(1, np.int32), dtype=int, device=device)

    return TubeModel(
        device=device, world_count=int(world_count), node_count=int(n_nodes), tube_count=t_index,
        force_count=len(order), al_slots=slot,
        tube_node_start=ints(tube_start), node_tube=ints(host["node_tube"]),
        node_rest_q=row(host["node_rest_q"], wp.vec3), node_mass=row(host["node_mass"]),
        node_inv_mass=row(host["node_inv_mass"]), node_damping=row(host["node_damping"]),
        seg_rest_length=row(host["seg_rest_length"]), seg_ke=row(host["seg_ke"]), seg_kd=row(host["seg_kd"]),
        node_bend_k=row(host["node_bend_k"]), node_kappa_rest=row(host["node_kappa_rest"], wp.vec3),
        node_anchor_k=row(host["node_anchor_k"]), node_anchor_kd=row(host["node_anchor_kd"]),
        gravity=wp.vec3(*(g if g is not None else (0.0, 0.0, 0.0))),
        tube_force_start=ints(tube_force_start), force_node=ints(force_node), force_tube=ints(force_tube),
        al_start=ints(al_start), al_force_index=ints(al_force_index), al_lines=al_lines,
        tube_al_force=wp.array(tube_al_force.astype(np.int32), dtype=int, device=device),
        features=features, host=host,
    )  # fmt: skip
