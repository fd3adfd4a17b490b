"""Assistant lines laid in some worlds of a batch: their new rows written into the line arrays.

:func:`line_rows_kernel` runs a thread per (row, point) of a compact block built on the host (the
worlds whose line was built this frame, the points of one force's line) and writes it into the
state's and control's line arrays at ``[worlds[r], p0 + j]``; the chord and forward tractive rest
lengths of a line's last point, and the backward one of its first, are not the line's and stay.

Shapes: ``worlds`` (k,) int; ``q_hi``, ``q_lo``, ``qd`` (k, n) vec3 [m, m, m/s]; ``link`` (k, n),
``chord``, ``fwd``, ``bwd`` (k, n - 1) float [m]; the outputs (W, slots) as in
:class:`warp_tube.model.tube.TubeState` and :class:`~warp_tube.model.tube.TubeControl`.
"""

from __future__ import annotations

import warp as wp


@wp.kernel(enable_backward=False)
def line_rows_kernel(
    worlds: wp.array[int],
    p0: int,
    q_hi: wp.array2d[wp.vec3],
    q_lo: wp.array2d[wp.vec3],
    qd: wp.array2d[wp.vec3],
    link: wp.array2d[float],
    chord: wp.array2d[float],
    fwd: wp.array2d[float],
    bwd: wp.array2d[float],
    al_q: wp.array2d[wp.vec3],
    al_q_lo: wp.array2d[wp.vec3],
    al_qd: wp.array2d[wp.vec3],
    al_link_length: wp.array2d[float],
    al_chord_length: wp.array2d[float],
    al_fwd_length: wp.array2d[float],
    al_bwd_length: wp.array2d[float],
):
    r, j = wp.tid()
    w = worlds[r]
    s = p0 + j
    al_q[w, s] = q_hi[r, j]
    al_q_lo[w, s] = q_lo[r, j]
    al_qd[w, s] = qd[r, j]
    al_link_length[w, s] = link[r, j]
    if j < q_hi.shape[1] - 1:
        al_chord_length[w, s] = chord[r, j]
        al_fwd_length[w, s] = fwd[r, j]
        al_bwd_length[w, s + 1] = bwd[r, j]
