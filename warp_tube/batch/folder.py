"""A batch's folder and inputs: what may be written where, what the batch's inputs are made of,
and what a batch being resumed left there.

- :func:`check_out_dir`: the folder can take the batch (or, resuming, holds one);
- :func:`check_inputs_not_outputs`: no input (the scene, its layers and assets, the table, files
  it names) is a file the batch would write;
- the files a batch depends on, with their contents' digests (:func:`named_files`,
  :func:`scene_files`), so that ``--resume`` sees a changed one;
- :func:`outputs_kept` and :func:`remove_stray_partials`: what is left of a batch being resumed;
- :func:`buffer_folder`: where chunks' arrays wait for the writers, and what batches killed before
  they could remove theirs left there.
"""

from __future__ import annotations

import logging
import os
import re
import shutil
import tempfile
from operator import itemgetter

from ..scene.spec import SceneError
from .journal import Journal, file_digest
from .lock import BatchLock

log = logging.getLogger(__name__)

__all__ = ["BATCH_FILES", "OUTPUT_NAME", "check_out_dir", "check_inputs_not_outputs", "named_paths", "named_files",
           "scene_dependencies", "scene_files", "outputs_kept", "remove_stray_partials", "buffer_folder"]

#: files a batch writes into its folder (an existing one means a batch is there already)
BATCH_FILES = ("summary.csv", "centerline.npy", "surface.npy", "surface_faces.npy", "arrays.json", "grid.usda",
               ".batch-finished.json")
#: names of the files a batch writes there, besides those
OUTPUT_NAME = re.compile(r"^(?:variant_\d+(?:\.partial(?:-\d+)?)?\.usdc|\.batch.*)$")


def check_out_dir(out_dir: str, resume: bool) -> None:
    """Refuse a batch folder that cannot take the batch: not a folder, not writable, under a
    missing folder, or (without ``resume``) holding a batch's outputs already; with ``resume``,
    one holding no batch."""
    parent = os.path.dirname(out_dir) or "."
    if os.path.exists(out_dir) and not os.path.isdir(out_dir):
        raise SceneError(f"{out_dir}: exists and is not a folder")
    if not os.path.isdir(out_dir):
        if resume:
            raise SceneError(f"{out_dir}: no such folder: nothing to resume")
        if not os.path.isdir(parent):
            raise SceneError(f"{out_dir}: folder {parent} does not exist")
        if not os.access(parent, os.W_OK):
            raise SceneError(f"{out_dir}: folder {parent} is not writable")
        return
    if not os.access(out_dir, os.W_OK):
        raise SceneError(f"{out_dir}: folder is not writable")
    BatchLock(out_dir).check()  # another batch writing there now: said before anything else
    journal = Journal(out_dir)
    found = [n for n in BATCH_FILES if os.path.exists(os.path.join(out_dir, n))]
    found += sorted(n for n in os.listdir(out_dir) if n.startswith("variant_") and OUTPUT_NAME.match(n))[:1]
    if resume:
        if not journal.exists() and not found:
            raise SceneError(f"{out_dir}: no batch there to resume")
    elif journal.exists() or found:
        what = ", ".join((["an unfinished batch (.batch)"] if journal.exists() else []) + found)
        if journal.exists() or ".batch-finished.json" in found:
            raise SceneError(f"{out_dir}: holds batch outputs already ({what}): --resume continues that batch; "
                             "or write to another folder")  # fmt: skip
        raise SceneError(f"{out_dir}: holds files named as a batch's outputs ({what}), which a batch would write over: "
                         "write to another folder (or --resume, if a batch wrote them)")  # fmt: skip


def check_inputs_not_outputs(out_dir: str, inputs) -> None:
    """Refuse an input (``(what, path)`` pairs: the scene, a layer or asset it uses, the table, a
    file the table names) that is, also through a link, a file the batch writes in ``out_dir``."""
    real_dir = os.path.realpath(out_dir)
    grid = os.path.join(real_dir, "grid")
    for what, path in inputs:
        if path is None:
            continue
        real = os.path.realpath(os.fspath(path))
        folder, name = os.path.split(real)
        written = folder == real_dir and (name in BATCH_FILES or OUTPUT_NAME.match(name))
        if written or folder == grid or folder.startswith(grid + os.sep) or folder.startswith(real_dir + os.sep + ".batch"):
            raise SceneError(f"{path}: {what} is in {out_dir} under a name the batch writes there ({name}): "
                             "move or rename it, or write the batch to another folder")  # fmt: skip


def named_paths(tab) -> dict[str, str]:
    """The files the table's cells name (``@`` columns, ``@FILE`` cells): name as written -> path."""
    names = set()
    for j, col in enumerate(tab.columns if tab is not None else ()):
        column = list(map(itemgetter(j), tab.rows))
        if not col.files and "@" not in "".join(column):  # (no cell names a file)
            continue
        for cell in column:
            if col.files or cell.startswith("@"):
                names.add(cell[1:].strip() if cell.startswith("@") else cell)
    return {name: name if os.path.isabs(name) else os.path.join(tab.folder, name) for name in sorted(names)}


