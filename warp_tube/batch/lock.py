"""One batch at a time in an output folder: ``DIR/.batch.lock``.

A batch takes the lock before it writes anything in its folder (the record of ``--resume``, stray
partial files removed, output arrays) and gives it back when it ends, however it ends. A second
batch into the same folder meanwhile, ``--resume`` included, is refused naming the process that
holds it, instead of the two writing over each other's files. A lock left by a batch that was
killed (its process no longer runs on this host) is taken over; one from another host, or one
that cannot be read, is reported with the file to remove if no batch is running.
"""

from __future__ import annotations

import json
import os
import socket
import time

from ..scene.spec import SceneError

__all__ = ["BatchLock", "LOCK_NAME"]

LOCK_NAME = ".batch.lock"
#: a lock file this old [s] that holds nothing readable was left by a process that died while
#: writing it
UNREADABLE_STALE_S = 10.0


class BatchLock:
    """The lock of ``out_dir`` (see the module docstring)."""

    def __init__(self, out_dir: str):
        self.out_dir = out_dir
        self.path = os.path.join(out_dir, LOCK_NAME)
        self.held = False

    def check(self) -> None:
        """Raise where another running batch holds the folder (nothing is taken).

        Raises:
            SceneError: naming the process and host that hold it.
        """
        owner = self._owner()
        if owner is not None:
            raise SceneError(self._message(owner))

    def acquire(self) -> None:
        """Take the lock (a stale one is taken over).

        Raises:
            SceneError: another running batch holds it.
        """
        for _ in range(3):
            try:
                fd = os.open(self.path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
            except FileExistsError:
                owner = self._owner()
                if owner is not None:
                    raise SceneError(self._message(owner)) from None
                try:
                    os.remove(self.path)  # stale: its batch no longer runs
                except FileNotFoundError:
                    pass
                continue
            with os.fdopen(fd, "w", encoding="utf-8") as f:
                json.dump({"pid": os.getpid(), "host": socket.gethostname(), "since": time.time()}, f)
            self.held = True
            return
        raise SceneError(f"{self.out_dir}: cannot take {self.path}: another batch is starting there")

    def release(self) -> None:
        """Give the lock back (nothing where it is not held)."""
        if self.held:
            self.held = False
            try:
                os.remove(self.path)
            except FileNotFoundError:
                pass

    def _owner(self) -> dict | None:
        """Who holds the lock, or None where nobody does (no file, or a stale one)."""
        try:
            with open(self.path, encoding="utf-8") as f:
                owner = json.load(f)
            pid, host = int(owner["pid"]), str(owner["host"])
        except FileNotFoundError:
            return None
        except (OSError, ValueError, KeyError, TypeError):
            try:
                age = time.time() - os.path.getmtime(self.path)
            except OSError:
                return None
            return None if age > UNREADABLE_STALE_S else {"pid": "?", "host": "?"}
        if host != socket.gethostname():
            return owner  # cannot tell from here whether it still runs
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return None  # its process is gone: stale
        except PermissionError:
            pass  # runs, as another user
        return owner

    def _message(self, owner: dict) -> str:
        return (f"{self.out_dir}: another batch is writing there (process {owner.get('pid')} on "
                f"{owner.get('host')}); wait for it to end, or, if none runs, remove {self.path}")  # fmt: skip
