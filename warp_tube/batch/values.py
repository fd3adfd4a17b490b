"""Table cells parsed to an attribute's USD type.

Syntax by type (``str(Sdf.ValueTypeName)``):

- real scalars (``double``, ``float``, ``half``): a number, ``1e5``;
- integer scalars (``int``, ``uint``, ``int64``, ``uint64``, ``uchar``): an integer;
- ``bool``: ``true``/``false`` (also ``1``/``0``, ``yes``/``no``);
- ``token``, ``string``: the text;
- vectors (``float3``, ``double3``, ``point3f``, ``vector3d``, ``color3f``, ``int2`` ...): the
  components separated by spaces or commas, optionally in parentheses: ``(0, 0.02, 0)``;
- arrays (``int[]``, ``float[]``, ``point3f[]`` ...): ``[1, 2, 3]`` or ``[(0, 0, 0), (1, 0, 0)]``,
  or ``@FILE`` (relative to the table): ``.npy`` (NumPy), ``.csv`` / ``.txt`` (numbers, one
  element per line), shaped (n,) or (n, components).

The value replaces the attribute's value and any time samples it had (the override is authored
as a default value in a stronger layer).
"""

from __future__ import annotations

import functools
import math
import os
import re
import warnings
from itertools import repeat

import numpy as np

__all__ = ["parse_value", "parse_plain", "parse_plain_column", "parse_plain_array", "CONTRACT_TYPES"]

REALS = ("double", "float", "half", "timecode")
#: the largest finite value of each real type (also by the suffix of point3f, color3h ...)
_REAL_MAX = {"double": 1.7976931348623157e308, "timecode": 1.7976931348623157e308, "float": 3.4028234663852886e38,
             "half": 65504.0, "d": 1.7976931348623157e308, "f": 3.4028234663852886e38, "h": 65504.0}  # fmt: skip
_INT_RANGES = {"int": (-(2**31), 2**31 - 1), "uint": (0, 2**32 - 1), "int64": (-(2**63), 2**63 - 1),
               "uint64": (0, 2**64 - 1), "uchar": (0, 255), "int2": (-(2**31), 2**31 - 1),
               "int3": (-(2**31), 2**31 - 1), "int4": (-(2**31), 2**31 - 1)}  # fmt: skip
_DIGIT = re.compile(r"\d")
_EMPTY_ARRAY = re.compile(r"^\s*(?:\[\s*\]|\(\s*\))\s*$")
_THOUSANDS = re.compile(r"^\s*[-+]?\d{1,3}(?:,\d{3})+\s*$")
_DECIMAL_COMMA = re.compile(r"^\s*[-+]?\d+,\d+(?:[eE][-+]?\d+)?\s*$")
_UNIT = re.compile(r"^\s*[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?\s*[A-Za-z%\u00b0\u00b5/]+[A-Za-z0-9/^*.\u00b2\u00b3]*\s*$")
INTS = ("int", "uint", "int64", "uint64", "uchar")
TEXTS = ("token", "string")
_VECTOR = re.compile(r"^(?:(half|float|double|int)([234])|(point|vector|normal|color|texCoord)([234])([hfd]))$")
_SPLIT = re.compile(r"[\s,;()\[\]]+")

#: USD types of the scene contract's attributes, used when the scene does not author one.
CONTRACT_TYPES = {
    "warptube:youngsModulus": "double", "warptube:stretchStiffness": "double", "warptube:bendStiffness": "double",
    "warptube:density": "double", "warptube:damping": "double", "warptube:springDamping": "double",
    "warptube:pinnedPoints": "int[]", "warptube:anchorPoints": "int[]", "warptube:anchorStiffness": "double",
    "warptube:spokes": "int", "warptube:spokeLengths": "float[]", "warptube:referenceNormal": "float3",
    "warptube:frames": "token", "warptube:caps": "bool", "warptube:timeStep": "double",
    "warptube:integrator": "token", "warptube:gravity": "float3", "warptube:point": "int",
    "warptube:force": "float3", "warptube:assistantLine": "bool",
}  # fmt: skip


@functools.lru_cache(maxsize=None)
def _shape(type_name: str):
    """(element kind, components, is_array) of a USD type name; kind in real, int, bool, text."""
    array = type_name.endswith("[]")
    base = type_name[:-2] if array else type_name
    if base in REALS:
        return "real", 1, array
    if base in INTS:
        return "int", 1, array
    if base == "bool":
        return "bool", 1, array
    if base in TEXTS and not array:
        return "text", 1, False
    m = _VECTOR.match(base)
    if m:
        if m.group(1):
            return ("int" if m.group(1) == "int" else "real"), int(m.group(2)), array
        return "real", int(m.group(4)), array
    return None, 0, array


