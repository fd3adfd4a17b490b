"""The device's own time in stretches of a batch's launches, measured without waiting for them.

On a GPU a stretch is timed by two CUDA events recorded around its launches on the device's
stream, read once the host has waited for the stream anyway (:meth:`DeviceClock.settle`): the
seconds the device spent in the stretch, while the host went on queueing work or reading the
frame before. On the CPU, where a launch returns when done, a stretch is the host's time in it.
"""

from __future__ import annotations

import time

import warp as wp

__all__ = ["DeviceClock"]


class DeviceClock:
    """Seconds a device spends in stretches of launches (:meth:`start` ... :meth:`stop`).

    Args:
        device: the Warp device (name or device).

    Attributes:
        seconds: the stretches' time so far [s], counting those settled.
    """

    def __init__(self, device):
        self.device = wp.get_device(device)
        self.seconds = 0.0
        self._pending: list = []  # (start event, stop event) of stretches not yet read
        self._free: list = []  # events read and ready to be recorded again

    def _event(self):
        return self._free.pop() if self._free else wp.Event(self.device, enable_timing=True)

    def start(self):
        """Mark a stretch's start; returns the mark for :meth:`stop`."""
        if not self.device.is_cuda:
            return time.perf_counter()
        return wp.get_stream(self.device).record_event(self._event())

    def stop(self, mark) -> float:
        """End the stretch begun at ``mark``; returns the host's seconds in it on the CPU (the
        stretch's own), 0 on a GPU (where a later :meth:`settle` reads the device's)."""
        if not self.device.is_cuda:
            spent = time.perf_counter() - mark
            self.seconds += spent
            return spent
        self._pending.append((mark, wp.get_stream(self.device).record_event(self._event())))
        return 0.0

    def settle(self) -> None:
        """Add the stretches stopped so far; on a GPU, call once the host has waited for the
        device's stream past them."""
        for a, b in self._pending:
            self.seconds += 1e-3 * wp.get_event_elapsed_time(a, b, synchronize=False)
            self._free += (a, b)
        self._pending.clear()
