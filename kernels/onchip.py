"""Semi-implicit Euler with a whole frame's substeps kept on chip: one CUDA block per group of tubes.

:func:`make_onchip_kernel` builds, for one combination of :class:`~.springs.Features`, one block
size and a number of assistant lines per tube, a kernel launched with ``wp.launch_tiled`` over
(world blocks, node groups): each block owns whole tubes, one thread per node, and the thread at
node ``i`` also owns the points of the tube's assistant lines at ``i``. A thread loads its node's
state and parameters into registers once, then for every substep

1. writes its compensated position ``(q, q_lo)`` (with spring damping also its velocity; with
   assistant lines also theirs) into a shared-memory tile, and reads its neighbours';
2. evaluates the terms it owns, each once, with the functions of :mod:`.springs`, first those
   that need its neighbours' values (so that these are not kept through the rest): structural
   spring ``i`` and three springs of each of its line points: the link and the chord of ``P_i'``
   and the tractive spring that crosses to node ``i + 1`` (:func:`~.assistant_line.al_lane_forces`:
   a line point's own springs are four at the force point, so each is evaluated where its
   tractive springs cross; every thread evaluates all three, one that is not there with no
   stiffness, so that no branch splits a warp);
3. with a curved rest shape, finds the Bishop normal of edge ``i - 1`` by a parallel prefix
   product along its tube (a Hillis-Steele scan, ``ceil(log2(tube length))`` rounds) of turns
   about the edges, unit complex numbers (:func:`~.frames.carried_twist`): each edge's turn from
   a normal of its own (:func:`~.frames.edge_normal`) to the one the previous edge's normal
   carries onto it (the rest normal at a tube's first edge), so that the product up to an edge
   turns its normal into its Bishop normal: two numbers a round where a scan of the transports
   themselves would carry quaternions;
4. evaluates the bending stencil at ``i`` and its frame terms (after the stencil, the suffix sums
   of the stencils' holonomy weights ``mu`` the same way; :func:`~.bending.curvature_targets` and
   :func:`~.bending.frame_forces` are the sequential form of both) and its node terms; it writes
   what its terms put on its two neighbours into a second tile and reads back what its
   neighbours' terms put on it;
5. advances its node (pinned nodes follow their targets, lerped from ``pin_q_start`` to
   ``pin_q_end`` over the frame) and its line points in registers;

and after the last substep stores the state once. Writing an element of a shared tile ends in a
block barrier (Warp), and every thread of the block writes each tile once a round (an idle
lane, past its block's tubes or worlds, writes the values of a real node that no active lane
reads), so each exchange costs one barrier and no tile is overwritten while read.

With ``exchange="shuffle"`` (CUDA, where the host's layout puts every tube within one warp of
32 lanes) the same exchanges go through registers instead (:mod:`.warp_shuffle`): each lane
takes its neighbours' values from the lanes beside it, the scans shuffle by ``1, 2, 4, ...``
lanes, and there is no shared memory and no barrier. Every lane of a warp calls each shuffle at
the same point (as every thread of a block writes each tile), and what a lane takes from another
tube, another warp or an idle lane is discarded by the same tests as above. With
``exchange="mixed"`` (CUDA, any layout) the scans of a curved tube run within each warp by
shuffles and are then carried between the warps a tube spans through one shared-memory tile each
(one barrier per scan instead of one per round); neighbours' values go through shared memory.
The values exchanged and the arithmetic are those of the shared-memory kernel, up to the order
of the scans' products and sums: with "shuffle" and "shared" that order depends only on a node's
place in its tube, with "mixed" also on where the tube sits against warp boundaries.

Block layout (set by the host, :class:`warp_tube.centerline.explicit.SemiImplicitEulerSolver`): the
tubes of one world are packed, in order, into groups of at most ``block_dim`` nodes
(``group_node_start``); a block holds ``worlds_per_block`` copies of one group from consecutive
worlds, each in ``slot`` consecutive lanes (``slot`` is the largest group's node count). So a
tube must fit in one block: at most :data:`MAX_BLOCK_DIM` points (longer tubes take the per-tube
kernel of :mod:`.integrate`).

On the CPU the same kernel runs when ``wp.config.enable_cpu_blocks`` is set (Warp's cooperative
fibers stand in for a block's threads, the barrier switches between them): slow, for testing.
"""


import functools

import warp as wp