def named_files(named: dict[str, str]) -> dict[str, str]:
    """The files the table names (:func:`named_paths`) with the SHA-256 of each file's bytes
    (None where there is none): a file changed between a batch and its ``--resume`` is seen."""
    return {name: file_digest(path) if os.path.isfile(path) else None for name, path in named.items()}


def scene_dependencies(scene: str) -> list[str]:
    """The files the scene brings in (sublayers, references, payloads, assets; not itself), as
    real paths; none where the scene cannot be read (its reading says why)."""
    from pxr import UsdUtils

    try:
        layers, assets, _ = UsdUtils.ComputeAllDependencies(os.fspath(scene))
    except Exception:  # (an unreadable scene)
        return []
    paths = {os.path.realpath(p) for p in [layer.realPath for layer in layers] + list(assets) if p}
    return sorted(paths - {os.path.realpath(scene)})


def scene_files(dependencies: list[str]) -> dict[str, str]:
    """The scene's files (:func:`scene_dependencies`) with the SHA-256 of each file's bytes: a
    layer changed between a batch and its ``--resume`` is seen."""
    return {p: file_digest(p) for p in dependencies if os.path.isfile(p)}


def outputs_kept(done: dict, layout: str, out_dir: str, work_dir: str) -> dict:
    """The finished chunks of a batch being resumed whose outputs are all still there; the others
    (a file deleted or moved since) are simulated again, with a warning naming the first."""
    if not done:
        return done
    if layout == "arrays":  # every chunk's frames are in the partial arrays
        path = os.path.join(work_dir, "centerline.npy")
        missing = {c: path for c in done} if not os.path.exists(path) else {}
    else:
        missing = {}
        for c, rec in done.items():
            names = [rec["layer"]] if layout == "grid" else rec["rows"]["output"]
            gone = next((n for n in names if n and not os.path.exists(os.path.join(out_dir, n))), None)
            if gone is not None:
                missing[c] = os.path.join(out_dir, gone)
    if missing:
        first = missing[min(missing)]
        log.warning("--resume: %s, written before, is missing: %d finished chunk(s) are simulated again",
                    first, len(missing))  # fmt: skip
    return {c: rec for c, rec in done.items() if c not in missing}


def remove_stray_partials(out_dir: str) -> None:
    """Remove partial and temporary files that an interrupted writer left (never a complete
    output): hidden ``.NAME.partial-*`` and ``.NAME.tmp-PID.EXT`` files
    (:func:`~warp_tube.scene.files.temp_path`) in the batch folder, which is the batch's own."""
    for folder in (out_dir, os.path.join(out_dir, "grid")):
        if os.path.isdir(folder):
            for n in os.listdir(folder):
                if n.startswith(".") and (".partial-" in n or ".tmp-" in n) and os.path.isfile(os.path.join(folder, n)):
                    os.remove(os.path.join(folder, n))


#: buffer folders in memory (/dev/shm) are named with this prefix and their batch's process id
SHM_PREFIX = "warp-tube-batch-"


def buffer_folder(chunk_bytes: int, work_dir: str, shm: str = "/dev/shm") -> str:
    """A new folder for chunks' arrays between simulation and writing: in ``shm`` (memory) when it
    has room for a few chunks, else in the batch's working folder. A batch removes its own when it
    ends, but one killed outright (SIGKILL, the system short of memory) cannot: folders in ``shm``
    of this user's batches whose process is gone are removed first, as they would hold memory until
    the machine restarts."""
    try:
        st = os.statvfs(shm)
        if os.access(shm, os.W_OK):
            _remove_orphaned_buffers(shm)
            if st.f_bavail * st.f_frsize > 4 * chunk_bytes:
                return tempfile.mkdtemp(prefix=f"{SHM_PREFIX}{os.getpid()}-", dir=shm)
    except OSError:
        pass
    return tempfile.mkdtemp(prefix="buffers-", dir=work_dir)


def _remove_orphaned_buffers(shm: str) -> None:
    """Remove ``shm``'s buffer folders of this user whose batch process no longer runs."""
    pattern = re.compile(rf"^{re.escape(SHM_PREFIX)}(\d+)-")
    for name in os.listdir(shm):
        m = pattern.match(name)
        path = os.path.join(shm, name)
        if m is None or not os.path.isdir(path) or os.stat(path).st_uid != os.getuid():
            continue
        try:
            os.kill(int(m.group(1)), 0)
        except ProcessLookupError:  # (gone; PermissionError: another user's live process)
            shutil.rmtree(path, ignore_errors=True)
            log.info("removed %s, left by a batch that was killed", path)
        except (OverflowError, OSError):
            continue
