"""The ``warptube:`` attributes each kind of scene prim takes, and the check that a prim carries
no other (a misspelling, or an attribute of another kind of prim, is an error naming it)."""

from __future__ import annotations

import difflib
import logging
import os

from .spec import SceneError

__all__ = ["SETTINGS_ATTRS", "TUBE_ATTRS", "FORCE_ATTRS", "MESH_ATTRS", "KNOWN_ATTRS", "TARGET", "check_names",
           "check_relationships", "not_simulated", "not_defined", "undefined", "attributes_of", "samples_differ", "kind_of",
           "taken", "ignored_hint", "where", "missing"]

log = logging.getLogger("warp_tube.scene.usd")

#: the one ``warptube:`` relationship: a force prim's tube
TARGET = "warptube:target"

SETTINGS_ATTRS = ("warptube:timeStep", "warptube:integrator", "warptube:gravity")
TUBE_ATTRS = {
    "warptube:youngsModulus", "warptube:stretchStiffness", "warptube:bendStiffness", "warptube:density",
    "warptube:damping", "warptube:springDamping", "warptube:pinnedPoints", "warptube:anchorPoints",
    "warptube:anchorStiffness", "warptube:spokes", "warptube:spokeLengths", "warptube:referenceNormal",
    "warptube:frames", "warptube:caps",
}  # fmt: skip
FORCE_ATTRS = {"warptube:point", "warptube:force", "warptube:assistantLine"}
#: a Mesh given as a surface: its extraction settings and a tube's attributes
MESH_ATTRS = TUBE_ATTRS | {"warptube:extract", "warptube:hubs"}
KNOWN_ATTRS = TUBE_ATTRS | MESH_ATTRS | FORCE_ATTRS | set(SETTINGS_ATTRS)


def kind_of(prim, names) -> tuple[str, set] | None:
    """What the reader takes ``prim`` for, carrying the ``warptube:`` attributes ``names``: its kind
    (``force``, ``simulation settings``, ``tube``, ``Mesh tube``) and the attributes that kind
    takes; None for a prim of none of them (ignored, or with ``names`` warned of: :func:`not_simulated`)."""
    from pxr import UsdGeom

    if prim.GetRelationship(TARGET):
        return "force", FORCE_ATTRS
    # (a tube carrying a settings attribute by mistake is a tube: the mistake is named, not its own attributes)
    tube_like = any(n in TUBE_ATTRS for n in names) and (prim.IsA(UsdGeom.BasisCurves) or prim.IsA(UsdGeom.Mesh))
    if any(n in SETTINGS_ATTRS for n in names) and not tube_like:
        return "simulation settings", set(SETTINGS_ATTRS)
    if names and prim.IsA(UsdGeom.BasisCurves):
        return "tube", TUBE_ATTRS
    if "warptube:extract" in names and prim.IsA(UsdGeom.Mesh):
        return "Mesh tube", MESH_ATTRS
    return None


def taken(known) -> str:
    """``known`` attributes for a message: ``gravity, integrator, timeStep``."""
    return ", ".join(sorted(n.split(":")[1] for n in known))


def ignored_hint(prim) -> str:
    """Where a tube's attributes found on ``prim`` (no tube, force or settings prim) belong."""
    if prim.GetTypeName() == "Mesh":
        return "set warptube:extract = true on it to extract a tube from it"
    return "tube attributes belong on a linear BasisCurves prim (or a Mesh with warptube:extract = true)"


def _home(name: str) -> str:
    """The kind of prim that takes the known attribute ``name``, for a message."""
    if name in SETTINGS_ATTRS:
        return "the simulation settings prim (a Scope carrying gravity, integrator, timeStep)"
    if name in FORCE_ATTRS:
        return f"a force prim (one with rel {TARGET})"
    if name in TUBE_ATTRS:
        return "a tube prim (a linear BasisCurves, or a Mesh with warptube:extract = true)"
    return "a Mesh with warptube:extract = true"


def where(file: str, prim, name: str) -> str:
    """``file: /prim.name``, the head of a message about ``prim``'s property ``name``, with where its
    value is authored where that is not ``file``'s own layer at that path (a referenced file, a
    payload, a sublayer, a variant): ``(authored in asset.usda at /Asset/Tube.warptube:density)``."""
    head = f"{file}: {prim.GetPath()}.{name}"
    spec = _strongest_spec(prim, name)
    if spec is None:
        return head
    root = spec.layer == prim.GetStage().GetRootLayer()
    same = spec.path == prim.GetPath().AppendProperty(name)
    if (root and same) or (spec.layer.anonymous and not root):  # (an anonymous layer: values a program set)
        return head
    at = "" if same else f" at {spec.path}"
    return f"{head} (authored{at})" if root else f"{head} (authored in {_layer_name(spec.layer, file)}{at})"


