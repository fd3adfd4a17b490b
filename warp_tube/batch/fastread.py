"""Variants made from the scene read once, for tables that set plain values only.

Most parameter studies vary a tube's material (Young's modulus, density, damping, ...) and the
forces' vectors. For such a table the variant scenes follow from the base scene without reading
the stage again: :class:`PlainColumns` replaces the parameters and force vectors in copies of the
base scene's specs (a few microseconds a row, against ~0.5 ms for authoring the row in the stage
and reading it through usd-core).

:meth:`PlainColumns.scenes` makes many rows at once, the values of each column checked as one
array (what a table of thousands of rows needs: a few microseconds a row in all);
:meth:`PlainColumns.scene` is one row of it.

It takes a row only where the result is certain to be what :class:`~warp_tube.scene.usd.SceneReader`
would read: values rounded as the attribute's type stores them (``float`` to float32), and every
check of the reader passed with no warning due. Any other row (a value the reader would refuse or
warn about) returns None, and the caller reads it through the stage as before, so every message
still comes from the reader.
"""

from __future__ import annotations

from itertools import repeat

import numpy as np

from ..scene.ranges import RANGES, out_of_range
from ..scene.spec import Scene

__all__ = ["PlainColumns", "may_be_plain"]

#: tube attributes taken here: TubeParams field, and whether the value must be > 0 (else >= 0)
TUBE_SCALARS = {
    "warptube:youngsModulus": ("youngs_modulus", True),
    "warptube:density": ("density", True),
    "warptube:damping": ("damping", False),
    "warptube:springDamping": ("spring_damping", False),
    "warptube:anchorStiffness": ("anchor_stiffness", False),
}
#: the reader's largest force component (scene.usd); its ranges of the scalars: scene.ranges.RANGES
MAX_FORCE = 1e9
SCALAR_TYPES = {"double": np.float64, "float": np.float32}
VECTOR_TYPES = {"double3": np.float64, "float3": np.float32}
#: the force attribute taken here: the force's vector
FORCE = "warptube:force"


def may_be_plain(attribute: str) -> bool:
    """Whether a column setting ``attribute`` may be taken here (a tube's scalar parameter or a
    force's vector): judged by the name alone, before the scene is read (:meth:`PlainColumns.of`
    decides with the prim and the type)."""
    return attribute in TUBE_SCALARS or attribute == FORCE


