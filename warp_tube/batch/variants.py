"""Variants of a scene: a table's rows crossed with the scene's USD variantSets, each read into a
validated :class:`~warp_tube.scene.spec.Scene`.

The scene is opened once. For each combination of variant selections, and then for each table
row, the selections and the row's values are authored in the stage's session layer (the
strongest layer: a value there replaces the attribute's value and any time samples of the scene's
layers), and the scene is read again through :class:`~warp_tube.scene.usd.SceneReader`, which
re-reads only the prims the table overrides (and the tubes below them, and forces on them). A
table that sets only tubes' scalar parameters and forces' vectors makes its variants from the
base scene instead (:mod:`warp_tube.batch.fastread`), reading the stage only for a row whose
values the reader would refuse or warn about. Each ``warptube:`` column is first checked against
the kind of prim it sets (:mod:`warp_tube.batch.kinds`), which the partial reads do not. Every
cell is parsed and every variant read before anything is simulated; all problems found are
reported together, each naming the row, the column and what is wrong; what a row's values are
warned of is said once, naming the first row (:mod:`warp_tube.batch.warned`).
"""

from __future__ import annotations

import itertools
import logging
from collections.abc import Sequence
from dataclasses import dataclass, replace
from itertools import repeat
from operator import itemgetter
from typing import NamedTuple

import numpy as np

from ..scene.attributes import attributes_of
from ..scene.spec import Scene, SceneError
from .fastread import PlainColumns, PlainRow, may_be_plain, plain_scenes
from .kinds import check_kinds
from .warned import HeldWarnings, merged_warnings, say_warnings, warn_same_choices, warned_where
from .table import Table
from .values import CONTRACT_TYPES, parse_plain, parse_plain_array, parse_value

log = logging.getLogger(__name__)

__all__ = ["VariantSetAxis", "Variant", "Variants", "find_variant_sets", "select_variant_sets", "prepare_variants",
           "collect_variants", "raise_problems", "plain_table", "say_warnings", "merged_warnings"]

#: at most this many problems are listed in one message
MAX_PROBLEMS = 10

_ELEMENT_DTYPES = {
    "int": np.int32, "uint": np.uint32, "int64": np.int64, "uint64": np.uint64, "uchar": np.uint8,
    "half": np.float16, "float": np.float32, "double": np.float64, "bool": np.bool_,
}  # fmt: skip


@dataclass(frozen=True)
class VariantSetAxis:
    """One USD variantSet expanded: the prim holding it, its name and its variants, in order."""

    prim: str
    name: str
    choices: tuple[str, ...]

    @property
    def label(self) -> str:
        """``/PRIM{SET}``: the summary's column for it."""
        return f"{self.prim}{{{self.name}}}"


class Variant(NamedTuple):
    """One variant of the batch (a named tuple: one per variant, made faster than a frozen dataclass).

    Attributes:
        index: its place in the batch (table row major, variant selections minor).
        name: ``variant_00000``...
        row: its table row, or None without a table.
        cells: the row's cells (empty without a table).
        selection: the chosen variant of each expanded variantSet.
        source: the variant's validated scene, or for a variant made by plain values its
            :class:`~warp_tube.batch.fastread.PlainRow` (the scene made when first asked for).
    """

    index: int
    name: str
    row: int | None
    cells: tuple[str, ...]
    selection: tuple[str, ...]
    source: Scene | PlainRow

    @property
    def scene(self) -> Scene:
        """The variant's validated scene."""
        s = self.source
        return s.scene if type(s) is PlainRow else s


SOURCE = itemgetter(5)  # (Variant.source)


@dataclass(frozen=True)
class Variants:
    """Every variant of a batch, in batch order, with what they were made from."""

    scene_path: str
    table: Table | None
    axes: tuple[VariantSetAxis, ...]
    variants: tuple[Variant, ...]
    #: every variant made from the one base scene by plain values (:mod:`warp_tube.batch.fastread`):
    #: they differ in tube materials and force vectors only, their layout and geometry the base's
    plain: bool = False
    #: what reading variants warned of (and reading the scene alone did not): (message, the first
    #: variant's index, where it is named, how many variants; a column's: -1, None, 1), said by
    #: :func:`~warp_tube.batch.warned.say_warnings`
    warnings: tuple = ()

    def __len__(self) -> int:
        return len(self.variants)

    def scenes(self, indices) -> Sequence[Scene]:
        """The scenes of the variants at ``indices`` (batch indices, in their order): where they
        were all made by plain values from one table read, a
        :class:`~warp_tube.batch.fastread.PlainScenes` (each made when asked for, the columns at
        hand), else a list."""
        sources = list(map(SOURCE, map(self.variants.__getitem__, indices)))
        return plain_scenes(sources) or [s.scene if type(s) is PlainRow else s for s in sources]

    def parameter_columns(self) -> list[str]:
        """The summary's parameter columns: the table's headers, then ``/PRIM{SET}`` per axis."""
        cols = [c.header for c in self.table.columns] if self.table is not None else []
        return cols + [a.label for a in self.axes]


