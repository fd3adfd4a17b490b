"""A process that makes a large batch's records (journal records and summary lines) beside it.

Formatting a chunk's summary fields (``repr`` of every number, the CSV writer, JSON) holds
Python's lock for about 6 us a variant; in the batch's process that time is taken from the
simulation, and on a thread it competes with the next chunk's build for the lock. A process of
its own takes them for the cost of pickling them (~1 us a variant).

The process is a plain ``python -c`` child (:mod:`subprocess`), not a :mod:`multiprocessing`
one: it does not import the batch's main module, so a script that calls ``run_batch`` outside
``if __name__ == "__main__":`` with the ``arrays`` layout (which has no writer processes) needs
no such guard for it. Requests (pickled) go to its standard input through a thread of this
process, replies (each chunk's summary lines, or an error) come back on its standard output to
another; Ctrl-C is left to the batch. Should the process stop, or not start, the records it had
not made are made here (:class:`~warp_tube.batch.bookkeeping.Bookkeeper`).
"""

from __future__ import annotations

import logging
import os
import pickle
import queue
import signal
import struct
import subprocess
import sys
import threading

__all__ = ["Recorder", "serve"]

log = logging.getLogger(__name__)

_HEADER = struct.Struct("<Q")  # the byte count of the pickle that follows


def _send(stream, data: bytes) -> None:
    stream.write(_HEADER.pack(len(data)))
    stream.write(data)
    stream.flush()


def _receive(stream) -> bytes | None:
    """The next message, or None at the end of the stream."""
    head = stream.read(_HEADER.size)
    if len(head) < _HEADER.size:
        return None
    (n,) = _HEADER.unpack(head)
    data = stream.read(n)
    return data if len(data) == n else None


def serve(reply_fd: int) -> None:
    """The child's loop: each request ``(key, function, args)`` run, its result or error sent
    back as ``(key, result, error)`` on file descriptor ``reply_fd``, until an empty request or
    the end of the input."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # (the batch stops it in order)
    inp, out = sys.stdin.buffer, os.fdopen(reply_fd, "wb")
    while True:
        data = _receive(inp)
        if not data:
            return
        key, function, args = pickle.loads(data)
        try:
            reply = (key, function(*args), None)
        except Exception as e:  # (reported to the batch, which makes the record itself)
            reply = (key, None, f"{type(e).__name__}: {e}")
        _send(out, pickle.dumps(reply, protocol=pickle.HIGHEST_PROTOCOL))


def _reap(proc: subprocess.Popen, timeout: float) -> None:
    """Wait for ``proc`` to end, killing it after ``timeout`` s."""
    try:
        proc.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()


class Recorder:
    """The child process and the two threads that talk to it.

    :meth:`submit` hands a call over and returns at once; :meth:`result` waits for its reply.
    ``broken`` is set when the process stopped (or could not start): every call not answered
    then has :meth:`result` raise :class:`RuntimeError`.
    """

    def __init__(self):
        root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
        # (replies on a copy of its standard output, which is then its standard error: anything
        # printed on importing cannot mix with them)
        code = (f"import os, sys; fd = os.dup(1); os.dup2(2, 1); sys.path.insert(0, {root!r}); "
                "from warp_tube.batch.recorder import serve; serve(fd)")  # fmt: skip
        self.replies: dict = {}
        self.done = threading.Condition()
        self.broken: str | None = None
        self._out: queue.SimpleQueue = queue.SimpleQueue()
        try:
            if not sys.executable:
                raise OSError("no Python executable to start (an embedded interpreter)")
            self.proc = subprocess.Popen([sys.executable, "-c", code], stdin=subprocess.PIPE, stdout=subprocess.PIPE)
        except (OSError, ValueError) as e:
            self.proc = None
            self.broken = f"it did not start ({e})"
            return
        threading.Thread(target=self._feed, name="batch-recorder-in", daemon=True).start()
        threading.Thread(target=self._read, name="batch-recorder-out", daemon=True).start()

    def submit(self, key, function, *args) -> None:
        """Have ``function(*args)`` run in the process (``function``: a module-level function)."""
        if self.broken is None:
            self._out.put(pickle.dumps((key, function, args), protocol=pickle.HIGHEST_PROTOCOL))

    def result(self, key):
        """The result of the call submitted as ``key``, once it is back.

        Raises:
            RuntimeError: the call failed in the process (its error named), or the process stopped."""
        with self.done:
            while key not in self.replies and self.broken is None:
                self.done.wait()
            if key not in self.replies:
                raise RuntimeError(f"the process making the batch's records stopped: {self.broken}")
            _, value, error = self.replies.pop(key)
        if error is not None:
            raise RuntimeError(error)
        return value

    def close(self, timeout: float = 60.0, wait: bool = True) -> None:
        """Let the process finish what it was given and stop (killed after ``timeout`` s).
        ``wait=False``: return at once and let a thread wait for its end (every result the
        caller needs is back: its own exit, ~0.07 s, need not be waited for)."""
        if self.proc is None:
            return
        self._out.put(b"")
        if not wait:
            threading.Thread(target=_reap, args=(self.proc, timeout), name="batch-recorder-end", daemon=True).start()
            return
        _reap(self.proc, timeout)

    def _feed(self) -> None:
        try:
            while True:
                data = self._out.get()
                _send(self.proc.stdin, data)  # (empty: the last)
                if not data:
                    self.proc.stdin.close()
                    return
        except (OSError, ValueError) as e:  # its input closed: it stopped
            self._stop(f"its input closed ({e})")

    def _read(self) -> None:
        while True:
            data = _receive(self.proc.stdout)
            if data is None:
                self._stop(f"it exited (status {self.proc.wait()})")
                return
            reply = pickle.loads(data)
            with self.done:
                self.replies[reply[0]] = reply
                self.done.notify_all()

    def _stop(self, why: str) -> None:
        with self.done:
            if self.broken is None:
                self.broken = why
            self.done.notify_all()
