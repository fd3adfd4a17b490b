"""The ``warptube:`` attributes each kind of scene prim takes, and the check that a prim carries
no other (a misspelling, or an attribute of another kind of prim, is an error naming it)."""

from __future__ import annotations

import difflib

from .spec import SceneError

__all__ = ["SETTINGS_ATTRS", "TUBE_ATTRS", "FORCE_ATTRS", "MESH_ATTRS", "KNOWN_ATTRS", "check_names"]

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


def check_names(path: str, prim, names: list, known: set, kind: str) -> None:
    """A ``warptube:`` attribute of ``prim`` that is not one of ``known`` (a ``kind`` prim's) is a
    mistake (a misspelling, or an attribute of another kind of prim): an error naming it, with the
    nearest known name."""
    for name in names:
        if name in known:
            continue
        if name in KNOWN_ATTRS:
            what = f"not an attribute of a {kind} prim"
        else:
            near = difflib.get_close_matches(name, sorted(known), n=1)
            what = "unknown attribute" + (f": did you mean {near[0]}?" if near else "")
        takes = ", ".join(sorted(n.split(":")[1] for n in known))
        raise SceneError(f"{path}: {prim.GetPath()}.{name}: {what} (a {kind} prim takes {takes})")
