"""Exchanges between the threads of one CUDA warp (32 lanes) through registers: ``__shfl_up_sync``
and ``__shfl_down_sync`` over the full warp.

Every lane of the warp must call each function at the same point (no lane inside a branch the
others skip): the on-chip kernel calls them where every lane of a block already meets for its
shared-memory exchanges. A lane whose source lane lies outside the warp gets its own value back.
The value passes bit for bit.

On the CPU there is no warp: the functions return their argument, and a kernel that exchanges
values with them must not run there (the on-chip kernel takes its shared-memory exchange on the
CPU, :func:`~.onchip.make_onchip_kernel`).
"""

from __future__ import annotations

import warp as wp

__all__ = ["shfl_up", "shfl_down", "shfl_up3", "shfl_down3", "shfl_up_quat"]

_UP = """
#if defined(__CUDA_ARCH__)
    return __shfl_up_sync(0xffffffffu, x, (unsigned)d);
#else
    return x;
#endif
"""

_DOWN = """
#if defined(__CUDA_ARCH__)
    return __shfl_down_sync(0xffffffffu, x, (unsigned)d);
#else
    return x;
#endif
"""


@wp.func_native(_UP)
def shfl_up(x: float, d: int) -> float:
    """``x`` of the lane ``d`` below this one in the warp (this lane's own below lane 0)."""


@wp.func_native(_DOWN)
def shfl_down(x: float, d: int) -> float:
    """``x`` of the lane ``d`` above this one in the warp (this lane's own above lane 31)."""


@wp.func
def shfl_up3(x: wp.vec3, d: int) -> wp.vec3:
    return wp.vec3(shfl_up(x[0], d), shfl_up(x[1], d), shfl_up(x[2], d))


@wp.func
def shfl_down3(x: wp.vec3, d: int) -> wp.vec3:
    return wp.vec3(shfl_down(x[0], d), shfl_down(x[1], d), shfl_down(x[2], d))


@wp.func
def shfl_up_quat(q: wp.quat, d: int) -> wp.quat:
    return wp.quat(shfl_up(q[0], d), shfl_up(q[1], d), shfl_up(q[2], d), shfl_up(q[3], d))