def find_variant_sets(stage) -> list[VariantSetAxis]:
    """The variantSets of the stage's prims (as composed with their current selections)."""
    out = []
    for prim in stage.Traverse():
        sets = prim.GetVariantSets()
        for name in sets.GetNames():
            choices = tuple(sets.GetVariantSet(name).GetVariantNames())
            if choices:
                out.append(VariantSetAxis(prim=str(prim.GetPath()), name=name, choices=choices))
    return out


def _authored_in(stage, axis: VariantSetAxis) -> set[str]:
    """``PRIM_PATH.ATTRIBUTE`` of every attribute some variant of ``axis`` authors."""
    out: set[str] = set()
    for spec in stage.GetPrimAtPath(axis.prim).GetPrimStack():
        if axis.name not in spec.variantSets:
            continue
        for variant in spec.variantSets[axis.name].variantList:
            todo = [(variant.primSpec, axis.prim)]
            while todo:
                prim_spec, path = todo.pop()
                out.update(f"{path}.{a.name}" for a in prim_spec.attributes)
                todo += [(child, f"{path}/{child.name}".replace("//", "/")) for child in prim_spec.nameChildren]
    return out


def _warn_overridden(stage, axes: list[VariantSetAxis], table: Table) -> None:
    """Warn of table columns that set an attribute a crossed variantSet also sets: the table's
    value wins in every combination, so the variantSet's choices give the same scenes."""
    for axis in axes:
        authored = _authored_in(stage, axis)
        both = [col.target for col in table.columns if col.target in authored]
        if both:
            log.warning("%s: column(s) %s set what variantSet %s sets: the table's value wins in every one of its %d "
                        "choices", table.path, ", ".join(both), axis.label, len(axis.choices))  # fmt: skip


def select_variant_sets(axes: list[VariantSetAxis], spec: str, scene_path: str) -> list[VariantSetAxis]:
    """The axes named by ``spec``: ``all``, or a comma-separated list of ``SET`` or ``/PRIM{SET}``.

    Raises:
        SceneError: a name that matches no variantSet, or a ``SET`` held by several prims.
    """
    found = ", ".join(a.label for a in axes) or "none"
    if spec.strip() == "all":
        if not axes:
            raise SceneError(f"--variant-sets all: {scene_path} has no variantSets")
        return list(axes)
    out = []
    for item in (s.strip() for s in spec.split(",")):
        if not item:
            continue
        if item.startswith("/"):
            match = [a for a in axes if a.label == item]
        else:
            match = [a for a in axes if a.name == item]
            if len(match) > 1:
                raise SceneError(f"--variant-sets {item}: held by several prims ({', '.join(a.label for a in match)}): "
                                 "name one as /PRIM{SET}")  # fmt: skip
        if not match:
            raise SceneError(f"--variant-sets {item}: no such variantSet in {scene_path} (found: {found})")
        if match[0] not in out:
            out.append(match[0])
    if not out:
        raise SceneError(f"--variant-sets {spec!r}: expected all, or SET or /PRIM{{SET}} names (found: {found})")
    return out


def name_width(count: int) -> int:
    """Digits of the variants' names (``variant_00000``): at least 5."""
    return max(5, len(str(count - 1)))


def _usd_value(value, type_name: str):
    """A parsed cell as ``UsdAttribute.Set`` takes it for ``type_name``."""
    if not isinstance(value, np.ndarray):
        return value
    from pxr import Sdf

    base = type_name[:-2]
    elem = base if base in _ELEMENT_DTYPES else {"f": "float", "d": "double", "h": "half"}.get(base[-1], None)
    if elem is None:  # int2, float3, double4, half2 ...
        elem = base.rstrip("234")
    cls = Sdf.ValueTypeNames.Find(type_name).type.pythonClass
    return cls.FromNumpy(np.ascontiguousarray(value, dtype=_ELEMENT_DTYPES[elem]))


