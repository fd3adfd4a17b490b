"""Compile options shared by the kernel modules."""

#: Module options of the CUDA-facing kernels (each compiled with ``module="unique"``): fast
#: approximate division and square root on CUDA. Warp's CPU compiler ignores the option, so CPU
#: results do not depend on it.
CUDA_OPTIONS = {"fast_math": True}
