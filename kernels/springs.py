"""The centerline's force terms, each defined once: the Warp functions every centerline path calls
(bending and the curved rest shape's frames in :mod:`.bending`, the assistant line's springs in
:mod:`.assistant_line`).

The paths (the per-tube kernel of :mod:`.integrate`, the on-chip kernel of :mod:`.onchip`, implicit
Euler in :mod:`.implicit`) differ only in how they walk a tube and sum what these functions
return; implicit Euler takes each term's energy, stiffness and damping blocks from here too, next
to its force. The stability bound (``warp_tube.centerline.stability``) reads the same stiffness
fields. ``ARCHITECTURE.md`` ("Adding a force term") says how a new term joins them.

=========================== ====================================== ==============================
term                        functions                              parameters
=========================== ====================================== ==============================
structural spring, and its  :func:`spring_force`, spring_energy,   seg_rest_length, seg_ke,
damping along it            spring_stiffness, spring_damping_*      seg_kd
bending                     :mod:`.bending`: bend_gradients (its   node_bend_k
                            unit form bend_gradients_unit from
                            edge_tangent, curvature_binormal_unit),
                            bend_jacobians, bend_energy
curved rest shape (Bishop   :mod:`.bending`: kappa_target,         node_kappa_rest
frame and its holonomy)     holonomy_stencil, twist_gradients,
                            first_frame_gradient (frames:
                            rotate_minimal, carried_twist)
returning spring, gravity,  :class:`NodeTerms` via                  node_anchor_k, node_anchor_kd,
point force                 :func:`make_node_terms`                 gravity, node_f_ext
pins                        :func:`pin_step`, frame_left           node_inv_mass 0, pin targets
mass damping                ``advance`` of make_node_terms          node_damping
assistant line: link,       :mod:`.assistant_line`: al_springs,    control.al_* rest lengths,
chord, tractive springs     al_point_forces, al_spring_block,      seg_ke, seg_kd
                            al_point_energy
=========================== ====================================== ==============================

Precision: the functions implicit Euler uses are generic in the float type (``wp.Float``):
float32 in the explicit kernels, float64 in the implicit one. Constants are written
``type(x)(c)`` so that both instances compute in their own precision.

Array conventions (see ``warp_tube.model.tube.TubeModel``): nodes of all tubes of one world are
concatenated; state arrays are (world_count, node_count); parameter arrays are
(1 or world_count, node_count) and read at row ``pw = w % rows``. Segment ``i`` joins node ``i``
to node ``i + 1`` of the same tube. Units: m, kg, s, N.
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import warp as wp


EPS = wp.constant(1.0e-12)

Vec = wp.types.vector(3, wp.Float)
Mat = wp.types.matrix((3, 3), wp.Float)


class Features(NamedTuple):
    """Which terms a scene uses; each False term is compiled out of every path."""

    bending: bool = True
    curved: bool = False
    anchors: bool = False
    gravity: bool = False
    mass_damping: bool = False
    spring_damping: bool = False
    external: bool = False
    assistant_line: bool = False


@wp.struct
class ModelArrays:
    """The TubeModel arrays the kernels read (units and shapes as in TubeModel)."""

    tube_node_start: wp.array[int]
    node_rest_q: wp.array2d[wp.vec3]
    node_mass: wp.array2d[float]
    node_inv_mass: wp.array2d[float]
    node_damping: wp.array2d[float]
    seg_rest_length: wp.array2d[float]
    seg_ke: wp.array2d[float]
    seg_kd: wp.array2d[float]
    node_bend_k: wp.array2d[float]
    node_kappa_rest: wp.array2d[wp.vec3]
    node_anchor_k: wp.array2d[float]
    node_anchor_kd: wp.array2d[float]
    gravity: wp.vec3
    tube_force_start: wp.array[int]
    force_node: wp.array[int]
    al_start: wp.array[int]
    tube_al_force: wp.array2d[int]


@wp.struct
class ControlArrays:
    """A TubeControl's arrays."""

    node_f_ext: wp.array2d[wp.vec3]
    pin_q_start: wp.array2d[wp.vec3]
    pin_q_end: wp.array2d[wp.vec3]
    al_active: wp.array2d[int]
    al_link_length: wp.array2d[float]
    al_chord_length: wp.array2d[float]
    al_fwd_length: wp.array2d[float]
    al_bwd_length: wp.array2d[float]


@wp.struct
class StateArrays:
    """A TubeState's arrays."""

    node_q: wp.array2d[wp.vec3]
    node_q_lo: wp.array2d[wp.vec3]
    node_qd: wp.array2d[wp.vec3]
    al_q: wp.array2d[wp.vec3]
    al_q_lo: wp.array2d[wp.vec3]
    al_qd: wp.array2d[wp.vec3]