def _targets(stage, table: Table, columns) -> list:
    """Per column (prim path, or None for a Mesh; attribute; USD type name), as PlainColumns takes them."""
    return [(None if _is_mesh(stage, col.prim) else col.prim, col.attribute, type_name)
            for col, (_, type_name, _) in zip(table.columns, columns)]  # fmt: skip


def _is_mesh(stage, path: str) -> bool:
    """Whether the prim at ``path`` is a Mesh (a tube extracted when read: read it again)."""
    from pxr import UsdGeom

    prim = stage.GetPrimAtPath(path)
    return bool(prim) and prim.IsA(UsdGeom.Mesh)


def _in_instances(table: Table, columns) -> list[str]:
    """Per column whose prim lies inside an instance (which usd-core does not edit), a problem:
    such a column can be taken only by rows made from the base scene (fastread)."""
    out = []
    for col, (attr, _, _) in zip(table.columns, columns):
        prim = attr.GetPrim() if attr is not None else None
        if prim is None or not prim.IsInstanceProxy():
            continue
        holder = prim.GetParent()
        while holder and not holder.IsInstance():
            holder = holder.GetParent()
        out.append(f"{table.path}: column {col.header}: {col.prim} lies inside the instance {holder.GetPath()}, which "
                   f"usd-core does not edit (plain values of warptube: parameters and forces are taken; these rows' are "
                   f"not): make {holder.GetPath()} not instanceable in the scene")  # fmt: skip
    return out


def _did_you_mean(name: str, choices: list[str]) -> str:
    """`` (did you mean X?)`` for the closest of ``choices`` to a mistyped ``name``, or ""."""
    import difflib

    close = difflib.get_close_matches(name, choices, n=1, cutoff=0.75)
    return f" (did you mean {close[0]}?)" if close else ""


def _scene_prims_hint(stage, most: int = 6) -> str:
    """`` (the scene's warp_tube prims: /World/Bowel, /World/Push)``: the prims of the stage that
    hold ``warptube:`` attributes or are curves (at most ``most`` named), or ""."""
    from pxr import UsdGeom

    found = [str(p.GetPath()) for p in stage.Traverse()
             if p.IsA(UsdGeom.BasisCurves) or any(n.startswith("warptube:") for n in p.GetPropertyNames())]  # fmt: skip
    if not found:
        return ""
    more = f", ... ({len(found)} in all)" if len(found) > most else ""
    return f" (the scene's warp_tube prims: {', '.join(found[:most])}{more})"


def _resolve_columns(stage, table: Table, context: str, ignored=frozenset()):
    """Per column: the attribute to author and its USD type name (or a problem message); for the
    columns in ``ignored`` (the reader would ignore them) no attribute, none being authored."""
    from pxr import Sdf

    out = []
    for k, col in enumerate(table.columns):
        prim = stage.GetPrimAtPath(col.prim)
        if not prim:
            paths = [str(p.GetPath()) for p in stage.Traverse()]
            hint = _did_you_mean(col.prim, paths) or _scene_prims_hint(stage)
            out.append((None, None, f"{table.path}: column {col.header}: no prim {col.prim} in {context}{hint}"))
            continue
        if col.attribute == "widths" and prim.GetAttribute("primvars:widths").HasAuthoredValue():
            out.append((None, None, f"{table.path}: column {col.header}: {col.prim} authors primvars:widths, which "
                                    f"takes precedence over widths: name the column {col.prim}.primvars:widths"))  # fmt: skip
            continue
        if prim.GetRelationship(col.attribute):
            out.append((None, None, f"{table.path}: column {col.header}: {col.prim}.{col.attribute} is a relationship: "
                                    "a table sets attributes only (a variantSet can change a relationship)"))  # fmt: skip
            continue
        attr = prim.GetAttribute(col.attribute)
        if attr and attr.GetTypeName():
            out.append((None if k in ignored else attr, str(attr.GetTypeName()), None))
        elif k in ignored and col.attribute in CONTRACT_TYPES:
            out.append((None, CONTRACT_TYPES[col.attribute], None))
        elif col.attribute in CONTRACT_TYPES:
            t = CONTRACT_TYPES[col.attribute]
            out.append((prim.CreateAttribute(col.attribute, Sdf.ValueTypeNames.Find(t)), t, None))
        else:
            names = list(prim.GetPropertyNames()) + sorted(attributes_of(prim))
            out.append((None, None, f"{table.path}: column {col.header}: {col.prim} has no attribute {col.attribute} "
                                    f"in {context} (and it is not a warptube: scene attribute)"
                                    f"{_did_you_mean(col.attribute, names)}"))  # fmt: skip
    return out


