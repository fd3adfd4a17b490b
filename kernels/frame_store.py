"""Output frames gathered on the device: an array of points, in stage units, into its slot of a
frame buffer; a few columns of a state array gathered for the host; rows of new values scattered
into the worlds that take them.

:func:`store_scaled_kernel` runs a thread per (row, column) and writes
``out[r, c] = src[r, c] / unit``, component by component (IEEE division: the same arithmetic as
NumPy's float32 ``src / unit``, so frames equal those a run alone writes bit for bit).

Shapes: ``src`` and ``out`` (rows, columns) vec3; ``out`` may be a strided view (a slice of a
larger buffer); ``unit`` [m per stage unit], 1 for directions (normals).
"""

from __future__ import annotations

import warp as wp


@wp.kernel(enable_backward=False)
def store_scaled_kernel(src: wp.array2d[wp.vec3], unit: float, out: wp.array2d[wp.vec3]):
    r, c = wp.tid()
    p = src[r, c]
    out[r, c] = wp.vec3(p[0] / unit, p[1] / unit, p[2] / unit)


@wp.kernel(enable_backward=False)
def gather_columns_kernel(src: wp.array2d[wp.vec3], columns: wp.array[int], out: wp.array2d[wp.vec3]):
    """``out[r, j] = src[r, columns[j]]``: a few columns of every row (e.g. the nodes around each
    force, in every world), so that the host reads those instead of the whole array."""
    r, j = wp.tid()
    out[r, j] = src[r, columns[j]]


@wp.kernel(enable_backward=False)
def scatter_rows_kernel(
    rows: wp.array[int],
    first: int,
    q_src: wp.array2d[wp.vec3],
    lo_src: wp.array2d[wp.vec3],
    qd_src: wp.array2d[wp.vec3],
    q_dst: wp.array2d[wp.vec3],
    lo_dst: wp.array2d[wp.vec3],
    qd_dst: wp.array2d[wp.vec3],
):
    """``dst[rows[i], first + j] = src[i, j]`` for three arrays at once (an assistant line's new
    points, compensated positions and velocities, into the worlds that built it): sources (R, n),
    destinations (W, L) vec3."""
    i, j = wp.tid()
    w = rows[i]
    q_dst[w, first + j] = q_src[i, j]
    lo_dst[w, first + j] = lo_src[i, j]
    qd_dst[w, first + j] = qd_src[i, j]