def _strongest_spec(prim, name):
    """The spec whose value ``prim``'s property ``name`` takes (the strongest with a default or time
    samples; a relationship's strongest), or None where there is none."""
    prop = prim.GetProperty(name)
    if not prop:
        return None
    is_attribute = prim.HasAttribute(name)
    for spec in prop.GetPropertyStack():
        if not is_attribute or _has_value(spec):
            return spec
    return None


def _has_value(spec) -> bool:
    """Whether an attribute spec holds a value: a default or time samples in its layer."""
    return bool(spec.HasDefaultValue() or spec.layer.GetNumTimeSamplesForPath(spec.path))


def _layer_name(layer, file: str) -> str:
    """A layer's file for a message: relative to the folder of the scene ``file`` where it can be."""
    if not layer.realPath:
        return layer.identifier
    try:
        return os.path.relpath(layer.realPath, os.path.dirname(os.path.abspath(file)))
    except ValueError:  # (another drive)
        return layer.realPath


def missing(prim, names) -> str:
    """``missing`` for an unauthored attribute of ``prim`` (one of ``names``, which may each take its
    place), with why where a variantSet on ``prim`` or an ancestor has no selection (or selects a
    variant it does not have) while some of its variants author one of them: ``missing (variantSet "stiffness" on /World/Tube has no selection;
    its variants soft, stiff author it: select one)``."""
    p = prim
    while p and not p.IsPseudoRoot():
        sets = p.GetVariantSets()
        for vset in sets.GetNames():
            variants = sets.GetVariantSet(vset).GetVariantNames()
            chosen = sets.GetVariantSelection(vset)
            if chosen in variants:
                continue
            authors = [v for v in variants if _variant_authors(p, vset, v, prim, names)]
            if authors:
                its = f"its variants {', '.join(authors)} author it" if len(authors) > 1 else f"its variant {authors[0]} authors it"
                which = f'selects "{chosen}", which it does not have' if chosen else "has no selection"
                return f'missing (variantSet "{vset}" on {p.GetPath()} {which}; {its}: select one)'
        p = p.GetParent()
    return "missing"


def _variant_authors(holder, vset: str, variant: str, prim, names) -> bool:
    """Whether the variant ``variant`` of ``holder``'s variantSet ``vset`` authors a value of one of
    ``prim``'s attributes ``names`` (``prim`` is ``holder`` or below it)."""
    below = prim.GetPath().MakeRelativePath(holder.GetPath())
    for spec in holder.GetPrimStack():
        at = spec.path.AppendVariantSelection(vset, variant)
        at = at if below.pathString == "." else at.AppendPath(below)
        for name in names:
            a = spec.layer.GetAttributeAtPath(at.AppendProperty(name))
            if a and _has_value(a):
                return True
    return False


def check_names(path: str, prim, names: list, known: set, kind: str) -> None:
    """A ``warptube:`` attribute of ``prim`` that is not one of ``known`` (a ``kind`` prim's) is a
    mistake (a misspelling, or an attribute of another kind of prim): an error naming it, with the
    nearest known name."""
    for name in names:
        if name in known:
            continue
        if name in KNOWN_ATTRS:
            raise SceneError(f"{where(path, prim, name)}: not an attribute of a {kind} prim: it belongs on "
                             f"{_home(name)}")  # fmt: skip
        near = difflib.get_close_matches(name, sorted(known), n=1)
        what = "unknown attribute" + (f": did you mean {near[0]}?" if near else "")
        raise SceneError(f"{where(path, prim, name)}: {what} (a {kind} prim takes {taken(known)})")


def check_relationships(path: str, prim) -> None:
    """A ``warptube:`` relationship other than ``warptube:target`` is a mistake (a misspelled
    target would otherwise leave its force out without a word): an error naming it."""
    for rel in prim.GetRelationships():
        name = rel.GetName()
        if name.startswith("warptube:") and name != TARGET:
            raise SceneError(f"{where(path, prim, name)}: unknown relationship: did you mean {TARGET} "
                             "(a force's tube: rel warptube:target = </PATH/TO/TUBE>)?")  # fmt: skip


