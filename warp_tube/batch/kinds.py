"""A table's ``warptube:`` columns checked against the kind of prim each sets (tube, force,
simulation settings), as the scene reader checks a scene's prims.

A batch reads a row again only for the prims its columns set (the reader's partial read), which
does not check what kind of prim carries what: a tube's attribute on the settings prim, or a
setting on a tube, would be authored and never read, and each variant run as the scene. So each
column is checked here, before anything runs, against what the reader takes for that prim's kind
(:func:`~warp_tube.scene.attributes.kind_of`, its lists of attributes per kind).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from ..scene.attributes import FORCE_ATTRS, KNOWN_ATTRS, SETTINGS_ATTRS, TARGET, ignored_hint, kind_of, taken

__all__ = ["ColumnKinds", "check_kinds"]


@dataclass
class ColumnKinds:
    """What :func:`check_kinds` found.

    Attributes:
        problems: per column the reader would refuse, a message naming it.
        warnings: per column the reader would ignore (a tube's attribute on a prim of no kind),
            the warning, naming it.
        ignored: those columns' indices: their values are checked, not authored.
        full: a column makes a prim a tube or the settings prim: rows are read whole (the partial
            read re-reads only the prims the scene had of each kind).
    """

    problems: list = field(default_factory=list)
    warnings: list = field(default_factory=list)
    ignored: set = field(default_factory=set)
    full: bool = False


def _scene_names(prim, session) -> set:
    """The ``warptube:`` attributes ``prim`` carries in the scene: not in the session layer, where
    the batch authors its rows."""
    return {a.GetName() for a in prim.GetAttributes() if a.GetName().startswith("warptube:")
            and any(spec.layer != session for spec in a.GetPropertyStack())}  # fmt: skip


def _settings_prims(stage, session, other_than: str) -> list[str]:
    """The scene's simulation settings prims other than ``other_than``."""
    from pxr import Usd

    return [str(p.GetPath()) for p in stage.Traverse(Usd.TraverseInstanceProxies(Usd.PrimDefaultPredicate))
            if str(p.GetPath()) != other_than and _scene_names(p, session) & set(SETTINGS_ATTRS)]  # fmt: skip


def check_kinds(stage, table) -> ColumnKinds:
    """Check ``table``'s columns of ``warptube:`` scene attributes against their prims' kinds in ``stage`` (a prim of
    no kind in the scene takes the kind the columns give it, as the reader would); columns whose
    prim is missing are left to the caller."""
    session = stage.GetSessionLayer()
    by_prim: dict = {}
    for k, col in enumerate(table.columns):
        if col.attribute in KNOWN_ATTRS:  # (an unknown name is the caller's: no such attribute)
            by_prim.setdefault(col.prim, []).append((k, col))
    out = ColumnKinds()
    for path, cols in by_prim.items():
        prim = stage.GetPrimAtPath(path)
        if not prim:
            continue
        names = _scene_names(prim, session)
        kind = kind_of(prim, names)
        new = kind is None
        if new:
            kind = kind_of(prim, names | {col.attribute for _, col in cols})
        if kind is None:  # as the reader's not_simulated: a force's attributes refused, a tube's ignored
            for k, col in cols:
                if col.attribute in FORCE_ATTRS:
                    out.problems.append(f"{table.path}: column {col.header}: {path} has no {TARGET} relationship, so "
                                        f"it is no force: a force prim names its tube with rel {TARGET} = "
                                        "</PATH/TO/TUBE>")  # fmt: skip
                    continue
                out.warnings.append(f"{table.path}: column {col.header}: {path} (a {prim.GetTypeName() or 'typeless'} "
                                    f"prim) is not a tube, force or settings prim: its values are ignored "
                                    f"({ignored_hint(prim)})")  # fmt: skip
                out.ignored.add(k)
            continue
        label, known = kind
        for _, col in cols:
            if col.attribute not in known:
                out.problems.append(f"{table.path}: column {col.header}: {path} is a {label} prim, which takes "
                                    f"{taken(known)}: not {col.attribute}")  # fmt: skip
        if new:
            out.full = True
            others = _settings_prims(stage, session, path) if label == "simulation settings" else []
            if others:
                col = next(col for _, col in cols if col.attribute in SETTINGS_ATTRS)
                out.problems.append(f"{table.path}: column {col.header}: the scene's simulation settings prim is "
                                    f"{others[0]}: set {col.attribute} there (one prim carries the settings)")  # fmt: skip
    return out
