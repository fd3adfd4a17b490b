"""Rows of world-major arrays moved between a full array and a compact one, by a list of rows.

A thread per (row of the list, column): :func:`gather_rows_vec3` copies
``src[rows[i], src_col + c]`` to ``out[i, c]``; :func:`scatter_rows_vec3` and
:func:`scatter_rows_float` copy ``src[i, src_col + c]`` to ``out[rows[i], out_col + c]``. Plain
copies: the values move bit for bit.

Shapes: full arrays (worlds, columns); compact arrays (len(rows), width); ``rows`` (len(rows),)
int32, each a valid row of the full array, no row twice in a scatter.
"""

from __future__ import annotations

import warp as wp


@wp.kernel(enable_backward=False)
def gather_rows_vec3(src: wp.array2d[wp.vec3], rows: wp.array[wp.int32], src_col: int, out: wp.array2d[wp.vec3]):
    i, c = wp.tid()
    out[i, c] = src[rows[i], src_col + c]


@wp.kernel(enable_backward=False)
def scatter_rows_vec3(src: wp.array2d[wp.vec3], src_col: int, rows: wp.array[wp.int32], out_col: int, out: wp.array2d[wp.vec3]):
    i, c = wp.tid()
    out[rows[i], out_col + c] = src[i, src_col + c]


@wp.kernel(enable_backward=False)
def scatter_rows_float(src: wp.array2d[float], src_col: int, rows: wp.array[wp.int32], out_col: int, out: wp.array2d[float]):
    i, c = wp.tid()
    out[rows[i], out_col + c] = src[i, src_col + c]
