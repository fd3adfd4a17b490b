"""Chosen worlds' rows of a batch's device arrays, read to the host and written back.

The assistant-line rule of a batch (:mod:`warp_tube.batch.control`) needs, in a frame, the
positions of the few worlds whose line is (re)built and writes only their lines. On CUDA the rows
are gathered into a compact array on the device and copied back through one page-locked buffer,
and written rows go up compact and are scattered by a kernel
(:mod:`warp_tube.kernels.rows`), instead of moving every world's arrays both ways; on the CPU the
arrays are host memory and NumPy indexes them directly. Either way the values move bit for bit.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ..kernels.rows import gather_rows_vec3, scatter_rows_float, scatter_rows_vec3

__all__ = ["WorldRows"]


class WorldRows:
    """Row access to world-major arrays (worlds, columns) of one device.

    Args:
        device: the arrays' Warp device.
        kernels: move rows through the gather and scatter kernels (default: on CUDA only; the
            CPU indexes its arrays in place).
    """

    def __init__(self, device, kernels: bool | None = None):
        self.device = wp.get_device(device)
        self.kernels = self.device.is_cuda if kernels is None else bool(kernels)
        self._staging = None  # page-locked vec3 buffer for rows read back (CUDA), grown as needed

    def take(self, arrays, rows: np.ndarray, start: int, stop: int) -> list[np.ndarray]:
        """Rows ``rows`` (world indices) and columns ``start:stop`` of each vec3 array of
        ``arrays``: NumPy float32 copies, shape (len(rows), stop - start, 3) each."""
        if not self.kernels:
            return [a.numpy()[rows, start:stop] for a in arrays]
        start, stop = int(start), int(stop)
        n, width = len(rows), stop - start
        size = n * width
        if self._staging is None or self._staging.shape[0] < len(arrays) * size:
            self._staging = wp.empty(max(len(arrays) * size, 1024), dtype=wp.vec3, device="cpu", pinned=self.device.is_cuda)
        r = wp.array(np.asarray(rows, dtype=np.int32), dtype=wp.int32, device=self.device)
        for j, a in enumerate(arrays):
            out = wp.empty((n, width), dtype=wp.vec3, device=self.device)
            wp.launch(gather_rows_vec3, dim=(n, width), inputs=[a, r, start], outputs=[out], device=self.device)
            wp.copy(self._staging, out.flatten(), dest_offset=j * size, count=size)
        if self.device.is_cuda:  # (the stream, not the device: frames copied back on another stream need not wait)
            wp.synchronize_stream(wp.get_stream(self.device))
        host = self._staging.numpy()
        return [host[j * size : (j + 1) * size].reshape(n, width, 3).copy() for j in range(len(arrays))]

    def put(self, rows: np.ndarray, writes) -> None:
        """Write ``values[:, src_start:src_start + width]`` into rows ``rows`` of ``array`` at
        columns ``start:start + width``, for each ``(array, start, values, src_start, width)`` of
        ``writes``; ``values`` float32, (len(rows), columns) for float arrays or (len(rows),
        columns, 3) for vec3 arrays. No row twice in ``rows``."""
        if not self.kernels:
            for a, start, values, src_start, width in writes:
                a.numpy()[rows, start : start + width] = values[:, src_start : src_start + width]
            return
        r = wp.array(np.asarray(rows, dtype=np.int32), dtype=wp.int32, device=self.device)
        for a, start, values, src_start, width in writes:
            start, src_start, width = int(start), int(src_start), int(width)
            kernel = scatter_rows_vec3 if a.dtype == wp.vec3 else scatter_rows_float
            src = wp.array(np.ascontiguousarray(values, dtype=np.float32), dtype=a.dtype, device=self.device)
            wp.launch(kernel, dim=(len(rows), width), inputs=[src, src_start, r, start], outputs=[a], device=self.device)
