"""What a batch has finished, kept in ``DIR/.batch`` so that ``--resume`` skips it.

``state.json`` holds the batch's signature (scene and table contents, options that change the
outputs, the chunk size); ``chunks/chunk_00003.json`` is written (atomically) when every output of
chunk 3 is complete, with its variants' summary fields. Resuming checks the signature and skips
the recorded chunks; chunks are planned the same way again, so the resumed batch ends with the
same files as an uninterrupted one. The folder is removed when the batch completes.
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

    def exists(self) -> bool:
        return os.path.exists(self.state_path)

    def begin(self, signature: dict, resume: bool) -> dict[int, dict]:
        """Start a new record, or (``resume``) check the old one's signature and return its
        finished chunks, ``{chunk id: record}``.

        Raises:
            SceneError: resuming a batch whose inputs or options differ (naming what differs).
        """
        if resume and self.exists():
            with open(self.state_path, encoding="utf-8") as f:
                old = json.load(f)
            differ = sorted(k for k in set(old) | set(signature) if old.get(k) != signature.get(k))
            if differ:
                raise SceneError(
                    f"{self.out_dir}: --resume: the batch there was made with other {', '.join(differ)}; "
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

    def remove(self) -> None:
        shutil.rmtree(self.dir, ignore_errors=True)

    @staticmethod
    def _atomic(path: str, data: dict) -> None:
        tmp = f"{path}.partial-{os.getpid()}"
        text = json.dumps(data)  # one string from the C encoder (json.dump encodes piece by piece in Python)
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(text)
        os.replace(tmp, path)