@functools.lru_cache(maxsize=None)
def _describe(type_name: str) -> str:
    kind, n, array = _shape(type_name)
    if array:
        example = "[1, 2, 3]" if n == 1 else "[(0, 0, 0), (1, 0, 0)]" if n == 3 else f"[({', '.join(['0'] * n)}), ...]"
        return f"{'an' if type_name[0] in 'aeiou' else 'a'} {type_name} array, e.g. {example}, or @FILE (.npy, .csv, .txt)"
    if n > 1:
        return f"{n} numbers (a {type_name}), e.g. ({', '.join(['0'] * n)})"
    return {"real": f"a number (a {type_name})", "int": f"an integer (an {type_name})", "bool": "true or false",
            "text": f"a {type_name}"}[kind]  # fmt: skip


def _number(t: str, kind: str):
    """One token as an int (``int``: also ``8.0``, ``1e3``: a number with no fraction) or a float;
    None where it is not one."""
    try:
        return int(t) if kind == "int" else float(t)
    except ValueError:
        pass
    if kind != "int":
        return None
    try:
        x = float(t)
    except ValueError:
        return None
    return int(x) if math.isfinite(x) and x.is_integer() else None


def _numbers(text: str, kind: str):
    out = []
    for t in (t for t in _SPLIT.split(text) if t):
        x = _number(t, kind)
        if x is None:
            return None
        out.append(x)
    return out


def _check_range(text: str, nums: list, type_name: str) -> None:
    """Raise ValueError where ``nums`` (of cell ``text``) do not fit ``type_name``: a number beyond
    what the type holds (``1e400``, ``1e39`` for a float; ``inf`` written as such is left to the
    scene's checks), an integer beyond the integer type's range."""
    base = type_name[:-2] if type_name.endswith("[]") else type_name
    limits = _INT_RANGES.get(base)
    if limits is not None:
        bad = next((x for x in nums if not limits[0] <= x <= limits[1]), None)
        if bad is not None:
            raise ValueError(f"found {_shown(text)}: {bad} is beyond what {base} holds ({limits[0]} to {limits[1]})")
        return
    m = _VECTOR.match(base)
    real = base if base in REALS else (m.group(1) or {"h": "half", "f": "float", "d": "double"}[m.group(5)]) if m else "double"
    top = _REAL_MAX.get(real, _REAL_MAX["double"])
    if "inf" in text.lower() or "nan" in text.lower():
        return
    if any(not abs(x) <= top for x in nums):
        raise ValueError(f"found {_shown(text)}: beyond the largest {real} ({top:.6g})")


def _load_file(name: str, folder: str, files: dict):
    path = name if os.path.isabs(name) else os.path.join(folder, name)
    if path in files:
        return files[path]
    if os.path.isdir(path):
        raise ValueError(f"{path}: is a folder: expected a .npy, .csv or .txt file")
    if not os.path.isfile(path):
        raise ValueError(f"no such file {path}")
    ext = os.path.splitext(path)[1].lower()
    if ext not in (".npy", ".csv", ".txt"):
        raise ValueError(f"{path}: extension {ext or '(none)'}: expected .npy, .csv or .txt")
    try:
        if ext == ".npy":
            arr = np.load(path, allow_pickle=False)
        else:
            with open(path, encoding="utf-8-sig") as f:
                first = f.readline()
            delimiter = "," if "," in first else ";" if ";" in first else None
            names = _numbers(first, "real") is None and not _DIGIT.search(first)  # a line of column names: x,y,z
            with warnings.catch_warnings():  # (a file of no numbers is an empty array: no NumPy warning)
                warnings.simplefilter("ignore", UserWarning)
                arr = np.loadtxt(path, delimiter=delimiter, ndmin=1, encoding="utf-8-sig", skiprows=int(names))
    except Exception as e:  # a corrupt file raises what NumPy's reader raises
        if ext == ".npy":
            raise ValueError(f"{path}: not a readable .npy array (damaged, not NumPy's format, or Python objects)") from None
        why = (str(e).splitlines() or [type(e).__name__])[0].split(";")[0].rstrip(".")
        raise ValueError(f"{path}: not a readable array ({why}): expected numbers, one element per line") from None
    files[path] = arr
    return arr


#: types :func:`parse_plain` reads: scalars and 3-vectors of reals
_PLAIN_LENGTH = {"double": 1, "float": 1, "double3": 3, "float3": 3}


