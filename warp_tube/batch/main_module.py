"""Whether a batch may start processes (its writers, its simulating workers, its table readers)
from the program that runs it.

The batch starts them with multiprocessing's ``forkserver`` or ``spawn`` methods
(:func:`~warp_tube.batch.writer_pool.writer_context`), which start each process by importing the
program's main module again, as ``__mp_main__`` (unless it is a package's ``__main__``, as for
``python -m warp_tube``): a script is run again in every process, all but its
``if __name__ == "__main__":`` block. Two programs cannot have that:

- a script read from stdin (``python - < script.py``, a here-document): there is no file to import,
  and each process fails on start (``FileNotFoundError: '<stdin>'``). The batch then does its work
  in its own process instead (:func:`may_start_processes` returns False);
- a script that calls :func:`~warp_tube.batch.run_batch` outside ``if __name__ == "__main__":``:
  each process would run the batch again. It is refused before any process starts, with one
  message naming the script's line.
"""

from __future__ import annotations

import ast
import logging
import os
import sys

from ..scene.spec import SceneError

log = logging.getLogger(__name__)

__all__ = ["may_start_processes", "main_script", "unguarded_line"]


def main_script() -> tuple[str | None, bool]:
    """The file a started process would run as its main module (None where it runs none: an
    interactive session, a notebook, ``python -c``, a package's ``__main__``), and whether that
    file can be read (False: a script read from stdin)."""
    main = sys.modules.get("__main__")
    name = getattr(getattr(main, "__spec__", None), "name", None)
    if name is not None and (name == "__main__" or name.endswith(".__main__")):
        return None, True  # (multiprocessing does not import a package's __main__ again)
    path = getattr(main, "__file__", None)
    if path is None:
        return None, True
    if name is None and not os.path.isabs(path):
        import multiprocessing.process

        path = os.path.join(multiprocessing.process.ORIGINAL_DIR or os.getcwd(), path)
    return path, os.path.isfile(path)


def unguarded_line(path: str) -> int | None:
    """The line of the main script ``path`` that is running now (the call that led here) where it
    runs whether or not the script is the main module: a statement at the script's top level, or
    inside only ``with``, ``for`` and ``try`` blocks (no ``if``, which may be the guard); None
    where it is guarded, or cannot be told (a call from another thread, a script that cannot be
    read)."""
    main = sys.modules.get("__main__")
    frame, outer = sys._getframe(1), None
    while frame is not None:
        if frame.f_globals is getattr(main, "__dict__", None) and frame.f_code.co_name == "<module>":
            outer = frame
        frame = frame.f_back
    if outer is None or outer.f_lineno is None:
        return None
    line = outer.f_lineno
    try:
        import tokenize

        with tokenize.open(path) as f:
            body = ast.parse(f.read()).body
    except (OSError, SyntaxError, ValueError, UnicodeDecodeError):
        return None
    blocks = (ast.With, ast.AsyncWith, ast.For, ast.AsyncFor, ast.Try, *((ast.TryStar,) if hasattr(ast, "TryStar") else ()))
    while True:
        stmt = next((s for s in body if s.lineno <= line <= (s.end_lineno or s.lineno)), None)
        if stmt is None:
            return None
        if not isinstance(stmt, ast.stmt) or isinstance(stmt, (ast.If, ast.While, ast.Match, ast.FunctionDef,
                                                                ast.AsyncFunctionDef, ast.ClassDef)):  # fmt: skip
            return None
        if not isinstance(stmt, blocks):
            return line
        inner = [*stmt.body, *getattr(stmt, "finalbody", [])]  # (not else or except: they may not run)
        if not any(s.lineno <= line <= (s.end_lineno or s.lineno) for s in inner):
            return None
        body = inner


def may_start_processes(what: str, asked: bool, refuse: bool = True) -> bool:
    """Whether the batch may start its ``what`` processes ("writer", "worker", ...) from this
    program; False for a script read from stdin (then the batch does that work in its own process;
    a warning says so where the processes were ``asked`` for, by ``workers`` or ``writers``), and,
    without ``refuse``, for a script that calls the batch outside ``if __name__ == "__main__":``.

    Raises:
        SceneError: with ``refuse``, the main script calls the batch outside
            ``if __name__ == "__main__":``, so that each process would run it again.
    """
    path, readable = main_script()
    if path is None:
        return True
    if not readable:
        if asked:
            log.warning("run_batch: the script is read from stdin (%s), which the batch's %s processes cannot import: "
                        "their work is done in this process; save the script to a file to have them",
                        os.path.basename(path), what)  # fmt: skip
        return False
    line = unguarded_line(path)
    if line is not None and not refuse:
        return False
    if line is not None:
        raise SceneError(f'{path}, line {line}: run_batch is called outside if __name__ == "__main__": the batch\'s {what} '
                         "processes import this script and would run the batch again: call it under "
                         'if __name__ == "__main__": (or run it with workers=1 and writers=0, no processes)')  # fmt: skip
    return True
