"""The floating-point mode of the CPU thread that launches a kernel: subnormal results flushed to zero.

As a damped tube comes to rest, its velocities and the small components of its positions decay
through the subnormal range of float32 (below 1.18e-38), where x86 cores take microcode assists
that make each operation on them about a hundred times slower. Warp runs a CPU kernel on the
thread that launches it, so one launch of :func:`flush_subnormals_kernel` on the CPU sets that
thread's mode for every later kernel it runs (and for any other floating-point code on it).

On x86-64 it sets flush-to-zero (FTZ, MXCSR bit 15): a result that would be subnormal comes out
as 0, so none is ever stored and none is read back. Denormals-are-zero (DAZ, bit 6: subnormal
operands read as 0) is left off: FTZ alone removes the slowdown, and DAZ breaks host code on the
same thread (SciPy 1.17's ``cKDTree``, which the contact monitor uses, segfaults under it building
a tree of points with coordinates at exactly 0). AArch64's FPCR.FZ flushes operands as well as
results, like DAZ, so it is left alone, as are other architectures and CUDA (whose cores take
subnormals at full speed): there the kernel changes nothing.

The snippet uses compiler built-ins only (no headers), so it compiles with Warp's CPU compiler
(Clang) and NVRTC alike.
"""

from __future__ import annotations

import warp as wp

__all__ = ["flush_subnormals", "flush_subnormals_kernel"]

_FLUSH_SNIPPET = """
#if defined(__CUDA_ARCH__)
    return 0;
#elif defined(__x86_64__) || defined(_M_X64)
    __builtin_ia32_ldmxcsr(__builtin_ia32_stmxcsr() | 0x8000u);
    return (__builtin_ia32_stmxcsr() & 0x8000u) ? 1 : 0;
#else
    return 0;
#endif
"""


@wp.func_native(_FLUSH_SNIPPET)
def flush_subnormals() -> int:
    """Set flush-to-zero on the calling CPU thread (x86-64).

    Returns 1 if the mode is now on, 0 where it is not set (CUDA, other architectures).
    """


@wp.kernel(enable_backward=False)
def flush_subnormals_kernel(applied_out: wp.array[wp.int32]):
    """Launched once on the CPU with ``dim=1``: flushes subnormals on the launching thread.

    ``applied_out`` shape (1,): 1 if the mode is on after the launch, else 0.
    """
    applied_out[0] = flush_subnormals()
