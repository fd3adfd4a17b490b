"""A Ctrl-C that lands in a finalizer (which Python drops) is raised at the next check
(warp_tube.runtime.interrupts)."""

import os
import signal
import time

import pytest

from warp_tube.runtime.interrupts import kept_interrupts, raise_if_interrupted


class Freed:
    def __del__(self):
        os.kill(os.getpid(), signal.SIGINT)
        for _ in range(200):  # the handler runs here, inside the finalizer, and its exception is dropped
            time.sleep(0.001)


@pytest.mark.filterwarnings("ignore::pytest.PytestUnraisableExceptionWarning")  # the drop this test makes happen
def test_a_ctrl_c_dropped_in_a_finalizer_is_raised_at_the_next_check():
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    with kept_interrupts():
        x = Freed()
        del x  # "Exception ignored in ... Freed.__del__": the interrupt is gone, but remembered
        with pytest.raises(KeyboardInterrupt):
            raise_if_interrupted()
        raise_if_interrupted()  # raised once: nothing pending now
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