def pack(struct_type, source):
    """Fill a new ``struct_type`` from the same-named attributes of ``source``."""
    out = struct_type()
    for name in struct_type.vars:
        setattr(out, name, getattr(source, name))
    return out


# -- springs: structural, and the assistant line's ---------------------------------------------


@wp.func(inline=True)
def spring_force(d: Vec, dv: Vec, rest_length: wp.Float, ke: wp.Float, kd: wp.Float):
    """Force on end ``a`` of a spring from ``a`` to ``b`` [N], given ``d = xb - xa`` [m] and
    ``dv = vb - va`` [m/s].

    Hookean along the spring, ``ke * (|d| - L)``, plus damping along it, ``kd * dv . d_hat``. A
    zero-length spring exerts no force (no direction to push along): ``d_hat`` is ``d`` over its
    length floored at ``EPS``, zero for a zero ``d`` (and shorter than 1 for a spring shorter than
    ``EPS``, which pushes with at most ``ke L``).
    """
    length = wp.length(d)
    n = d * (type(length)(1.0) / wp.max(length, type(length)(EPS)))
    return n * (ke * (length - rest_length) + kd * wp.dot(dv, n))


@wp.func(inline=True)
def spring_energy(d: Vec, rest_length: wp.Float, ke: wp.Float):
    """Energy ``ke/2 (|d| - L)^2`` [J] of the spring of :func:`spring_force`."""
    stretch = wp.length(d) - rest_length
    return type(stretch)(0.5) * ke * stretch * stretch


@wp.func(inline=True)
def spring_stiffness(d: Vec, rest_length: wp.Float, ke: wp.Float):
    """Stiffness block [N/m] of :func:`spring_force`: the Hessian of :func:`spring_energy`,
    ``ke (n n^T + (1 - L/|d|) (I - n n^T))``, with the transverse factor clamped at 0 (a
    compressed spring would otherwise give a negative eigenvalue)."""
    length = wp.length(d)
    nn = wp.outer(d, d) / (length * length)
    t = wp.max(type(length)(1.0) - rest_length / length, type(length)(0.0))
    return (nn + (wp.identity(n=3, dtype=type(length)) - nn) * t) * ke


@wp.func(inline=True)
def spring_damping_matrix(d: Vec, kd: wp.Float):
    """Velocity Jacobian ``kd n n^T`` [N s/m] of the damping in :func:`spring_force`."""
    return wp.outer(d, d) * (kd / wp.dot(d, d))


@wp.func(inline=True)
def spring_dissipation(d: Vec, d0: Vec, kd: wp.Float, h: wp.Float):
    """Dissipation potential [J] of the spring damping over a step of ``h`` [s] from end
    difference ``d0`` to ``d`` [m]: ``kd / (2h) ((d - d0) . n)^2``, ``n`` taken at ``d`` (its
    stationary point in ``d`` is the damping force of :func:`spring_force`)."""
    length = wp.length(d)
    if length < type(length)(EPS):
        return type(length)(0.0)
    dd = wp.dot(d - d0, d / length)
    return type(length)(0.5) * kd * dd * dd / h


# -- geometry shared by the terms -------------------------------------------------------------


@wp.func
def node_delta(node_q: wp.array2d[wp.vec3], node_q_lo: wp.array2d[wp.vec3], w: int, i: int, j: int) -> wp.vec3:
    """``x_j - x_i`` [m] from the compensated positions ``node_q + node_q_lo``.

    The float32 difference of nearby positions is exact, so adding the difference of the
    low-order parts recovers the segment to well below the positions' own rounding (which times a
    stiff spring would be force noise that heats a long undamped run).
    """
    return (node_q[w, j] - node_q[w, i]) + (node_q_lo[w, j] - node_q_lo[w, i])


# -- the stability bound's row sums, term by term ---------------------------------------------
# Semi-implicit Euler's step bound (warp_tube.centerline.stability) takes the highest natural
# frequency from Gershgorin's theorem on M^-1 K: each term adds to the rows of the nodes it acts on
# the sum of the absolute entries of its stiffness, as below; ``stability_rows_kernel`` sums them.


@wp.func
def spring_rows(ke: wp.float64) -> wp.float64:
    """Row sum [N/m] a spring of stiffness ``ke`` (:func:`spring_stiffness` along it) adds to each of
    its ends: the diagonal and the neighbour, ``2 ke``."""
    return wp.float64(2.0) * ke


