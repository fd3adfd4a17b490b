"""What a batch has finished, kept in ``DIR/.batch`` so that ``--resume`` skips it.

``state.json`` holds the batch's signature (scene and table contents, options that change the
outputs, the chunk size); ``chunks/chunk_00003.json`` is written (atomically) when every output of
chunk 3 is complete, with its variants' lines of ``summary.csv`` and the summary fields the batch
reads back (index, status, reason, contact frame, outputs: one list per field, in the chunk's
order; :mod:`warp_tube.batch.bookkeeping`).
Resuming checks the signature and skips the recorded chunks; chunks are planned the same way
again, so the resumed batch ends with the same files as an uninterrupted one. The folder is removed when the batch completes, and its
signature kept in ``DIR/.batch-finished.json``, so that ``--resume`` of a finished batch with other
inputs or options is refused as for an unfinished one.
"""

from __future__ import annotations

import glob
import hashlib
import json
import os
import shutil

from ..scene.spec import SceneError

__all__ = ["Journal", "file_digest"]


def file_digest(path: str | None) -> str | None:
    """SHA-256 of a file's bytes (None for None)."""
    if path is None:
        return None
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


class Journal:
    """The record of a batch in ``out_dir/.batch``."""

    def __init__(self, out_dir: str):
        self.out_dir = out_dir
        self.dir = os.path.join(out_dir, ".batch")
        self.chunk_dir = os.path.join(self.dir, "chunks")
        self.state_path = os.path.join(self.dir, "state.json")
        self.signature: dict | None = None  # set by begin()

    def exists(self) -> bool:
        return os.path.exists(self.state_path)

    @property
    def finished_path(self) -> str:
        return os.path.join(self.out_dir, ".batch-finished.json")

    @staticmethod
    def _differ(old: dict, signature: dict, ignore=()) -> list[str]:
        """What differs, in words: ``table contents``, ``--frames (3 then, 4 now)`` ..."""
        keys = sorted(k for k in set(old) | set(signature) if k not in ignore and old.get(k) != signature.get(k))
        if "table" in keys and old.get("table_sha256") and old.get("table_sha256") == signature.get("table_sha256"):
            keys.remove("table")  # the same table moved or renamed: its contents (and the files it names) count
        if {"table", "table_sha256"} <= set(keys):  # another table: one item
            keys.remove("table_sha256")
        return [_what(k, old.get(k), signature.get(k)) for k in keys]

    def _read(self, path: str) -> dict:
        try:
            with open(path, encoding="utf-8") as f:
                data = json.load(f)
            if isinstance(data, dict):
                return data
        except (OSError, ValueError):
            pass
        raise SceneError(f"{self.out_dir}: --resume: {path} is damaged: the batch there cannot be resumed; "
                         "write to another folder")  # fmt: skip

    def check_finished(self, signature: dict) -> None:
        """For ``--resume`` of a batch that finished: refuse where it was made with other inputs
        or options (its chunk size aside: it does not change the outputs).

        Raises:
            SceneError: naming what differs.
        """
        if not os.path.exists(self.finished_path):
            return  # finished before its signature was kept: nothing to compare
        old = self._read(self.finished_path)
        differ = self._differ(old, signature, ignore=("chunk",))
        if differ:
            raise SceneError(
                f"{self.out_dir}: --resume: the batch there is finished and was made with other {'; '.join(differ)}; "
                "write to another folder"
            )

    def begin(self, signature: dict, resume: bool) -> dict[int, dict]:
        """Start a new record, or (``resume``) check the old one's signature and return its
        finished chunks, ``{chunk id: record}``.

        Raises:
            SceneError: resuming a batch whose inputs or options differ (naming what differs).
        """
        self.signature = signature
        if resume and self.exists():
            old = self._read(self.state_path)
            differ = self._differ(old, signature)
            if differ:
                raise SceneError(
                    f"{self.out_dir}: --resume: the batch there was made with other {'; '.join(differ)}; "
                    "resume with the same scene, table and options, or write to another folder"
                )
            done = {}
            for path in sorted(glob.glob(os.path.join(self.chunk_dir, "chunk_*.json"))):
                with open(path, encoding="utf-8") as f:
                    rec = json.load(f)
                done[int(rec["chunk"])] = rec
            return done
        os.makedirs(self.chunk_dir, exist_ok=True)
        self._atomic(self.state_path, signature)
        return {}

    def record(self, chunk: int, record: dict) -> None:
        """Mark chunk ``chunk`` finished (all its outputs complete)."""
        self._atomic(os.path.join(self.chunk_dir, f"chunk_{chunk:05d}.json"), dict(record, chunk=chunk))

    def finish(self) -> None:
        """The batch is complete: keep its signature (as :meth:`begin` had it) beside the outputs,
        remove the record."""
        self._atomic(self.finished_path, self.signature)
        try:  # the record first: a folder left half removed is then no unfinished batch
            os.remove(self.state_path)
        except FileNotFoundError:
            pass
        self.remove_leftover()

    def remove_leftover(self) -> None:
        """Remove the folder of a finished batch's record (what is left of it)."""
        shutil.rmtree(self.dir, ignore_errors=True)

    @staticmethod
    def _atomic(path: str, data: dict) -> None:
        tmp = f"{path}.partial-{os.getpid()}"
        text = json.dumps(data)  # one string from the C encoder (json.dump encodes piece by piece in Python)
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(text)
        os.replace(tmp, path)


#: a signature's entries in words
_NAMES = {"scene": "scene", "scene_sha256": "scene contents (the file changed)", "table": "table",
          "table_sha256": "table contents (the file changed)", "table_files": "files the table names",
          "scene_files": "layers and assets the scene uses",
          "variant_sets": "--variant-sets", "layout": "--layout", "every": "--every", "frames": "--frames",
          "surface": "Surface", "chunk": "--chunk", "variants": "number of variants",
          "version": "batch format"}  # fmt: skip


def _what(key: str, old, new) -> str:
    name = _NAMES.get(key, key)
    if key.endswith("sha256"):
        return name
    if key in ("table_files", "scene_files"):
        old, new = old or {}, new or {}
        changed = sorted(k for k in set(old) | set(new) if old.get(k) != new.get(k))
        return f"{name}: {', '.join(changed[:3])}{' ...' if len(changed) > 3 else ''} changed"
    if key == "surface":
        old, new = ("written" if x else "not written" for x in (old, new))
        return f"Surface ({old} then, {new} now: --no-surface, --surface-arrays)"
    return f"{name} ({old} then, {new} now)"
