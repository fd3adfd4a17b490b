"""Copying device arrays back to the host into reused page-locked buffers.

On a CUDA device, ``wp.array.numpy()`` allocates fresh pageable host memory for every copy: the
copy runs at pageable speed and every frame's new pages are faulted in again. A
:class:`HostMirror` keeps ``slots`` page-locked host arrays of one device array's shape and copies
into them in turn (``slots=2`` keeps the previous frame's copy readable while the next one lands).
On the CPU the device array is already host memory and :meth:`HostMirror.fetch` returns its view.
"""

from __future__ import annotations

import numpy as np
import warp as wp

__all__ = ["HostMirror"]


class HostMirror:
    """Reused host copies of device arrays of one shape and dtype.

    Args:
        like: a device array whose shape and dtype the copies take.
        slots: host buffers used in turn (1, or 2 to keep the previous copy while fetching the next).
    """

    def __init__(self, like: wp.array, slots: int = 1):
        self.on_host = not like.device.is_cuda
        self.bufs = [] if self.on_host else [wp.empty(like.shape, dtype=like.dtype, device="cpu", pinned=True) for _ in range(slots)]
        self.turn = 0

    def fetch(self, src: wp.array) -> np.ndarray:
        """Start copying ``src`` into the next buffer and return the buffer's NumPy view; on CUDA the
        copy is asynchronous: synchronise the device before reading the view."""
        if self.on_host:
            return src.numpy()
        buf = self.bufs[self.turn]
        self.turn = (self.turn + 1) % len(self.bufs)
        wp.copy(buf, src)
        return buf.numpy()
