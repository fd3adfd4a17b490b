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

from .frames import turn_product

#: Rounds of a Hillis-Steele scan over a warp's 32 lanes (strides 1, 2, 4, 8, 16).
WARP_ROUNDS = 5

__all__ = ["shfl_up", "shfl_down", "shfl_up3", "shfl_down3", "shfl_up2", "warp_prefix_turns", "warp_suffix_sum", "warp_suffix_sum2"]

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
def shfl_up2(x: wp.vec2, d: int) -> wp.vec2:
    return wp.vec2(shfl_up(x[0], d), shfl_up(x[1], d))


@wp.func
def warp_prefix_turns(z: wp.vec2, back: int) -> wp.vec2:
    """The product of turns ``z`` (:func:`~.frames.turn_product`) over this lane and the ``back``
    lanes before it (-1 on an idle lane), by a Hillis-Steele scan: every lane meets each round."""
    p = z
    for r in range(WARP_ROUNDS):
        d = 1 << r
        p = turn_product(wp.where(back >= d, shfl_up2(p, d), wp.vec2(1.0, 0.0)), p)
    return p


@wp.func
def warp_suffix_sum(x: float, fwd: int) -> float:
    """The sum of ``x`` over this lane and the ``fwd`` lanes after it (-1 on an idle lane), by a
    Hillis-Steele scan: every lane meets each round."""
    s = x
    for r in range(WARP_ROUNDS):
        d = 1 << r
        s += wp.where(fwd >= d, shfl_down(s, d), 0.0)
    return s


@wp.func
def warp_suffix_sum2(x: wp.vec2, fwd: int) -> wp.vec2:
    """:func:`warp_suffix_sum` of both components of ``x``."""
    s = x
    for r in range(WARP_ROUNDS):
        d = 1 << r
        s += wp.where(fwd >= d, wp.vec2(shfl_down(s[0], d), shfl_down(s[1], d)), wp.vec2(0.0))
    return s