@wp.func
def bend_rows(k: wp.float64, la: wp.float64, lb: wp.float64) -> wp.vec3d:
    """Row sums [N/m] of a bending stencil's Gauss-Newton stiffness ``k J^T J`` on its (prev, mid,
    next) nodes: ``k |J_m| sum_n |J_n|`` with the Jacobian magnitudes of a straight stencil of edge
    lengths ``la``, ``lb`` (:func:`bend_jacobians`: ``|dkb/da| = 2 |b| / D = 1 / |a|``),
    ``(1/la, 1/la + 1/lb, 1/lb)``."""
    jac = wp.vec3d(wp.float64(1.0) / la, wp.float64(1.0) / la + wp.float64(1.0) / lb, wp.float64(1.0) / lb)
    return (jac * k) * (jac[0] + jac[1] + jac[2])


@wp.func
def anchor_rows(ka: wp.float64) -> wp.float64:
    """Row sum [N/m] of a returning spring of stiffness ``ka``, counted as a spring (``2 ka``)."""
    return wp.float64(2.0) * ka


@wp.func
def al_rows(axial: wp.float64, lines: int) -> wp.float64:
    """Row sum [N/m] the assistant lines add at a node whose structural springs add ``axial``: per
    line a link and a tractive spring beside every structural spring (:func:`al_springs`, with the
    stiffness of the segment beside them), ``2 lines axial``."""
    return wp.float64(2.0 * float(lines)) * axial


@wp.struct
class StabilityArrays:
    """The model's stiffness fields the row sums read, float64 host copies, shape (node_count,)
    (filled by name from ``TubeModel.host``)."""

    seg_rest_length: wp.array[wp.float64]
    seg_ke: wp.array[wp.float64]
    node_bend_k: wp.array[wp.float64]
    node_anchor_k: wp.array[wp.float64]


@wp.kernel(enable_backward=False, module="unique")
def stability_rows_kernel(lines: int, tube_node_start: wp.array[int], m: StabilityArrays, rows_out: wp.array[wp.float64]):
    """Gershgorin row sums [N/m] of the stiffness of one tube (thread per tube), from the terms'
    row functions above; ``lines`` assistant lines on every tube."""
    t = wp.tid()
    start = tube_node_start[t]
    end = tube_node_start[t + 1]
    zero = wp.float64(0.0)
    for i in range(start, end):
        rows_out[i] = zero
    for i in range(start, end - 1):
        r = spring_rows(m.seg_ke[i])
        rows_out[i] = rows_out[i] + r
        rows_out[i + 1] = rows_out[i + 1] + r
    for i in range(start, end):
        rows_out[i] = rows_out[i] + al_rows(rows_out[i], lines)
    for j in range(start + 1, end - 1):
        if m.node_bend_k[j] > zero:
            r3 = bend_rows(m.node_bend_k[j], m.seg_rest_length[j - 1], m.seg_rest_length[j])
            rows_out[j - 1] = rows_out[j - 1] + r3[0]
            rows_out[j] = rows_out[j] + r3[1]
            rows_out[j + 1] = rows_out[j + 1] + r3[2]
    for i in range(start, end):
        rows_out[i] = rows_out[i] + anchor_rows(m.node_anchor_k[i])


# -- pins ---------------------------------------------------------------------------------------


@wp.func
def pin_step(x_start: wp.vec3, x_end: wp.vec3, left: float, x: Vec, inv_dt: wp.Float):
    """A pinned node's substep: its target [m], lerped over the frame from ``x_start`` to
    ``x_end`` (``left``, the fraction of the frame left after the substep, is 0 at its last), and
    the velocity [m/s] that takes it there from ``x`` in a substep of ``1 / inv_dt`` [s] (in the
    precision of ``x``); :func:`frame_left` gives ``left``.

    The target is ``x_end - left (x_end - x_start)``: exactly ``x_end`` at the frame's end
    (``left`` = 0: the next frame starts from it) and exactly where it is for a pin that holds
    (``wp.lerp``'s ``x_start (1 - frac) + x_end frac`` wandered by a float32 step between
    substeps for a pin that holds: 1 um at 10 m from the origin, whose velocity of ulp / dt shook
    the tube)."""
    x_new = x_end - (x_end - x_start) * left
    return x_new, (type(x)(x_new) - x) * inv_dt


@wp.func
def frame_left(step: int, substep_count: int, inv_count: float) -> float:
    """The fraction of a frame of ``substep_count`` substeps left after substep ``step`` (from 0):
    ``(substep_count - step - 1) inv_count`` with ``inv_count = 1 / substep_count``, exactly 0
    after the last."""
    return float(substep_count - step - 1) * inv_count


# -- node terms: returning spring, gravity, point force; mass damping -------------------------


