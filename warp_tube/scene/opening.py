"""Opening a USD stage, with every failure as a :class:`~warp_tube.scene.spec.SceneError` in the
user's terms: the file, and the line and column of a syntax error, a damaged binary file, a file
that is not USD, or a sublayer, reference or payload that cannot be opened (and why)."""

from __future__ import annotations

import os
import re

from .files import not_a_file
from .spec import SceneError

__all__ = ["open_stage", "usd_error_in_user_terms"]


def open_stage(path: str):
    """Open a USD stage, turning every failure into a :class:`SceneError` naming the file and saying
    what is wrong in the user's terms (the line and column of a syntax error; a file that is not
    USD; a damaged binary file; a sublayer, reference or payload that cannot be opened).

    usd-core's own C++ diagnostics, written to stderr, are caught (see
    :mod:`warp_tube.runtime.native_output`) and not shown.
    """
    from pxr import Tf, Usd

    from ..runtime.native_output import native_stderr

    path = os.fspath(path)
    if not os.path.exists(path):
        raise SceneError(f"{path}: {not_a_file(path, 'a USD file')}")
    if os.path.isdir(path):
        raise SceneError(f"{path}: is a folder, expected a USD file (.usda, .usdc, .usd)")
    if not os.access(path, os.R_OK):
        raise SceneError(f"{path}: cannot be read (permission denied)")
    stage = None
    problem = None
    with native_stderr():
        try:
            stage = Usd.Stage.Open(path, Usd.Stage.LoadAll)
        except Tf.ErrorException as e:
            problem = _not_utf8(e, path) or usd_error_in_user_terms(path, str(e))
    if problem is not None:
        raise SceneError(f"{path}: {problem}")
    if stage is None:
        raise SceneError(f"{path}: not a readable USD stage")
    errors = [str(e) for e in stage.GetCompositionErrors()] if hasattr(stage, "GetCompositionErrors") else []
    if errors:
        more = f" (and {len(errors) - 1} more)" if len(errors) > 1 else ""
        raise SceneError(f"{path}: {_composition_error_in_user_terms(errors[0])}{more}")
    return stage


def _not_utf8(error, path: str) -> str | None:
    """None where usd-core's error text reads as UTF-8; else (it quotes a file that is not UTF-8)
    what is wrong in words: the first byte of ``path`` that is not UTF-8, or usd-core's text with
    such bytes replaced."""
    try:
        str(error)
        return None
    except UnicodeDecodeError:
        pass
    try:
        with open(path, "rb") as f:
            data = f.read()
        if data.startswith(b"#usda"):  # (a text file: a binary one is not UTF-8 throughout)
            data.decode("utf-8")
    except UnicodeDecodeError as e:
        line = data.count(b"\n", 0, e.start) + 1
        column = e.start - data.rfind(b"\n", 0, e.start)
        return (f"not UTF-8 text at byte {e.start} (0x{data[e.start]:02x}, line {line}, column {column}): a USD "
                "text file is UTF-8; save it as UTF-8")  # fmt: skip
    except OSError:
        pass
    parts = []
    for arg in error.args:
        text = getattr(arg, "commentary", None)
        if isinstance(text, bytes):
            text = text.decode("utf-8", errors="replace")
        parts.append(text if isinstance(text, str) else "a message that is not UTF-8 text")
    return f"cannot be opened: {'; '.join(parts) or 'a message that is not UTF-8 text'}"


_TF_MESSAGE = re.compile(r"Error in '[^']*' at line \d+ in file [^:]* : '(.*?)'\s*(?=\n\s*Error in|\Z)", re.S)
_SYNTAX = re.compile(r"^.*?:(\d+):(\d+):\s*(.*)$", re.S)


def usd_error_in_user_terms(path: str, text: str) -> str:
    """What usd-core's error text ``text`` for opening ``path`` means, without C++ locations."""
    messages = [m.strip() for m in _TF_MESSAGE.findall(text)] or [text.strip()]
    misnamed = _format_unlike_extension(path)
    if misnamed:
        return misnamed
    for m in messages:
        hit = _SYNTAX.match(m)
        if hit:
            line, col, what = hit.groups()
            what = re.sub(r"parse error matching \S*pegtl::internal::eof", "unexpected end of file (an unclosed bracket?)", what)
            what = re.sub(r"pxrInternal_\w+?__pxrReserved__:*|\S*pegtl::\S*", "", what).strip()
            return f"USD syntax error at line {line}, column {col}: {what}"
    try:
        with open(path, "rb") as f:
            head = f.read(16)
    except OSError as e:
        return f"cannot be read ({e.strerror})"
    if not head:
        return "empty file: expected a USD stage (a .usda text file starts with '#usda 1.0')"
    if head.startswith(b"PXR-USDC"):
        crate = [m for m in messages if "crate" in m.lower() or "bootstrap" in m.lower()]
        return f"damaged or truncated binary USD (.usdc) file ({(crate or messages)[0]})"
    if head.startswith(b"#usda"):
        return f"not a valid USD text file ({messages[0]})"
    if head.startswith(b"PK"):
        return f"not a readable USD package (.usdz) ({messages[0]})"
    printable = all(32 <= b < 127 or b in (9, 10, 13) for b in head)
    shown = repr(head.decode("ascii").splitlines()[0]) if printable else f"the bytes {head[:8].hex(' ')}"
    return (f"not a USD file: it starts with {shown}; a USD text file starts with '#usda 1.0' and a binary "
            "one with 'PXR-USDC'")  # fmt: skip


#: each format's first bytes, what it is, and the extensions usd-core reads it under
_FORMATS = ((b"PXR-USDC", "a binary USD (crate) file", (".usdc", ".usd")), (b"#usda", "a USD text file", (".usda", ".usd")),
            (b"PK\x03\x04", "a USD package (a zip archive)", (".usdz",)))  # fmt: skip


def _format_unlike_extension(path: str) -> str | None:
    """What is wrong where the file's format is not the one its extension names (usd-core picks the
    reader by the extension, and that reader's own error would call a sound file damaged)."""
    try:
        with open(path, "rb") as f:
            head = f.read(8)
    except OSError:
        return None
    ext = os.path.splitext(path)[1].lower()
    for magic, what, extensions in _FORMATS:
        if head.startswith(magic) and ext not in extensions:
            named = f"named {ext}" if ext else "without an extension"
            return f"{what} {named}: rename it {' or '.join(extensions)}"
    return None


def _composition_error_in_user_terms(message: str) -> str:
    """A composition error (missing sublayer, reference or payload) as a short sentence."""
    hit = re.search(r"Could not (?:open|load) (?:asset|sublayer) @([^@]*)@", message)
    if not hit:
        # one line, without the session layer usd-core names by its address (@anon:0x...@)
        text = re.sub(r",?@anon:0x[0-9a-f]+:[^@]*@", "", message)
        return "cannot be composed: " + re.sub(r"\s*\n\s*", " ", text).strip()
    what = "sublayer" if "sublayer" in message else "payload" if "payload" in message else "reference"
    where = re.search(r"@[^@]*@<([^>]*)>", message)
    at = f" (at {where.group(1)})" if where else ""
    asset = hit.group(1)
    reason = re.search(r" -- (.*?)\s*(?:; skipping)?\.?\s*$", message, re.S)
    if reason and os.path.isfile(asset):  # usd-core resolved it: the file is there, and says why it failed
        why = usd_error_in_user_terms(asset, reason.group(1))
    elif os.path.isabs(asset) and os.path.isfile(asset):
        why = "not a readable USD file"
    else:
        why = "no such file or not a USD file"
    return f"cannot open the {what} {asset}{at}: {why}"