def prepare_variants(scene_path: str, table: Table | None = None, variant_sets: str | None = None, extract=None,
                     progress=None) -> Variants:  # fmt: skip
    """Read every variant of a batch, checking everything before anything runs.

    Args, Raises: as :func:`collect_variants`, which this runs and whose problems it raises.
    """
    variants, problems = collect_variants(scene_path, table, variant_sets, extract, progress)
    raise_problems(problems)
    return variants


def plain_table(table: Table | None) -> bool:
    """Whether ``table``'s columns may all be read as plain values (:func:`~warp_tube.batch.fastread.may_be_plain`,
    no file column), judged without reading the scene: what deciding how many processes read the
    table needs. Whether each row is read that way is decided when it is read."""
    return table is not None and all(not c.files and may_be_plain(c.attribute) for c in table.columns)


def raise_problems(problems: list) -> None:
    """Raise one SceneError listing ``problems`` ((row, message) pairs) in row order, if any; a
    problem found again (a cell's, in each variantSet combination) is listed once."""
    if problems:
        problems = sorted(dict.fromkeys(problems), key=lambda p: p[0])
        head = [msg for _, msg in problems[:MAX_PROBLEMS]]
        more = f"\n  ... and {len(problems) - MAX_PROBLEMS} more" if len(problems) > MAX_PROBLEMS else ""
        raise SceneError(f"{len(problems)} problem(s) in the variants; nothing was run:\n  " + "\n  ".join(head) + more)


def collect_variants(scene_path: str, table: Table | None = None, variant_sets: str | None = None, extract=None,
                     progress=None, say: bool = True) -> tuple[Variants, list]:  # fmt: skip
    """Read every variant of a batch (or of a part of its table), collecting the problems.

    Args:
        scene_path: the scene file.
        table: the variants table, or None (then ``variant_sets`` alone makes the variants).
        variant_sets: ``all``, a comma-separated list of ``SET`` / ``/PRIM{SET}``, or None.
        extract: the extraction hook for ``Mesh`` tubes (as :func:`warp_tube.scene.usd.load_scene`).
        progress: None, or a callable taking the number of variants read so far.
        say: say what reading the variants warned of (:func:`say_warnings`); else it is only kept
            in the variants' ``warnings``.

    Returns:
        The variants (None where a variant has a problem) and the problems, (row or -1, message)
        pairs, each message naming the row (and line), the column and the problem.

    Raises:
        SceneError: the scene itself is invalid, or the request is (``variant_sets``, no table).
    """
    held = HeldWarnings()  # a scene's warning once, not once per variant; a variant's naming it
    reader_log = logging.getLogger("warp_tube.scene.usd")
    reader_log.addFilter(held)
    try:
        variants, problems = _collect(scene_path, table, variant_sets, extract, progress, held)
    finally:
        reader_log.removeFilter(held)
    variants = replace(variants, warnings=tuple((m, *h) for m, h in held.held.items()))
    if say:
        say_warnings(variants)
    return variants, problems


def _plain_scenes(plain: PlainColumns, table: Table, columns) -> list:
    """Per row of ``table``, its variant made from the base scene by ``plain`` (all rows at
    once: a :class:`~warp_tube.batch.fastread.PlainRow`), or None where the row must go through the stage (a cell not written plainly, or one
    the reader would refuse or warn about: that path parses it again and names the problem)."""
    parsed, whole = [], 0
    for j, (col, (_, type_name, _)) in enumerate(zip(table.columns, columns)):
        values = None if col.files else parse_plain_array([cells[j] for cells in table.rows], type_name)
        if values is not None:  # (every cell plain: read as one column, an array)
            parsed.append(values)
            whole += 1
            continue
        cache: dict = {}
        values = []
        for cells in table.rows:
            text = cells[j]
            v = cache.get(text)
            if v is None and text not in cache:
                v = cache[text] = None if col.files else parse_plain(text, type_name)
            values.append(v)
        parsed.append(values)
    if whole == len(parsed):
        rows = list(range(len(table.rows)))
    else:
        rows = [r for r in range(len(table.rows)) if all(col[r] is not None for col in parsed)]
    if not rows:
        return [None] * len(table.rows)
    if len(rows) < len(table.rows):
        parsed = [col[rows] if isinstance(col, np.ndarray) else [col[r] for r in rows] for col in parsed]
    made = plain.rows(parsed)
    out: list = [None] * len(table.rows)
    for r, scene in zip(rows, made):
        out[r] = scene
    return out