@wp.struct
class NodeTerms:
    """The parameters of a node's own force terms, fixed over a frame.

    Attributes:
        anchor_q: rest position its returning spring pulls towards [m].
        anchor_k: returning-spring stiffness [N/m] (0: no anchor).
        anchor_kd: returning-spring damping [N s/m].
        f_applied: gravity ``m g`` plus the point force on the node [N].
    """

    anchor_q: wp.vec3
    anchor_k: float
    anchor_kd: float
    f_applied: wp.vec3


def node_terms_have_blocks(features: Features) -> bool:
    """Whether a node term of ``features`` has stiffness or damping blocks (implicit Euler adds
    ``stiffness`` and ``damping`` of :func:`make_node_terms` only then): the returning spring."""
    return bool(features.anchors)


@functools.cache
def make_node_terms(features: Features, lanes: bool = False):
    """The node terms specialised to ``features`` (unused terms compiled out); cached.

    ``lanes``: the form for a kernel whose nodes run side by side in the lanes of a warp (the
    on-chip kernel): the returning spring evaluated on every node (one without it has
    ``k = kd = 0``), where a branch would run both ways in any warp holding an anchored node; by
    default it is skipped where ``k`` is 0 (the per-tube kernel's nodes run one after the other).
    The same force either way.

    Returns ``(load, force, energy, stiffness, damping, advance)``:

    - ``load(model, control, w, pw, i) -> NodeTerms``;
    - ``force(p, x, v)`` [N], ``energy(p, x)`` [J] and the coefficients of ``I`` in the stiffness
      [N/m] and damping [N s/m] blocks, ``stiffness(p)``, ``damping(p)``: generic in the float
      type of ``x``, ``v``;
    - ``advance(x, lo, v, f, inv_mass, alpha, dt) -> (x', lo', v')``: the semi-implicit Euler
      update with mass-proportional damping ``alpha`` [1/s] taken implicitly.
    """
    features = Features(*(bool(v) for v in features))
    ANCHORS = features.anchors
    GRAVITY = features.gravity
    EXTERNAL = features.external
    MASS_DAMPING = features.mass_damping
    LANES = bool(lanes)

    @wp.func(inline=True)
    def load(model: ModelArrays, control: ControlArrays, w: int, pw: int, i: int) -> NodeTerms:
        p = NodeTerms()
        p.anchor_q = wp.vec3(0.0)
        p.anchor_k = 0.0
        p.anchor_kd = 0.0
        p.f_applied = wp.vec3(0.0)
        if wp.static(ANCHORS):
            p.anchor_q = model.node_rest_q[pw, i]
            p.anchor_k = model.node_anchor_k[pw, i]
            p.anchor_kd = model.node_anchor_kd[pw, i]
        if wp.static(GRAVITY):
            p.f_applied = model.gravity * model.node_mass[pw, i]
        if wp.static(EXTERNAL):
            p.f_applied = p.f_applied + control.node_f_ext[w, i]
        return p

    @wp.func
    def force(p: NodeTerms, x: Vec, v: Vec):
        f = type(x)(p.f_applied)
        if wp.static(ANCHORS):
            anchored = True  # (lanes: on every node, a constant the compiler takes the branch out for)
            if wp.static(not LANES):
                anchored = p.anchor_k > 0.0
            if anchored:
                f = f - (x - type(x)(p.anchor_q)) * type(x[0])(p.anchor_k) - v * type(x[0])(p.anchor_kd)
        return f

    @wp.func
    def energy(p: NodeTerms, x: Vec):
        e = -wp.dot(type(x)(p.f_applied), x)
        if wp.static(ANCHORS):
            e = e + type(x[0])(0.5 * p.anchor_k) * wp.length_sq(x - type(x)(p.anchor_q))
        return e

    @wp.func
    def stiffness(p: NodeTerms) -> float:
        return p.anchor_k

    @wp.func
    def damping(p: NodeTerms) -> float:
        return p.anchor_kd

    @wp.func
    def advance(x: wp.vec3, lo: wp.vec3, v: wp.vec3, f: wp.vec3, inv_mass: float, alpha: float, dt: float):
        """Semi-implicit Euler with implicit mass-proportional damping; returns (x', lo', v').

        The position sum is compensated (Kahan): ``lo`` carries the low-order bits that adding a
        small ``v dt`` to a float32 position drops. Without it the dropped bits act as white
        noise that heats the stiff axial modes of a long undamped run.
        """
        v_new = v + f * (inv_mass * dt)
        if wp.static(MASS_DAMPING):
            v_new = v_new / (1.0 + alpha * dt)
        y = v_new * dt + lo
        x_new = x + y
        return x_new, y - (x_new - x), v_new

    return load, force, energy, stiffness, damping, advance