def _one_pair(t: str) -> bool:
    """Whether stripped cell ``t`` has no brackets or one pair around it: ``(...)`` or ``[...]``."""
    opened, closed = t.count("(") + t.count("["), t.count(")") + t.count("]")
    if opened == closed == 0:
        return True
    return opened == closed == 1 and ((t[0] == "(" and t[-1] == ")") or (t[0] == "[" and t[-1] == "]"))


def _depth(text: str) -> int | None:
    """How deep ``text``'s brackets nest (0: none), or None where they do not balance (a bracket
    closed by the other kind, or left open, or closed unopened)."""
    if not any(c in text for c in "()[]"):
        return 0
    stack, deepest = [], 0
    for c in text:
        if c in "([":
            stack.append(c)
            deepest = max(deepest, len(stack))
        elif c in ")]":
            if not stack or "([".index(stack.pop()) != ")]".index(c):
                return None
    return None if stack else deepest


#: a cell longer than this is shown cut in messages (a whole array pasted into a scalar column)
_SHOWN = 120


def _shown(text: str) -> str:
    return repr(text) if len(text) <= _SHOWN else f"{text[:_SHOWN]!r}... ({len(text):,} characters)"


def parse_plain(text: str, type_name: str):
    """:func:`parse_value`'s result for a real scalar (``double``, ``float``) or 3-vector
    (``double3``, ``float3``) cell written plainly (a number; three numbers separated by commas,
    optionally in parentheses or brackets), or None where :func:`parse_value` must decide
    (another type, a file, any other spelling, every malformed cell).

    Whatever it returns, :func:`parse_value` returns too (its tokens are split at the same
    characters and read by ``float``); it only skips the general path, for tables of many rows.
    """
    n = _PLAIN_LENGTH.get(type_name)
    if n is None or text.startswith("@") or not text.isascii():  # (float() reads other scripts' digits)
        return None
    try:
        if n == 1:
            x = float(text)
            return x if abs(x) <= _REAL_MAX[type_name] else None
        t = text.strip()
        if not _one_pair(t):
            return None
        parts = t.strip("()[]").split(",")
        if len(parts) != 3:
            return None
        out = (float(parts[0]), float(parts[1]), float(parts[2]))
    except ValueError:
        return None
    top = _REAL_MAX[type_name[:-1]]
    return out if all(abs(x) <= top for x in out) else None


def parse_plain_column(texts: list[str], type_name: str) -> list | None:
    """``[parse_plain(t, type_name) for t in texts]`` for a whole column at once, or None where
    some cell is not written plainly (the caller then parses cell by cell, as before): the same
    values, read by ``float`` from the same tokens, a few times faster for a column of thousands."""
    a = parse_plain_array(texts, type_name)
    if a is None:
        return None
    return a.tolist() if a.ndim == 1 else list(map(tuple, a.tolist()))


def _plain_triples(cells: list[str]) -> list[str] | None:
    """The stripped 3-vector cells without their brackets, or None where one has brackets
    :func:`parse_plain` does not take (:func:`_one_pair`): the column's bracket counts settle the
    usual cases (every cell in one pair of parentheses, or none) without a look at each cell."""
    joined = "".join(cells)
    if "[" not in joined and "]" not in joined:
        opened, closed = joined.count("("), joined.count(")")
        if opened == closed == 0:
            return cells
        # (one "(" and one ")" a cell, each cell's first and last: each cell is one pair)
        if opened == closed == len(cells) and all(map(str.startswith, cells, repeat("("))) \
                and all(map(str.endswith, cells, repeat(")"))):  # fmt: skip
            return [t[1:-1] for t in cells]
    if not all(map(_one_pair, cells)):
        return None
    return [t.strip("()[]") for t in cells]


def parse_plain_array(texts: list[str], type_name: str) -> np.ndarray | None:
    """:func:`parse_plain_column`'s values as one float64 array, (rows,) for a real scalar type,
    (rows, 3) for a 3-vector (its values' unit), or None where it gives None: a column taken whole
    without a Python number per cell."""
    n = _PLAIN_LENGTH.get(type_name)
    if n is None or not texts:
        return None
    joined = "".join(texts)
    if not joined.isascii() or ("@" in joined and any(t.startswith("@") for t in texts)):
        return None
    try:
        if n == 1:
            a = np.fromiter(map(float, texts), np.float64, len(texts))
            top = _REAL_MAX[type_name]
        else:
            inner = _plain_triples(list(map(str.strip, texts)))
            if inner is None or list(map(str.count, inner, repeat(","))).count(2) != len(inner):
                return None
            a = np.fromiter(map(float, ",".join(inner).split(",")), np.float64, 3 * len(inner)).reshape(-1, 3)
            top = _REAL_MAX[type_name[:-1]]
    except ValueError:
        return None
    if not (np.abs(a) <= top).all():  # (NaN too: parse_plain leaves those to parse_value)
        return None
    return a