def _made_variants(out: list, made: list, table: Table, combo: tuple, c: int, combos: int, width: int, done: int,
                   progress) -> int:  # fmt: skip
    """The variants of variant selection ``combo`` (the ``c``-th of ``combos``) into ``out`` where
    every row of ``table`` was made from the base scene (``made``, per row): what the row-by-row
    loop of :func:`_collect` gives them (a row equal to an earlier one: the earlier one's scene), in
    one pass. Returns, and says to ``progress`` as that loop does, the variants done."""
    rows = table.rows
    n = len(rows)
    first = dict(zip(reversed(rows), range(n - 1, -1, -1)))  # a row's cells -> the first row with them
    firsts = list(map(first.__getitem__, rows))
    numbers = range(table.first_row, table.first_row + n)
    indices = range(table.first_row * combos + c, (table.first_row + n) * combos + c, combos)
    names = map(f"variant_%0{width}d".__mod__, indices)
    # (each a Variant made as Variant._make makes it)
    out[c::combos] = map(tuple.__new__, repeat(Variant),
                         zip(indices, names, numbers, rows, repeat(combo), map(made.__getitem__, firsts)))  # fmt: skip
    if progress is not None:
        for i in range(1023 - done % 1024, n, 1024):  # (a row equal to an earlier one is not said)
            if firsts[i] == i:
                progress(done + i + 1)
    return done + n


