"""Warp kernels and functions of warp_tube: pure functions of arrays (no pxr, no allocation, no I/O)."""