def _why(text: str, kind: str, n: int, array: bool) -> str:
    """A hint for a cell that is not the number it should be: a decimal comma, a unit, a fraction."""
    if n == 1 and not array and _THOUSANDS.match(text):
        return " (numbers take a decimal point and no thousands separators, e.g. 100000 or 1.5)"
    if n == 1 and not array and _DECIMAL_COMMA.match(text):
        return f" (a decimal comma? write {text.strip().replace(',', '.')})"
    if _UNIT.match(text):
        return " (no units: the scene's units, SI for warptube: attributes)"
    return ""


def parse_value(text: str, type_name: str, *, folder: str = ".", is_file: bool = False, files: dict | None = None):
    """Parse one cell for an attribute of USD type ``type_name``.

    Args:
        text: the cell.
        type_name: the attribute's type, e.g. ``double``, ``float3``, ``point3f[]``.
        folder: where relative file names are found (the table's folder).
        is_file: the cell names a file whatever it looks like (a ``@`` column).
        files: a cache of arrays already loaded, by path.

    Returns:
        A value ``UsdAttribute.Set`` takes for that type: a Python number, bool or str, a tuple
        of numbers, or a NumPy array (arrays).

    Raises:
        ValueError: the cell does not parse; the message says what was found and what is expected.
    """
    files = {} if files is None else files
    kind, n, array = _shape(type_name)
    if kind is None:
        raise ValueError(f"attribute type {type_name} is not supported in a table")
    expected = _describe(type_name)
    if text == "":
        raise ValueError(f"empty cell: expected {expected}")
    if not (is_file or text.startswith("@")) and kind in ("real", "int"):
        if not text.isascii():
            raise ValueError(f"found {_shown(text)}: characters other than ASCII digits, signs and separators: expected "
                             f"{expected}")  # fmt: skip
        depth = _depth(text)
        if depth is None:
            raise ValueError(f"found {_shown(text)}: its brackets do not balance: expected {expected}")
        allowed = (1 if n > 1 else 0) + (1 if array else 0)
        if depth > allowed:
            raise ValueError(f"found {_shown(text)}: brackets nested {depth} deep: expected {expected}")
    if is_file or text.startswith("@"):
        if not array:
            raise ValueError(f"found {_shown(text)}: a file gives arrays; expected {expected}")
        arr = _load_file(text[1:].strip() if text.startswith("@") else text, folder, files)
        if arr.dtype.kind not in "biuf":
            raise ValueError(f"found {_shown(text)}: an array of {arr.dtype}: expected numbers")
        ok = (arr.ndim == 1 and (n == 1 or arr.size % n == 0)) or (arr.ndim == 2 and arr.shape[1] == n)
        if not ok:
            raise ValueError(f"found {_shown(text)}: an array of shape {arr.shape}: expected (n,) or (n, {n})")
        values = arr.reshape(-1, n) if n > 1 else arr.reshape(-1)
        if kind == "int":
            if not np.all(np.equal(np.mod(values, 1), 0)):
                raise ValueError(f"found {_shown(text)}: non-integer values: expected integers")
            return values.astype(np.int64)
        if kind == "bool":
            return values.astype(bool)
        return values.astype(np.float64)
    if kind == "text":
        return text
    if kind == "bool":
        low = text.lower()
        if low in ("true", "1", "yes"):
            return True
        if low in ("false", "0", "no"):
            return False
        raise ValueError(f"found {_shown(text)}: expected {expected}")
    if array and _EMPTY_ARRAY.match(text):  # [] or (): no elements
        return np.zeros((0, n) if n > 1 else 0, dtype=np.int64 if kind == "int" else np.float64)
    nums = _numbers(text, "int" if kind == "int" else "real")
    if nums is None or len(nums) == 0:
        raise ValueError(f"found {_shown(text)}: expected {expected}{_why(text, kind, n, array)}")
    if array:
        if len(nums) % n:
            raise ValueError(f"found {_shown(text)}: {len(nums)} numbers, not a multiple of {n}: expected {expected}")
        _check_range(text, nums, type_name)
        arr = np.asarray(nums, dtype=np.int64 if kind == "int" else np.float64)
        return arr.reshape(-1, n) if n > 1 else arr
    if len(nums) != n:
        raise ValueError(f"found {_shown(text)}: {len(nums)} number(s): expected {expected}{_why(text, kind, n, array)}")
    _check_range(text, nums, type_name)
    if n == 1:
        return nums[0]
    return tuple(nums)
