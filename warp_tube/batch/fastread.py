"""Variants made from the scene read once, for tables that set plain values only.

Most parameter studies vary a tube's material (Young's modulus, density, damping, ...) and the
forces' vectors. For such a table the variant scenes follow from the base scene without reading
the stage again: :class:`PlainColumns` replaces the parameters and force vectors in copies of the
base scene's specs (a few microseconds a row, against ~0.5 ms for authoring the row in the stage
and reading it through usd-core).

:meth:`PlainColumns.rows` takes many rows at once, the values of each column checked as one
array, and keeps them as columns (:class:`PlainRows`): a row's scene is made only when something
asks for it, and a batch's planning and chunks read the columns instead (:class:`PlainScenes`),
so a table of thousands of rows costs a few microseconds a row in all. :meth:`PlainColumns.scene`
is one row of it.

It takes a row only where the result is certain to be what :class:`~warp_tube.scene.usd.SceneReader`
would read: values rounded as the attribute's type stores them (``float`` to float32), and every
check of the reader passed with no warning due. Any other row (a value the reader would refuse or
warn about) returns None, and the caller reads it through the stage as before, so every message
still comes from the reader.
"""

from __future__ import annotations

from collections.abc import Sequence
from itertools import repeat
from operator import attrgetter

import numpy as np

from ..scene.ranges import RANGES, out_of_range
from ..scene.spec import Scene, replace_checked

__all__ = ["PlainColumns", "PlainRows", "PlainRow", "PlainScenes", "plain_scenes", "may_be_plain"]

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
        """:meth:`scene` for many rows at once (:meth:`rows`, each row's scene made)."""
        return [None if r is None else r.scene for r in self.rows(columns)]

    def rows(self, columns: list[list]) -> list[PlainRow | None]:
        """:meth:`scene` for many rows at once, each scene made when first asked for: ``columns``
        holds, per column, every row's value (as parsed for the stage); returns per row a
        :class:`PlainRow`, or None where the stage must be read. The same scenes as :meth:`scene`
        row by row, the checks done per column."""
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
        if not len(taken):
            return out
        every = len(taken) == rows
        made = PlainRows(self.base, {k: {f: (a if every else a[taken]) for f, a in fields.items()} for k, fields in tube_fields.items()},
                         {k: (v if every else v[taken]) for k, v in force_values.items()})  # fmt: skip
        for r, handle in zip(taken.tolist(), map(PlainRow, repeat(made), range(len(taken)))):
            out[r] = handle
        return out


class PlainRows:
    """Variants made from one base scene by plain values, kept as columns: each variant's scene
    is made when first asked for (:meth:`scene`), as :func:`~warp_tube.scene.spec.replace_checked`
    makes copies: the base's specs with the row's tube parameters and force vectors.

    Args:
        base: the scene as read with no override.
        tube_fields: per tube prim (index in ``base.tubes``), per ``TubeParams`` field, each row's
            value, (n,) float64 (checked).
        force_values: per force (index in ``base.forces``), each row's vector, (n, 3) float64
            (checked): one constant sample a row.
    """

    def __init__(self, base: Scene, tube_fields: dict, force_values: dict):
        self.base = base
        self.tube_fields = tube_fields
        self.force_values = {}
        for k, v in force_values.items():  # each row's force: a row of one (n, 1, 3) array (read only)
            v = np.ascontiguousarray(v).reshape(-1, 1, 3)
            v.flags.writeable = False
            self.force_values[k] = v
        self.times = np.zeros(1)
        self.times.flags.writeable = False  # shared by every row's constant forces
        self._made: dict = {}

    def __getstate__(self) -> dict:
        return {**self.__dict__, "_made": {}}  # (the scenes made are made again where needed)

    def scene(self, r: int) -> Scene:
        """Row ``r``'s scene (made once)."""
        scene = self._made.get(r)
        if scene is None:
            base = self.base
            tubes = list(base.tubes)
            for k, fields in self.tube_fields.items():
                t = tubes[k]
                tubes[k] = replace_checked(t, params=replace_checked(t.params, **{f: float(a[r]) for f, a in fields.items()}))
            forces = list(base.forces)
            for k, v in self.force_values.items():
                forces[k] = replace_checked(forces[k], times=self.times, values=v[r])
            scene = self._made[r] = replace_checked(base, tubes=tuple(tubes), forces=tuple(forces))
        return scene

    def param(self, k: int, field: str, rows: np.ndarray):
        """Tube prim ``k``'s ``TubeParams`` field in ``rows``: (len(rows),) float64 where the
        table sets it, else the base's value (a scalar, or None)."""
        a = self.tube_fields.get(k, {}).get(field)
        return getattr(self.base.tubes[k].params, field) if a is None else a[rows]


class PlainRow:
    """One row of :class:`PlainRows`: its scene is made when first asked for."""

    __slots__ = ("rows", "r")

    def __init__(self, rows: PlainRows, r: int):
        self.rows, self.r = rows, r

    @property
    def scene(self) -> Scene:
        return self.rows.scene(self.r)


class PlainScenes(Sequence):
    """The scenes of some rows of one :class:`PlainRows`, made when asked for, with the columns
    they differ in at hand (what a chunk of plain variants is built from without making them).

    Args:
        rows: the rows' :class:`PlainRows`.
        index: each scene's row in it, (n,) int.
    """

    def __init__(self, rows: PlainRows, index: np.ndarray):
        self.rows, self.index = rows, np.asarray(index, dtype=np.int64)

    @property
    def base(self) -> Scene:
        return self.rows.base

    def __len__(self) -> int:
        return len(self.index)

    def __getitem__(self, i):
        if isinstance(i, slice):
            return PlainScenes(self.rows, self.index[i])
        return self.rows.scene(int(self.index[i]))

    def materials(self, names: tuple[str, ...]) -> np.ndarray:
        """Each scene's tube prims' ``TubeParams`` fields ``names``, scene after scene, (n x
        prims, len(names)) float64, NaN for None."""
        T = len(self.base.tubes)
        out = np.empty((len(self), T, len(names)))
        for k in range(T):
            for j, name in enumerate(names):
                v = self.rows.param(k, name, self.index)
                out[:, k, j] = np.nan if v is None else v
        return out.reshape(len(self) * T, len(names))

    def force_values(self, k: int) -> np.ndarray:
        """Force ``k``'s samples in each scene, (n, samples, 3) [N] (a new array)."""
        v = self.rows.force_values.get(k)
        if v is None:
            return np.repeat(self.base.forces[k].values[None], len(self), axis=0)
        return v[self.index]

    def force_times(self, k: int) -> np.ndarray:
        """Force ``k``'s sample times [s], the same in every scene."""
        return self.rows.times if k in self.rows.force_values else self.base.forces[k].times


def plain_scenes(sources: list) -> PlainScenes | None:
    """``sources`` (variants' :class:`PlainRow` handles, or scenes) as :class:`PlainScenes`, where
    they are all rows of one :class:`PlainRows`; else None."""
    # (each test a pass of C over the handles: a chunk of thousands costs a few milliseconds)
    if not sources or set(map(type, sources)) != {PlainRow} or len(set(map(id, map(attrgetter("rows"), sources)))) != 1:
        return None
    return PlainScenes(sources[0].rows, np.fromiter(map(attrgetter("r"), sources), np.int64, len(sources)))
