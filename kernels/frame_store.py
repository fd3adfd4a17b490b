"""Output frames gathered on the device: an array of points, in stage units, into its slot of a
window of frames.

:func:`store_scaled_kernel` runs a thread per (row, column) and writes
``out[slot, r, first + c] = src[r, c] / unit``, component by component (IEEE division: the same
arithmetic as NumPy's float32 ``src / unit``, so frames equal those a run alone writes bit for bit).

Shapes: ``src`` (rows, columns) vec3; ``out`` (frames, rows, all columns) vec3, a window of
frames whose columns ``first`` to ``first + columns`` this output fills (a prim's vertices, or a
prim's two extent corners); ``unit`` [m per stage unit], 1 for directions (normals). The frame
``slot`` is a launch parameter, so one recorded launch stores every frame of a window.
"""

from __future__ import annotations

import warp as wp


@wp.kernel(enable_backward=False)
def store_scaled_kernel(src: wp.array2d[wp.vec3], unit: float, out: wp.array3d[wp.vec3], slot: int, first: int):
    r, c = wp.tid()
    p = src[r, c]
    out[slot, r, first + c] = wp.vec3(p[0] / unit, p[1] / unit, p[2] / unit)
