"""Output frames gathered on the device: an array of points, in stage units, into its slot of a
frame buffer.

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
