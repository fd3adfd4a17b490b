"""What native libraries (Warp, usd-core) write straight to the process's stderr, caught.

Their C and C++ code writes to file descriptor 2, past Python's ``sys.stderr``; the text is C++
function names and line numbers that mean nothing to a user. :func:`native_stderr` points
descriptor 2 at a temporary file for the duration of a block, so the caller can say what went
wrong in the user's terms and pass on only what is useful.
"""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile

__all__ = ["native_stderr", "Captured"]


class Captured:
    """Text written to descriptor 2 inside :func:`native_stderr` (``text`` is set on exit)."""

    text: str = ""

    def lines(self) -> list[str]:
        return [line for line in self.text.splitlines() if line.strip()]


@contextlib.contextmanager
def native_stderr():
    """Capture what native code writes to stderr in the block (see the module docstring).

    Yields:
        a :class:`Captured` whose ``text`` holds the output after the block (also on an exception).
        Where descriptor 2 cannot be redirected, nothing is captured and the text stays empty.
    """
    out = Captured()
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError, AttributeError):
        yield out
        return
    with tempfile.TemporaryFile() as capture:
        os.dup2(capture.fileno(), 2)
        try:
            yield out
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            capture.seek(0)
            out.text = capture.read().decode("utf-8", errors="replace")