class PlainColumns:
    """The table's columns, when each sets a tube's scalar parameter or a force's vector.

    Args:
        base: the scene as read with no override.
        targets: per column, (prim path, attribute name, USD type name); the path None for a Mesh
            (a tube extracted from it when read, not taken here).
    """

    def __init__(self, base: Scene, targets: list):
        self.base = base
        self.targets = targets
        self.tube_of = {t.path: k for k, t in enumerate(base.tubes)}
        self.force_of = {f.path: k for k, f in enumerate(base.forces)}

    @classmethod
    def of(cls, base: Scene, targets: list) -> PlainColumns | None:
        """The columns as :class:`PlainColumns`, or None where one sets anything else."""
        tubes = {t.path for t in base.tubes}
        forces = {f.path for f in base.forces}
        for prim, attr, type_name in targets:
            if prim is None:  # an extracted Mesh
                return None
            if prim in tubes and attr in TUBE_SCALARS and type_name in SCALAR_TYPES:
                continue
            if prim in forces and attr == FORCE and type_name in VECTOR_TYPES:
                continue
            return None
        return cls(base, targets)

    def scene(self, values: list) -> Scene | None:
        """The variant with ``values`` (one per column, as parsed for the stage), or None where
        the stage must be read (a value the reader refuses or warns about): :meth:`scenes` of one row."""
        return self.scenes([[v] for v in values])[0]

    def scenes(self, columns: list[list]) -> list[Scene | None]:
        """:meth:`scene` for many rows at once: ``columns`` holds, per column, every row's value
        (as parsed for the stage); returns per row the variant, or None where the stage must be
        read. The same scenes as :meth:`scene` row by row, the checks done per column."""
        rows = len(columns[0]) if columns else 0
        good = np.ones(rows, dtype=bool)
        tube_fields: dict = {}  # tube index -> {TubeParams field: (rows,) float64}
        force_values: dict = {}  # force index -> (rows, 3) float64
        with np.errstate(over="ignore", invalid="ignore"):
            for (prim, attr, type_name), values in zip(self.targets, columns):
                if attr == FORCE:
                    v = np.asarray(np.asarray(values, dtype=VECTOR_TYPES[type_name]), dtype=np.float64).reshape(rows, 3)
                    good &= np.isfinite(v).all(axis=1) & (np.abs(v).max(axis=1, initial=0.0) <= MAX_FORCE)
                    force_values[self.force_of[prim]] = v
                    continue
                v = np.asarray(np.asarray(values, dtype=np.float64), dtype=SCALAR_TYPES[type_name]).astype(np.float64)
                field, positive = TUBE_SCALARS[attr]
                within = RANGES[attr]
                good &= np.isfinite(v) & ((v > 0.0) if positive else (v >= 0.0)) & ~out_of_range(v, within)
                tube_fields.setdefault(self.tube_of[prim], {})[field] = v
            for k, fields in tube_fields.items():
                t = self.base.tubes[k]
                # Warnings the reader gives a row and not the base scene (whose own were given once
                # when it was read): the rows go through the reader.
                p = t.params
                if "youngs_modulus" in fields and p.youngs_modulus is None and p.stretch_stiffness is not None and p.bend_stiffness is not None:
                    good[:] = False  # the modulus is not used
                anchor_k = np.asarray(fields.get("anchor_stiffness", p.anchor_stiffness))
                if len(t.anchors):
                    good &= anchor_k != 0.0  # anchors with no stiffness
                elif "anchor_stiffness" in fields:
                    good &= (anchor_k == 0.0) | (p.anchor_stiffness > 0.0)  # a stiffness with no anchors
        out: list = [None] * rows
        taken = np.flatnonzero(good)
        every = len(taken) == rows
        # Per tube prim and force, its spec in each row taken (copies made as replace_checked makes
        # them, the values checked above, per column): the base's where the table does not set it.
        tubes: list = [repeat(t) for t in self.base.tubes]
        for k, fields in tube_fields.items():
            t = self.base.tubes[k]
            params = _copies(t.params, {f: (a if every else a[taken]).tolist() for f, a in fields.items()})
            tubes[k] = _copies(t, {"params": params})
        forces: list = [repeat(f) for f in self.base.forces]
        times = np.zeros(1)
        times.flags.writeable = False  # shared by every variant's constant forces
        for k, v in force_values.items():
            # each variant's force: one constant sample, a row of one (rows, 1, 3) array (read only)
            v = (v if every else v[taken]).reshape(-1, 1, 3)
            v.flags.writeable = False
            forces[k] = _copies(self.base.forces[k], {"times": repeat(times, len(v)), "values": list(v)})
        new, scene_type, scene_fields = object.__new__, type(self.base), self.base.__dict__
        for r, tubes_r, forces_r in zip(taken.tolist(), zip(*tubes), zip(*forces) if forces else repeat(())):
            scene = out[r] = new(scene_type)
            d = scene.__dict__
            d.update(scene_fields)
            d["tubes"] = tubes_r
            d["forces"] = forces_r
        return out


def _copies(spec, changes: dict) -> list:
    """Copies of frozen ``spec`` as :func:`~warp_tube.scene.spec.replace_checked` makes them, the
    i-th with each field of ``changes`` (field -> values) set to its i-th value."""
    new, cls, fields = object.__new__, type(spec), spec.__dict__
    out = []
    if len(changes) == 1:
        (name, values), = changes.items()
        for value in values:
            c = new(cls)
            d = c.__dict__
            d.update(fields)
            d[name] = value
            out.append(c)
        return out
    names = tuple(changes)
    for values in zip(*changes.values()):
        c = new(cls)
        d = c.__dict__
        d.update(fields)
        d.update(zip(names, values))
        out.append(c)
    return out
