"""A Ctrl-C that lands in a finalizer (which Python drops) is raised at the next check
(warp_tube.runtime.interrupts)."""

import os
import signal
import time

import pytest

from warp_tube.runtime.interrupts import held_interrupts, kept_interrupts, raise_if_interrupted


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


def test_an_interrupt_during_an_import_is_raised_once_the_module_is_in(tmp_path, monkeypatch):
    """usd-core's import, cut by a Ctrl-C, left its bindings half registered (a later call failed
    with "No to_python converter", or the command ran on): import_whole holds the interrupt until
    the module is whole, then raises it."""
    import sys

    from warp_tube.runtime.interrupts import import_whole

    (tmp_path / "slow_to_import.py").write_text(
        "import os, signal, time\n"
        "os.kill(os.getpid(), signal.SIGINT)\n"
        "for _ in range(100):\n    time.sleep(0.001)\n"
        "WHOLE = True\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(KeyboardInterrupt):
        import_whole("slow_to_import")
    assert sys.modules["slow_to_import"].WHOLE
    del sys.modules["slow_to_import"]


def test_a_ctrl_c_in_a_held_block_is_raised_at_its_end():
    """A run counts and writes each frame in such a block: the frame is finished before the
    interrupt stops the run."""
    finished = []
    with kept_interrupts():
        with pytest.raises(KeyboardInterrupt):
            with held_interrupts():
                os.kill(os.getpid(), signal.SIGINT)
                for _ in range(100):  # the handler runs here, and only notes the signal
                    time.sleep(0.001)
                finished.append(True)
        assert finished == [True]
        raise_if_interrupted()  # raised once: nothing pending now
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