def check_namespace(path: str, prim, names) -> None:
    """An attribute in a namespace that reads as ``warptube`` but is spelled otherwise
    (``warpTube:``, ``WarpTube:``, ``warp_tube:``, ``warp-tube:``, also under ``primvars:``) is
    meant for the simulation, which would not see it (a tube left out, or its defaults taken,
    without a word): an error naming it, with the spelling to use."""
    for name in names:
        parts = name.split(":")
        k = 1 if parts[0] == "primvars" and len(parts) > 2 else 0
        space = parts[k]
        if len(parts) > k + 1 and space != "warptube" and space.lower().replace("_", "").replace("-", "") == "warptube":
            raise SceneError(f"{where(path, prim, name)}: the namespace is spelled warptube (all lower case, one "
                             f"word): author it as warptube:{':'.join(parts[k + 1:])}")  # fmt: skip


def not_simulated(path: str, prim, names: list) -> None:
    """``prim`` carries known ``warptube:`` attributes (``names``) but is no tube, force or
    settings prim: a force's attributes without its target are an error (the force would be left
    out without a word); a tube's on another kind of prim are ignored, with a warning saying why."""
    force = sorted(set(names) & FORCE_ATTRS)
    if force:
        raise SceneError(f"{path}: {prim.GetPath()}: {', '.join(force)} without a {TARGET} relationship: a force prim "
                         f"names its tube with rel {TARGET} = </PATH/TO/TUBE>")  # fmt: skip
    log.warning("%s: %s (a %s prim) carries %s but is not a tube, force or settings prim: ignored (%s)", path,
                prim.GetPath(), prim.GetTypeName() or "typeless", ", ".join(sorted(names)), ignored_hint(prim))


def undefined(prim) -> tuple[str, str]:
    """Why an undefined prim (``over`` only: no ``def`` of it, or of an ancestor, in any layer, so
    USD composes no prim there) is so, and what defines it: ("an `over` with no `def`", "it")."""
    overs, p = [], prim  # it and its ancestors without a def, innermost first
    while p and not p.IsPseudoRoot():
        if not p.HasDefiningSpecifier():
            overs.append(str(p.GetPath()))
        p = p.GetParent()
    if not overs or overs[0] != str(prim.GetPath()):  # a def under an over
        above = ", ".join(reversed(overs)) or "an ancestor"
        return f"under {above}, an `over` with no `def`", above
    if len(overs) == 1:
        return "an `over` with no `def`", "it"
    return f"an `over` with no `def`, as is its ancestor {', '.join(overs[1:])}", "them"


def not_defined(path: str, prim, names: list) -> None:
    """``prim`` carries ``warptube:`` attributes (``names``) but is not defined (an override whose
    path is mistyped, or an ``over`` written for a ``def``): ignored, with a warning saying why."""
    what, it = undefined(prim)
    parent = prim.GetParent()
    near = difflib.get_close_matches(prim.GetName(), [c.GetName() for c in parent.GetChildren()], n=1) if parent else []
    hint = f"a mistyped path? did you mean {parent.GetPath().AppendChild(near[0])}?" if near else f"define {it} with def"
    log.warning("%s: %s (%s) carries %s but is not a tube, force or settings prim: ignored (%s)", path,
                prim.GetPath(), what, ", ".join(sorted(names)), hint)


def attributes_of(prim) -> set:
    """The ``warptube:`` attributes a prim of ``prim``'s kind takes (what a mistyped name is
    matched against): a force's (it has a target), the settings', a tube's (a BasisCurves), a Mesh
    tube's, or any where the kind is not known."""
    from pxr import UsdGeom

    kind = kind_of(prim, prim.GetPropertyNames())  # (a BasisCurves has properties: a tube)
    if kind is not None:
        return kind[1]
    return MESH_ATTRS if prim.IsA(UsdGeom.Mesh) else KNOWN_ATTRS


def samples_differ(attr) -> bool:
    """Whether a USD attribute's time samples hold more than one value (DCC tools often write a
    constant as the same sample on every frame: that is no animation)."""
    if not attr.ValueMightBeTimeVarying():
        return False
    times = attr.GetTimeSamples()
    first = attr.Get(times[0]) if times else None
    return any(attr.Get(t) != first for t in times[1:])