from .frames import carried_twist, edge_binormal, edge_normal, turn_product, turned_components, twist_terms, twisted, unit_turn
from .options import CUDA_OPTIONS
from .warp_shuffle import shfl_down, shfl_down3, shfl_up, shfl_up2, shfl_up3, warp_prefix_turns, warp_suffix_sum, warp_suffix_sum2
from .assistant_line import al_lane_diagonal, al_lane_forces
from .bending import (bend_gradients_unit, curvature_binormal_unit, edge_tangent, first_edge_free, first_edge_normal, holonomy_stencil,
                      kappa_target, stencil_forces, twist_gradients)  # fmt: skip
from .springs import ControlArrays, Features, ModelArrays, StateArrays, frame_left, make_node_terms, pin_step, spring_force

#: Largest block (threads = nodes) of the on-chip kernel; longer tubes need another path.
MAX_BLOCK_DIM = 1024


@functools.cache
def make_onchip_kernel(features: Features, block_dim: int, al_lines: int = 0, max_registers: int | None = None,
                       exchange: str = "shared", twist_free: bool = False):  # fmt: skip
    """The on-chip substep kernel for ``features``, ``block_dim`` threads per block and at most
    ``al_lines`` assistant lines per tube; cached. ``max_registers`` caps the registers per thread
    on CUDA (more blocks resident per multiprocessor, at the price of spills); None: the compiler's
    choice. ``exchange`` (see the module docstring): "shared" (shared memory), "shuffle" (warp
    shuffles; CUDA, no tube spanning two warps) or "mixed" (CUDA: the scans of a curved tube by
    warp shuffles with one shared-memory carry between warps, the rest through shared memory).
    ``twist_free``: some curved tube's first edge may turn, so its first frame is twisted to the
    bending energy's minimum (:func:`~.bending.curvature_targets`; shared memory or shuffles,
    not mixed)."""
    features = Features(*(bool(v) for v in features))
    if not 1 <= block_dim <= MAX_BLOCK_DIM:
        raise ValueError(f"block_dim must be in [1, {MAX_BLOCK_DIM}], got {block_dim}")
    B = int(block_dim)
    if exchange not in ("shared", "shuffle", "mixed"):
        raise ValueError(f"exchange must be shared, shuffle or mixed, got {exchange!r}")
    SHUFFLE = exchange == "shuffle"  # every exchange through warp shuffles
    MIXED = exchange == "mixed"  # the scans through shuffles, carried between warps in shared memory
    SCAN_SHUFFLE = SHUFFLE or MIXED
    if SCAN_SHUFFLE and B % 32:
        raise ValueError(f"{exchange} exchanges need whole warps: block_dim {B} is not a multiple of 32")
    BENDING = features.bending
    CURVED = features.curved and features.bending
    FREE = CURVED and bool(twist_free)  # the first frames of tubes free to turn: twisted to the minimum
    if FREE and MIXED:
        raise ValueError("twist_free needs the shared-memory or the shuffle exchange")
    SD = features.spring_damping
    K = int(al_lines) if features.assistant_line else 0
    KL = max(K, 1)  # register arrays need a row even without lines
    # Shared-tile elements: per node (q, q_lo[, qd]) then per line point the same; what a thread's
    # terms put on its previous node, its next node and each line's next point.
    NODE = 9 if SD else 6
    POS = NODE * (1 + K)
    CON = 6 + 3 * K
    pos_t = wp.types.vector(length=POS, dtype=wp.float32)
    con_t = wp.types.vector(length=CON, dtype=wp.float32)
    lines3 = wp.types.matrix((KL, 3), dtype=wp.float32)
    lines_i = wp.types.vector(length=KL, dtype=wp.int32)
    lines4 = wp.types.matrix((KL, 4), dtype=wp.float32)
    load_node, node_force, _, _, _, advance = make_node_terms(features, lanes=True)

    @wp.func
    def get3(e: pos_t, off: int) -> wp.vec3:
        return wp.vec3(e[off], e[off + 1], e[off + 2])

    @wp.func
    def con3(e: con_t, off: int) -> wp.vec3:
        return wp.vec3(e[off], e[off + 1], e[off + 2])

    @wp.kernel(enable_backward=False, module="unique", module_options=CUDA_OPTIONS, cuda_max_registers=max_registers)
    def substeps_onchip(
        substep_count: int,
        dt: float,
        slot: int,
        worlds_per_block: int,
        group_node_start: wp.array[int],
        node_tube: wp.array[int],
        model: ModelArrays,
        state_in: StateArrays,
        control: ControlArrays,
        state_out: StateArrays,
    ):
        """Advance the nodes (and line points) of one group of tubes in ``worlds_per_block``
        worlds by ``substep_count`` substeps of ``dt`` [s]; one thread per node, state in
        registers, neighbours exchanged through shared memory."""
        block, g, lane = wp.tid()
        c = lane // slot
        w = block * worlds_per_block + c
        i = group_node_start[g] + (lane - c * slot)
        active = c < worlds_per_block and w < state_in.node_q.shape[0] and i < group_node_start[g + 1]

        zero = wp.vec3(0.0)
        t_rest = wp.vec3(1.0, 0.0, 0.0)
        u_rest = wp.vec3(0.0, 1.0, 0.0)
        kappa_rest = zero
        free_tube = False
        rest_len = float(0.0)
        ke = float(0.0)
        kd = float(0.0)
        ke_prev = float(0.0)
        kd_prev = float(0.0)
        kb = float(0.0)
        # Assistant-line points at this node, one row per line: state, the rest lengths of the
        # thread's three springs (link, chord, the tractive spring crossing to node i + 1), their
        # stiffnesses and dampings (the link's, then the chord's and the tractive spring's: zero
        # where the line is not there, so that its springs are evaluated without a branch and
        # exert nothing), which way the tractive spring goes (al_lane_diagonal), slot.
        al_x = lines3()
        al_lo = lines3()
        al_v = lines3()
        al_rest = lines3()
        al_k = lines4()
        al_dir = lines_i(-1)
        al_slot = lines_i(-1)
        # An idle lane loads the values of a real node (the last world's, the group's last node):
        # none of them reaches an active lane (every exchange is read under has_prev, has_next or a
        # scan's reach, all false or -1 on an idle lane) and nothing is stored from it, and loading
        # them unconditionally spares the substep loop a choice of each by `active`.
        wc = wp.min(w, state_in.node_q.shape[0] - 1)
        ic = wp.min(i, group_node_start[g + 1] - 1)
        pw = wc % model.node_mass.shape[0]
        t = node_tube[ic]
        start = model.tube_node_start[t]
        end = model.tube_node_start[t + 1]
        x = state_in.node_q[wc, ic]
        lo = state_in.node_q_lo[wc, ic]
        v = state_in.node_qd[wc, ic]
        im = model.node_inv_mass[pw, ic]
        inv_m = 1.0 / model.node_mass[pw, ic]
        alpha = model.node_damping[pw, ic]
        x_pin0 = control.pin_q_start[wc, ic]
        x_pin1 = control.pin_q_end[wc, ic]
        terms = load_node(model, control, wc, pw, ic)
        if ic + 1 < end:
            rest_len = model.seg_rest_length[pw, ic]
            ke = model.seg_ke[pw, ic]
            if wp.static(SD):
                kd = model.seg_kd[pw, ic]
        if ic > start:
            ke_prev = model.seg_ke[pw, ic - 1]
            if wp.static(SD):
                kd_prev = model.seg_kd[pw, ic - 1]
        if wp.static(BENDING):
            if ic > start and ic < end - 1:
                kb = model.node_bend_k[pw, ic]
        if wp.static(CURVED):
            t_rest = wp.normalize(model.node_rest_q[pw, start + 1] - model.node_rest_q[pw, start])
            u_rest = first_edge_normal(t_rest)
            kappa_rest = model.node_kappa_rest[pw, ic]
            if wp.static(FREE):
                free_tube = first_edge_free(model.node_inv_mass, pw, start)
        if wp.static(K > 0):
            # the link's stiffness and damping: segment i's, i - 1's at the last node
            link_ke = wp.where(ic + 1 < end, ke, ke_prev)
            link_kd = wp.where(ic + 1 < end, kd, kd_prev)
            for m in range(K):
                a = model.tube_al_force[t, m]
                if a >= 0:
                    if control.al_active[wc, a] != 0:
                        p = model.al_start[a] + (ic - start)
                        al_slot[m] = p
                        al_x[m] = state_in.al_q[wc, p]
                        al_lo[m] = state_in.al_q_lo[wc, p]
                        al_v[m] = state_in.al_qd[wc, p]
                        way = al_lane_diagonal(ic, model.force_node[a], end)
                        diagonal = float(0.0)
                        if way == 1:
                            diagonal = control.al_fwd_length[wc, p]
                        elif way == 0:
                            diagonal = control.al_bwd_length[wc, p + 1]
                        al_dir[m] = way
                        al_k[m] = wp.vec4(link_ke, link_kd, ke, kd)
                        al_rest[m] = wp.vec3(control.al_link_length[wc, p], control.al_chord_length[wc, p], diagonal)

        span = int(slot)  # shared-memory scans: rounds while their stride is below the tube slot
        wl = lane % 32  # lane in its warp
        # How far a scan may reach back (to the tube's first node) and forward (to its last) from
        # this lane; -1 on an idle lane. Through shuffles also no further than the warp's ends.
        back = int(-1)
        fwd = int(-1)
        if active:
            back = i - start
            fwd = end - 1 - i
        has_prev = back > 0
        has_next = fwd > 0
        if wp.static(MIXED):
            back = wp.min(back, wl)
            fwd = wp.min(fwd, 31 - wl)
        if wp.static(not SHUFFLE):
            pos_buf = wp.tile_zeros(shape=(B,), dtype=pos_t, storage="shared")
            con_buf = wp.tile_zeros(shape=(B,), dtype=con_t, storage="shared")
        if wp.static(CURVED and not SCAN_SHUFFLE):
            turns = wp.tile_zeros(shape=(2, B), dtype=wp.vec2, storage="shared")
            weights = wp.tile_zeros(shape=(2, B), dtype=float, storage="shared")
        if wp.static(FREE and not SHUFFLE):
            sums = wp.tile_zeros(shape=(2, B), dtype=wp.vec2, storage="shared")
        if wp.static(CURVED and MIXED):
            carry_z = wp.tile_zeros(shape=(B,), dtype=wp.vec2, storage="shared")
            carry_m = wp.tile_zeros(shape=(B,), dtype=float, storage="shared")
        inv_count = 1.0 / float(substep_count)
        inv_dt = 1.0 / dt
        for step in range(substep_count):
            # 1. Positions (and velocities) out, neighbours' in: the next node's (nx, nlo, nv, and
            # its line points') and, through shared memory, the previous node's position (px, plo;
            # through shuffles edge i - 1 comes from the lane before instead); at a tube's ends
            # whatever the lane beside holds (shuffles) or this node's own (shared memory), never
            # used there.
            px = x
            plo = lo
            nx = x
            nlo = lo
            nv = v
            nal_x = al_x
            nal_lo = al_lo
            nal_v = al_v
            if wp.static(SHUFFLE):
                tx = shfl_down3(x, 1)
                tlo = shfl_down3(lo, 1)
                tv = v
                if wp.static(SD):
                    tv = shfl_down3(v, 1)
                t_al_x = lines3()
                t_al_lo = lines3()
                t_al_v = lines3()
                if wp.static(K > 0):
                    for m in range(K):
                        t_al_x[m] = shfl_down3(al_x[m], 1)
                        t_al_lo[m] = shfl_down3(al_lo[m], 1)
                        if wp.static(SD):
                            t_al_v[m] = shfl_down3(al_v[m], 1)
                nx = tx
                nlo = tlo
                nv = tv
                nal_x = t_al_x
                nal_lo = t_al_lo
                nal_v = t_al_v
            else:
                own = pos_t()
                for k in range(3):
                    own[k] = x[k]
                    own[3 + k] = lo[k]
                    if wp.static(SD):
                        own[6 + k] = v[k]
                if wp.static(K > 0):
                    for m in range(K):
                        for k in range(3):
                            own[NODE * (m + 1) + k] = al_x[m, k]
                            own[NODE * (m + 1) + 3 + k] = al_lo[m, k]
                            if wp.static(SD):
                                own[NODE * (m + 1) + 6 + k] = al_v[m, k]
                pos_buf[lane] = own
                if has_prev:
                    prev = pos_buf[lane - 1]
                    px = get3(prev, 0)
                    plo = get3(prev, 3)
                if has_next:
                    nxt = pos_buf[lane + 1]
                    nx = get3(nxt, 0)
                    nlo = get3(nxt, 3)
                    if wp.static(SD):
                        nv = get3(nxt, 6)
                    if wp.static(K > 0):
                        nal_x = lines3()
                        nal_lo = lines3()
                        nal_v = lines3()
                        for m in range(K):
                            nal_x[m] = get3(nxt, NODE * (m + 1))
                            nal_lo[m] = get3(nxt, NODE * (m + 1) + 3)
                            if wp.static(SD):
                                nal_v[m] = get3(nxt, NODE * (m + 1) + 6)
            if wp.static(not SD):  # velocities enter only with spring damping
                nv = zero
                nal_v = lines3()
            e = wp.where(has_next, (nx - x) + (nlo - lo), zero)  # edge i (zero at its last node)
            # Bending: each edge's unit tangent and reciprocal length once; edge i - 1's from the
            # lane before (shuffles: the same bits; whatever that lane holds at a tube's first node,
            # never used there) or from the previous node's position (shared memory: zero at a
            # tube's first node); with a curved rest shape also each edge's own normal and binormal
            # (edge_normal, edge_binormal).
            t_e = zero
            ilb = float(0.0)
            t_p = zero
            ila = float(0.0)
            n_e = zero
            m_e = zero
            n_p = zero
            m_p = zero
            if wp.static(BENDING):
                t_e, ilb = edge_tangent(e)
                if wp.static(CURVED):
                    n_e = edge_normal(t_e)
                    m_e = edge_binormal(t_e)
                if wp.static(SHUFFLE):
                    t_p = shfl_up3(t_e, 1)
                    ila = shfl_up(ilb, 1)
                    if wp.static(CURVED):
                        n_p = shfl_up3(n_e, 1)
                        m_p = shfl_up3(m_e, 1)
                else:
                    t_p, ila = edge_tangent(wp.where(has_prev, (x - px) + (lo - plo), zero))
                    if wp.static(CURVED):
                        n_p = edge_normal(t_p)
                        m_p = edge_binormal(t_p)
            # A curved tube's first edge: no stencil, but the twist its frame's carry from the
            # rest direction puts into every later frame (bending.first_frame_gradient), the
            # twist gradient below of the curvature binormal of (rest direction, first edge).
            first_edge = False
            if wp.static(CURVED):
                first_edge = active and i == start and i < end - 1
            t_a = t_p
            kappa = zero
            q = float(0.0)
            if wp.static(BENDING):
                # On every lane (no branch to split the warp): kappa is used only where a stencil
                # or a first edge is (zero edges give finite values: the lengths are floored).
                t_a = wp.where(first_edge, t_rest, t_p)
                kappa, q = curvature_binormal_unit(t_a, t_e, wp.where(first_edge, 1.0, ila), ilb)

            # 2. The structural spring, then the line springs, while the neighbours' values are
            # at hand (they are not kept through the frames and the bending stencil).
            f = zero
            to_prev = zero
            to_next = zero
            fs = spring_force(e, nv - v, rest_len, ke, kd)  # (zero at a tube's last node: e = 0)
            f += fs
            to_next -= fs
            al_f = lines3()
            al_next = lines3()
            if wp.static(K > 0):
                for m in range(K):
                    # The link (point to node i), the chord (to point i + 1) and the tractive
                    # spring crossing to node i + 1: forward from the point to that node,
                    # backward from node i to point i + 1 (differences taken from the link's
                    # and the chord's and the edge; where there is no next node ke = kd = 0).
                    d_link = (x - al_x[m]) + (lo - al_lo[m])
                    dv_link = v - al_v[m]
                    d_chord = (nal_x[m] - al_x[m]) + (nal_lo[m] - al_lo[m])
                    dv_chord = nal_v[m] - al_v[m]
                    forward = al_dir[m] == 1
                    d_diag = wp.where(forward, e + d_link, d_chord - d_link)
                    dv_diag = wp.where(forward, (nv - v) + dv_link, dv_chord - dv_link)
                    f_link, f_chord, f_diag = al_lane_forces(d_link, dv_link, d_chord, dv_chord, d_diag, dv_diag, al_rest[m], al_k[m, 0], al_k[m, 1], al_k[m, 2], al_k[m, 3])
                    f_fwd = wp.where(forward, f_diag, zero)  # on the point; on node i + 1 against it
                    f_bwd = f_diag - f_fwd  # on node i; on point i + 1 against it
                    al_f[m] = f_link + f_chord + f_fwd
                    al_next[m] = -(f_chord + f_bwd)
                    f += f_bwd - f_link
                    to_next -= f_fwd

            # 3. Curved rest shapes: the Bishop frame of edge i - 1, by a scan of turns. Each
            # edge has a normal of its own (edge_normal); z is the turn about edge i from its
            # normal to the one edge i - 1's normal carries onto it (at a tube's first edge, the
            # rest normal's); the product of the turns up to edge i turns edge i's normal into its
            # Bishop normal.
            target = zero
            if wp.static(CURVED):
                # (on every lane, the last node's and idle lanes' turn chosen away: no branch)
                z = carried_twist(wp.where(has_prev, t_p, t_rest), wp.where(has_prev, n_p, u_rest), t_e, n_e, m_e)
                z = wp.where(has_next, z, wp.vec2(1.0, 0.0))
                z_prev = z
                has_stencil = has_prev and kb != 0.0  # (a stencil at i: edges i - 1 and i)
                if wp.static(SCAN_SHUFFLE):
                    z = warp_prefix_turns(z, back)
                    carried = wp.vec2(1.0, 0.0)
                    if wp.static(MIXED):
                        # Each warp's product from its first lane (or the tube's start) to lane
                        # 31; a lane multiplies in those of the earlier warps its tube spans.
                        carry_z[lane] = z
                        if active:
                            first_warp = (lane - (i - start)) // 32
                            j = lane // 32 - 1
                            while j >= first_warp:
                                carried = turn_product(carry_z[32 * j + 31], carried)
                                j = j - 1
                        z = turn_product(carried, z)
                    z_prev = shfl_up2(z, 1)
                    if wl == 0:
                        z_prev = carried  # the product up to the last lane of the warp before
                else:
                    turns[0, lane] = z
                    rd = int(0)
                    d = int(1)
                    while d < span:  # (the same on every thread: each meets the barrier)
                        if back >= d:
                            z = turn_product(turns[rd, lane - d], z)
                        rd = 1 - rd
                        turns[rd, lane] = z
                        d = d * 2
                    if has_stencil:
                        z_prev = turns[rd, lane - 1]
                # A stencil's target on every lane (the rest curvature's components turned instead
                # of the frame: the same target); where there is no stencil kb = 0 and what it
                # meets is multiplied by kb (finite on every lane: the lengths are floored).
                target = kappa_target(t_p, n_p, m_p, turned_components(kappa_rest, unit_turn(z_prev)))
                if wp.static(FREE):
                    # A tube whose first edge may turn: every target twisted by the angle that
                    # minimises its bending energy, the stencils' (A, B) summed over the tube by a
                    # suffix scan and read at its first node (bending.curvature_targets).
                    turns_here = has_stencil and free_tube
                    ab = wp.where(turns_here, twist_terms(t_p, target, kappa, kb), wp.vec2(0.0))
                    total = wp.vec2(0.0)
                    if wp.static(SHUFFLE):  # (the same sums in the same order, through registers)
                        ab = warp_suffix_sum2(ab, fwd)
                        first = wp.max(back, 0)  # from the tube's first lane (within this warp)
                        total = wp.vec2(shfl_up(ab[0], first), shfl_up(ab[1], first))
                    else:
                        sums[0, lane] = ab
                        rd = int(0)
                        d = int(1)
                        while d < span:
                            if fwd >= d:
                                ab += sums[rd, lane + d]
                            rd = 1 - rd
                            sums[rd, lane] = ab
                            d = d * 2
                        if turns_here:
                            total = sums[rd, lane - (i - start)]
                    cs = total / wp.length(total)  # (cos, sin) of psi = atan2(B, A) (NaN for a zero total: not chosen)
                    turned_target = wp.where(total[0] != 0.0 or total[1] != 0.0, twisted(t_p, target, cs[0], cs[1]), target)
                    target = wp.where(turns_here, turned_target, target)

            # 4. The bending stencil at i, its frame terms, the node terms.
            ga = zero
            gb = zero
            if wp.static(BENDING):
                # On every lane (no branch to split the warp): where kb = 0 (a tube's ends) the
                # gradients are zero and an idle lane's are never read.
                ga, gb = bend_gradients_unit(t_a, t_e, ila, ilb, kappa, q, target, kb)
            grad_a = zero
            grad_b = zero
            if wp.static(CURVED):
                stencil = kb != 0.0
                grad_a, mu = holonomy_stencil(t_p, ila, kappa, target, kb)  # (zero where kb = 0)
                # Suffix sums of mu along the tube: the later stencils' weight on this transport.
                m_after = float(0.0)
                if wp.static(SCAN_SHUFFLE):
                    mu = warp_suffix_sum(mu, fwd)
                    mu_later = float(0.0)
                    if wp.static(MIXED):
                        # Each warp's suffix sum from its first lane to the tube's end (or lane
                        # 31); a lane adds those of the later warps its tube spans.
                        carry_m[lane] = mu
                        if active:
                            last_warp = (lane + (end - 1 - i)) // 32
                            j = lane // 32 + 1
                            while j <= last_warp:
                                mu_later += carry_m[32 * j]
                                j = j + 1
                        mu += mu_later
                    mu_next = shfl_down(mu, 1)
                    if wl == 31:
                        mu_next = mu_later  # the sum from the first lane of the warp after
                    if has_next:
                        m_after = mu_next
                else:
                    weights[0, lane] = mu
                    rd = int(0)
                    d = int(1)
                    while d < span:
                        if fwd >= d:
                            mu += weights[rd, lane + d]
                        rd = 1 - rd
                        weights[rd, lane] = mu
                        d = d * 2
                    if has_next:
                        m_after = weights[rd, lane + 1]
                ta, tb = twist_gradients(kappa, m_after, ila, ilb)
                grad_a = wp.where(stencil, grad_a + ta, grad_a)
                grad_b = wp.where(stencil or first_edge, tb, zero)
            if wp.static(BENDING):
                c_prev, c_mid, c_next = stencil_forces(ga, gb, grad_a, grad_b)
                f += c_mid
                to_prev += c_prev
                to_next += c_next
            f += node_force(terms, x, v)
            # 4 (end). What this thread's terms put on its neighbours out, theirs on it in.
            if wp.static(SHUFFLE):
                from_prev = shfl_up3(to_next, 1)
                from_next = shfl_down3(to_prev, 1)
                al_from_prev = lines3()
                if wp.static(K > 0):
                    for m in range(K):
                        al_from_prev[m] = shfl_up3(al_next[m], 1)
                if has_prev:
                    f += from_prev
                    if wp.static(K > 0):
                        for m in range(K):
                            al_f[m] = al_f[m] + al_from_prev[m]
                if has_next:
                    f += from_next
            else:
                out = con_t()
                for k in range(3):
                    out[k] = to_prev[k]
                    out[3 + k] = to_next[k]
                if wp.static(K > 0):
                    for m in range(K):
                        for k in range(3):
                            out[6 + 3 * m + k] = al_next[m, k]
                con_buf[lane] = out
                if has_prev:
                    from_prev_buf = con_buf[lane - 1]
                    f += con3(from_prev_buf, 3)
                    if wp.static(K > 0):
                        for m in range(K):
                            al_f[m] = al_f[m] + con3(from_prev_buf, 6 + 3 * m)
                if has_next:
                    f += con3(con_buf[lane + 1], 0)

            # 5. Advance in registers.
            # (both steps on every lane and one chosen: a branch would split the warp all the same)
            pinned = im == 0.0
            x_pin, v_pin = pin_step(x_pin0, x_pin1, frame_left(step, substep_count, inv_count), x, inv_dt)
            x_free, lo_free, v_free = advance(x, lo, v, f, im, alpha, dt)
            x = wp.where(pinned, x_pin, x_free)  # (an idle lane steps too: nothing of it is read or stored)
            lo = wp.where(pinned, zero, lo_free)
            v = wp.where(pinned, v_pin, v_free)
            if wp.static(K > 0):
                for m in range(K):  # (a line that is not there steps too: nothing of it is stored)
                    xm, lm, vm = advance(al_x[m], al_lo[m], al_v[m], al_f[m], inv_m, alpha, dt)
                    al_x[m] = xm
                    al_lo[m] = lm
                    al_v[m] = vm
        if active:
            state_out.node_q[w, i] = x
            state_out.node_q_lo[w, i] = lo
            state_out.node_qd[w, i] = v
            if wp.static(K > 0):
                for m in range(K):
                    p = al_slot[m]
                    if p >= 0:
                        state_out.al_q[w, p] = al_x[m]
                        state_out.al_q_lo[w, p] = al_lo[m]
                        state_out.al_qd[w, p] = al_v[m]

    return substeps_onchip