def _collect(scene_path, table, variant_sets, extract, progress, held):
    from pxr import Usd

    from ..scene.usd import SceneReader, open_stage

    if table is None and not variant_sets:
        raise SceneError("nothing to vary: give --variants TABLE, --variant-sets, or both")
    stage = open_stage(scene_path)
    reader = SceneReader(stage, scene_path, extract)
    try:
        reader.read()  # the scene as it is must be valid, unless its variantSets are expanded
    except SceneError:
        if not variant_sets:
            raise
        # without a selection it may be incomplete (a set without a default): each combination is read below
    axes = select_variant_sets(find_variant_sets(stage), variant_sets, scene_path) if variant_sets else []
    if table is not None and axes and table.first_row == 0:  # (once, not per part of the table)
        _warn_overridden(stage, axes, table)
    combos = list(itertools.product(*[a.choices for a in axes]))
    bases: dict = {}  # each combination's scene, as read with no table row
    n_rows = len(table.rows) if table is not None else 1
    total_rows = (table.first_row + n_rows) if table is not None else 1
    width = name_width(total_rows * len(combos))
    stage.SetEditTarget(Usd.EditTarget(stage.GetSessionLayer()))
    out: list = [None] * (n_rows * len(combos))
    problems: list[tuple[int, str]] = []  # (row or -1, message)
    files: dict = {}
    made = None  # per row its variant made from the base scene (plain values), or None
    parsed_cache: dict = {}
    done = 0
    for c, combo in enumerate(combos):
        for axis, choice in zip(axes, combo):
            stage.GetPrimAtPath(axis.prim).GetVariantSet(axis.name).SetVariantSelection(choice)
        chosen = ", ".join(f"{a.label} = {ch}" for a, ch in zip(axes, combo))
        context = f"{scene_path}" + (f" with {chosen}" if chosen else "")
        try:
            base = reader.read()
        except SceneError as e:
            problems.append((-1, f"{context}: {e}" if chosen else str(e)))
            continue
        bases[combo] = base
        if table is None:
            out[c] = Variant(index=c, name=f"variant_{c:0{width}d}", row=None, cells=(), selection=combo, source=base)
            done += 1
            continue
        kinds = check_kinds(stage, table)
        for msg in kinds.warnings:  # (a column's: said as it is, once)
            held.add(msg, -1, None, 1)
        columns = _resolve_columns(stage, table, context, kinds.ignored)
        bad_cols = kinds.problems + [msg for _, _, msg in columns if msg]
        if bad_cols:
            problems += [(-1, msg) for msg in bad_cols]
            if kinds.problems:  # (columns of the wrong kind: the same in every combination)
                break
            continue
        changed = None if kinds.full else sorted({col.prim for k, col in enumerate(table.columns) if k not in kinds.ignored})
        plain = PlainColumns.of(base, _targets(stage, table, columns))
        made = _plain_scenes(plain, table, columns) if plain is not None else None
        if made is None or any(m is None for m in made):  # rows authored in the stage
            inside = _in_instances(table, columns)
            if inside:
                problems += [(-1, f"{msg} ({context})") for msg in inside]
                continue
        if made is not None and all(m is not None for m in made):  # every row made from the base scene
            done = _made_variants(out, made, table, combo, c, len(combos), width, done, progress)
            continue
        seen_rows: dict = {}
        row_warnings: dict = {}  # a row's cells -> what reading its variant warned of
        folder = table.folder
        for r, cells in enumerate(table.rows, start=table.first_row):
            here = (r - table.first_row) * len(combos) + c  # in this (part of the) table
            index = r * len(combos) + c  # in the batch
            name = f"variant_{index:0{width}d}"
            if cells in seen_rows:  # the same values as an earlier row: the same scene
                out[here] = Variant(index, name, r, cells, combo, seen_rows[cells])
                for msg in row_warnings.get(cells, ()):  # (and the same warnings)
                    held.add(msg, index, warned_where(table, r, chosen, msg), 1)
                done += 1
                continue
            if made is not None and made[r - table.first_row] is not None:  # plain values, made from the base scene
                seen_rows[cells] = scene = made[r - table.first_row]
                out[here] = Variant(index, name, r, cells, combo, scene)
                done += 1
                if progress is not None and done % 1024 == 0:
                    progress(done)
                continue
            values, ok = [], True
            for col, (attr, type_name, _), text in zip(table.columns, columns, cells):
                key = (type_name, col.files, text)
                try:
                    if key not in parsed_cache:
                        parsed_cache[key] = _usd_value(
                            parse_value(text, type_name, folder=folder, is_file=col.files, files=files), type_name)
                    values.append((attr, parsed_cache[key]))
                except ValueError as e:
                    problems.append((r, f"{table.where(r, col)}: {e}"))
                    ok = False
            if not ok:
                continue
            scene = plain.scene([v for _, v in values]) if plain is not None else None
            if scene is not None:  # made from the base scene: no need to read the stage
                seen_rows[cells] = scene
                out[here] = Variant(index, name, r, cells, combo, scene)
                done += 1
                if progress is not None:
                    progress(done)
                continue
            for attr, value in values:
                if attr is not None and not attr.Set(value):
                    problems.append((r, f"{table.where(r)}: {attr.GetPath()}: usd-core refused the value"))
                    ok = False
            if not ok:
                continue
            given = held.reading(index, lambda msg: warned_where(table, r, chosen, msg))
            try:
                scene = reader.read(changed=changed)
            except SceneError as e:
                msg = str(e)
                col = next((col for col in table.columns if col.target in msg), None)
                if col is None and ".curveVertexCounts:" in msg:  # the row's points, counted against the scene's curves
                    col = next((col for col in table.columns if col.attribute == "points" and f"{col.prim}.curveVertexCounts" in msg), None)
                    if col is not None:
                        msg += f" (the row's {col.header} gives another point count: set {col.prim}.curveVertexCounts in the table too)"
                problems.append((r, f"{table.where(r, col)}{' with ' + chosen if chosen else ''}: {msg}"))
                continue
            finally:
                held.reading(None)
            row_warnings[cells] = given
            seen_rows[cells] = scene
            out[here] = Variant(index, name, r, cells, combo, scene)
            done += 1
            if progress is not None:
                progress(done)
        if len(problems) > 10 * MAX_PROBLEMS:
            break
    if table is None or table.first_row == 0:  # (once, not per part of the table)
        warn_same_choices(axes, bases)
    plain = not axes and table is not None and made is not None and all(m is not None for m in made) and not problems
    return Variants(scene_path=scene_path, table=table, axes=tuple(axes), variants=tuple(out), plain=plain), problems
