"""File safety shared by every stage that writes (scenes, extraction, outputs, exports): no input is written over, an existing output
is replaced only by a complete one, and unfinished work is kept under a name that says so.

- :func:`output_path` checks an output path before any work: extension, folder, not a folder,
  and not one of the command's inputs (compared as files: symbolic links, relative paths and hard
  links to an input are refused too), nor is its partial or temporary name.
- :func:`temp_path` is the hidden name a file is written under (same folder, so the final
  :func:`os.replace` is atomic); :func:`write_atomically` writes through it.
- :func:`partial_path` is where the finished part of an interrupted or failed run goes:
  ``OUT.partial.usdc`` beside ``OUT.usdc`` (:func:`free_partial_path`: ``OUT.partial-2.usdc``, ...
  where a file has that name already); the complete output at ``OUT.usdc`` is left alone.
- :func:`default_run_output` names a run's output when ``-o`` is not given, so that it can never be
  the scene itself.

Files are created with ``open``'s default mode, so the user's umask applies.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable

from .spec import SceneError

__all__ = [
    "USD_EXTENSIONS",
    "default_run_output",
    "output_path",
    "partial_path",
    "free_partial_path",
    "refuse_existing",
    "same_file",
    "temp_path",
    "usd_layer_files",
    "not_a_file",
    "write_atomically",
]

USD_EXTENSIONS = (".usdc", ".usda", ".usd")


def same_file(a, b) -> bool:
    """Whether paths ``a`` and ``b`` name the same file (after links; hard links included)."""
    a, b = os.fspath(a), os.fspath(b)
    if os.path.realpath(a) == os.path.realpath(b):
        return True
    try:
        return os.path.samefile(a, b)
    except OSError:  # one of them does not exist
        return False


def partial_path(path) -> str:
    """``dir/name.partial.ext`` for ``dir/name.ext``: where unfinished results go."""
    stem, ext = os.path.splitext(os.fspath(path))
    return f"{stem}.partial{ext}"


def free_partial_path(path) -> str:
    """:func:`partial_path` of ``path``, or where a file is there already (a user's, or an earlier
    run's partial result) the first free ``dir/name.partial-2.ext``, ``-3``, ...: never written over."""
    first = partial_path(path)
    if not os.path.lexists(first):
        return first
    stem, ext = os.path.splitext(first)
    k = 2
    while os.path.lexists(f"{stem}-{k}{ext}"):
        k += 1
    return f"{stem}-{k}{ext}"


def temp_path(path) -> str:
    """Hidden temporary name beside ``path`` (same folder and extension, process id in it)."""
    folder, name = os.path.split(os.fspath(path))
    stem, ext = os.path.splitext(name)
    return os.path.join(folder, f".{stem}.tmp-{os.getpid()}{ext}")


def output_path(path, extensions: Iterable[str], *, inputs: Iterable = (), what: str = "output") -> str:
    """Check an output path before any work is done; returns it absolute.

    Args:
        path: the output file.
        extensions: allowed extensions, lower case with the dot (e.g. ``(".usdc", ".usda")``).
        inputs: files the command reads; the output, its partial and its temporary name must be
            none of them.
        what: what the file is, for messages ("output", "scene", "PNG").

    Raises:
        SceneError: a wrong extension, a missing or read-only folder, a folder given as the file,
            or an input given as the output.
    """
    raw = os.fspath(path)
    if not raw:
        raise SceneError(f"an empty {what} name: expected a file name ({', '.join(extensions)})")
    path = os.path.abspath(raw)
    ext = os.path.splitext(path)[1].lower()
    extensions = tuple(extensions)
    if os.path.isdir(path):  # (before the extension: a folder is named as one)
        raise SceneError(f"{raw}: is a folder: expected a file name for the {what}, e.g. "
                         f"{os.path.join(raw, 'out' + extensions[0]) if extensions else raw}")  # fmt: skip
    if ext not in extensions:
        raise SceneError(f"{raw}: {what} extension {ext or '(none)'}: expected {', '.join(extensions)}")
    folder = os.path.dirname(path)
    if not os.path.isdir(folder):
        up = folder
        while up and not os.path.exists(up) and os.path.dirname(up) != up:
            up = os.path.dirname(up)
        if os.path.exists(up) and not os.path.isdir(up):
            raise SceneError(f"{raw}: cannot write the {what}: {up} is a file, not a folder")
        raise SceneError(f"{raw}: cannot write the {what}: folder {folder} does not exist")
    if not os.access(folder, os.W_OK):
        raise SceneError(f"{raw}: cannot write the {what}: folder {folder} is not writable")
    longest = _name_max(folder) - DERIVED_NAME_EXTRA
    if len(os.path.basename(path).encode()) > longest:
        raise SceneError(f"{raw}: a file name of {len(os.path.basename(path).encode())} bytes: expected at most {longest} "
                         f"(the {what} is written under a longer temporary name beside it first, and an unfinished "
                         f"one under NAME.partial{ext})")  # fmt: skip
    for src in inputs:
        for candidate, role in ((path, ""), (partial_path(path), " (its partial name)"), (temp_path(path), " (its temporary name)")):
            if same_file(candidate, src):
                raise SceneError(
                    f"{raw}: is the input {os.fspath(src)}{role}: refusing to write over an input; choose another {what} name"
                )
    return path


#: how much longer than an output's name the names written beside it may be: the temporary name
#: (".NAME.tmp-PID", twice where a staged file is itself written atomically) or "NAME.partial-K"
DERIVED_NAME_EXTRA = 28


def _name_max(folder: str) -> int:
    """The longest file name [bytes] the file system of ``folder`` takes (255 where not said)."""
    try:
        return int(os.pathconf(folder, "PC_NAME_MAX"))
    except (OSError, ValueError):
        return 255


def default_run_output(scene_path: str | None) -> str:
    """Output name of ``warp-tube run`` without ``-o``: ``<scene name>.out.usdc`` in the current
    folder (``tube.usdc`` for the embedded scene). It differs from the scene's own file name, so a
    run in the scene's folder cannot write over the scene."""
    if scene_path is None:
        return "tube.usdc"
    stem = os.path.splitext(os.path.basename(os.fspath(scene_path)))[0] or "scene"
    return f"{stem}.out.usdc"


def not_a_file(path: str, expected: str) -> str:
    """What is at ``path``, which is neither a folder nor a regular file, in words (``expected``:
    what it should be, e.g. "a mesh file"): a symbolic link loop, a link to nothing, a device, pipe or
    socket, or nothing."""
    import errno

    if os.path.islink(path):
        try:
            os.stat(path)
        except OSError as e:
            if e.errno == errno.ELOOP:
                return f"a symbolic link loop (the link leads back to itself): expected {expected}"
            return f"a symbolic link to {os.readlink(path)}, which does not exist"
    if os.path.exists(path):
        return f"not a regular file (a device, pipe or socket): expected {expected}"
    return "no such file"


def usd_layer_files(stage) -> list[str]:
    """Every local file an open USD stage reads or names: root layer, sublayers, references,
    payloads, and the files of asset-valued attributes (a texture, a linked file)."""
    from pxr import Sdf

    files = []
    for layer in stage.GetUsedLayers():
        real = layer.realPath
        if real and os.path.exists(real):
            files.append(real)
    assets = (Sdf.ValueTypeNames.Asset, Sdf.ValueTypeNames.AssetArray)
    for prim in stage.TraverseAll():
        for attr in prim.GetAuthoredAttributes():
            if attr.GetTypeName() in assets:
                value = attr.Get()
                for a in ([value] if isinstance(value, Sdf.AssetPath) else list(value or [])):
                    real = a.resolvedPath
                    if real and os.path.exists(real):
                        files.append(real)
    return files


def refuse_existing(paths: Iterable, *, flag: str = "--force") -> None:
    """SceneError naming the first of ``paths`` that exists (before anything is written)."""
    existing = [os.fspath(p) for p in paths if os.path.lexists(p)]
    if existing:
        more = f" (and {len(existing) - 1} more)" if len(existing) > 1 else ""
        raise SceneError(f"{existing[0]}: exists{more}: not replaced; pass {flag} to replace, or choose another -o")


def write_atomically(path, write: Callable[[str], object]) -> str:
    """Call ``write(tmp)`` to write the file under :func:`temp_path`, then rename it to ``path``.

    An existing file at ``path`` is replaced only when ``write`` returned; on any exception
    (interrupt included) the temporary file is removed and ``path`` is untouched.

    Raises:
        SceneError: the file cannot be written (the OS reason in the message).
    """
    path = os.fspath(path)
    tmp = temp_path(path)
    try:
        write(tmp)
        os.replace(tmp, path)
    except OSError as e:
        raise SceneError(f"{path}: cannot write ({e.strerror or e})") from None
    finally:
        if os.path.lexists(tmp):
            os.remove(tmp)
    return path
