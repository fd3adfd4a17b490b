"""The physical range of every real-valued scene quantity, and the check that refuses a value
outside it.

A value outside its range is a unit or a typing mistake (metres for centimetres, a missing
exponent's sign), never a tube: taken as it is, it overflows the simulation's float32 arithmetic or
divides by a value that is no longer there. Each range is generous, wide enough for any real tube
from a blood capillary to a 100 m hose, and from a gel of 1 Pa to steel; the reason for each bound
is given with it. Zero stays allowed where the attribute allows it (no damping, no bending).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = ["Range", "RANGES", "METERS_PER_UNIT", "RADIUS_M", "GRAVITY", "TIME_STEP", "out_of_range", "expected", "number_text",
           "check_attribute", "lengths_outside", "check_scene_ranges"]


class Range(NamedTuple):
    """Accepted values ``lo <= v <= hi`` in ``unit`` (``zero``: 0 is accepted too, below ``lo``)."""

    lo: float
    hi: float
    unit: str
    zero: bool = False


#: metersPerUnit [m]: nanometres to 1000 km a unit (past either, a coordinate of a unit or two is no
#: tube's, and dividing the results by it leaves the float range)
METERS_PER_UNIT = Range(1e-9, 1e6, "m")
#: a tube's radius after the transforms and metersPerUnit [m]: a nanometre (a continuum tube no
#: thinner than a few molecules; below it r^4, the bending stiffness's, leaves float32's range) to
#: 1 km (ten times a 100 m hose's length)
RADIUS_M = Range(1e-9, 1e3, "m")
#: the gravity's magnitude [m/s^2]: up to about 100,000 g (an ultracentrifuge's); 0 is none
GRAVITY = Range(0.0, 1e6, "m/s^2")
#: the forced substep [s]: a picosecond (below the stability bound of any tube accepted here) to 10 s
TIME_STEP = Range(1e-12, 10.0, "s")

#: the real-valued ``warptube:`` attributes of a tube prim
RANGES = {
    # Young's modulus: a thousandth of the softest gels' (about 1 Pa) to 50 times steel's (2e11 Pa)
    "warptube:youngsModulus": Range(1e-3, 1e13, "Pa"),
    # mass density: below the lightest aerogels' (0.16 kg/m^3) to over 40 times osmium's (22,600 kg/m^3)
    "warptube:density": Range(1e-2, 1e6, "kg/m^3"),
    # axial stiffness EA: a 1 Pa gel thread of 1 um radius (3e-12 N) to a solid steel rod of 40 m radius
    "warptube:stretchStiffness": Range(1e-12, 1e15, "N"),
    # bending stiffness EI (0: none): from 1e-30 (below a 1 Pa gel thread of 1 um radius, 8e-25) to a solid steel rod of 9 m radius
    "warptube:bendStiffness": Range(1e-30, 1e15, "N m^2", zero=True),
    # mass-proportional damping rate (0: none): up to a rate that stops any motion within a microsecond
    "warptube:damping": Range(1e-12, 1e6, "1/s", zero=True),
    # stiffness-proportional damping time (0: none): up to 10 s (1 s already overdamps every mode above 2 rad/s)
    "warptube:springDamping": Range(1e-15, 10.0, "s", zero=True),
    # returning springs' stiffness (0: none): up to 1e12 N/m (a steel bar of 1 m^2 section, 0.2 m long)
    "warptube:anchorStiffness": Range(1e-12, 1e12, "N/m", zero=True),
}


#: the bounds' relative slack: a bound authored as a float (float32) or reached through a float
#: transform is read a few parts in 1e8 off
SLACK = 1e-6


def out_of_range(v, r: Range):
    """Whether ``v`` (a number, or an array: per element) lies outside ``r`` (NaN does)."""
    inside = (r.lo * (1.0 - SLACK) <= v) & (v <= r.hi * (1.0 + SLACK))
    return ~(inside | ((v == 0.0) & r.zero)) if hasattr(inside, "shape") else not (inside or (r.zero and v == 0.0))


def number_text(v: float) -> str:
    """``v`` for a message, short: ``1e6``, ``1e-12``, ``0.5``, ``5e-324`` (a subnormal as Python's
    repr writes it: formatting it is arithmetic, which reads 0 where the process flushes them)."""
    text = repr(float(v)) if 0.0 < abs(v) < 2.3e-308 else f"{v:.4g}"
    return text.replace("e+0", "e").replace("e+", "e").replace("e-0", "e-")


def expected(r: Range) -> str:
    """What a message expects of a value outside ``r``."""
    lo = f"0 or {number_text(r.lo)}" if r.zero else number_text(r.lo)
    return f"{lo} to {number_text(r.hi)} {r.unit} (the physical range: past it no real tube, a unit is likely wrong)"


def check_attribute(where: str, name: str, v: float) -> None:
    """A SceneError naming ``where`` (file, prim and attribute, as :func:`.attributes.where` has
    them) where the value ``v`` of the attribute ``name``, one of :data:`RANGES`, lies outside its range."""
    from .spec import SceneError

    if name in RANGES and out_of_range(v, RANGES[name]):
        raise SceneError(f"{where}: found {number_text(v)}: expected {expected(RANGES[name])}")


def lengths_outside(values_m, what: str, after: str = " (after the transforms and metersPerUnit)") -> str | None:
    """What a message names where the least or the largest of ``values_m`` (radii or spoke lengths
    [m], after the transforms and metersPerUnit) lies outside :data:`RADIUS_M`: ``"{what} of 1e-12
    m (after ...)"``; None where both lie inside."""
    a = np.asarray(values_m, dtype=np.float64)
    for v in (float(a.min()), float(a.max())):
        if out_of_range(v, RADIUS_M):
            return f"{what} of {number_text(v)} m{after}"
    return None


#: TubeParams fields and the scene attributes whose ranges they take
_PARAMS = {"youngs_modulus": "warptube:youngsModulus", "density": "warptube:density",
           "stretch_stiffness": "warptube:stretchStiffness", "bend_stiffness": "warptube:bendStiffness",
           "damping": "warptube:damping", "spring_damping": "warptube:springDamping",
           "anchor_stiffness": "warptube:anchorStiffness"}  # fmt: skip


def check_scene_ranges(scene) -> None:
    """The ranges a scene read from USD is held to, for a :class:`~warp_tube.scene.spec.Scene`
    built in Python (the reader checks each attribute as it reads it): each tube's parameters,
    radii and spoke lengths, the stage's metersPerUnit, the forced time step and gravity.

    Raises:
        SceneError: naming the tube (or setting), the field, the value and its range."""
    from .spec import SceneError

    def refuse(where: str, found: str, r: Range) -> None:
        raise SceneError(f"{scene.source}: {where}: found {found}: expected {expected(r)}")

    mpu = scene.stage.meters_per_unit
    if out_of_range(mpu, METERS_PER_UNIT):
        refuse("stage.meters_per_unit", number_text(mpu), METERS_PER_UNIT)
    step = scene.settings.time_step
    if step is not None and out_of_range(step, TIME_STEP):
        refuse("settings.time_step", f"{number_text(step)} s", TIME_STEP)
    g = scene.settings.gravity
    if g is not None and out_of_range(float(np.linalg.norm(g)), GRAVITY):
        refuse("settings.gravity", f"a magnitude of {number_text(float(np.linalg.norm(g)))} m/s^2", GRAVITY)
    for t in scene.tubes:
        for field, attr in _PARAMS.items():
            v = getattr(t.params, field)
            if v is not None and out_of_range(v, RANGES[attr]):
                refuse(f"tube {t.path}: params.{field}", number_text(v), RANGES[attr])
        for what, values in (("a radius", t.radius), ("a spoke length", t.spoke_lengths)):
            outside = None if values is None else lengths_outside(values, what, after="")
            if outside:
                raise SceneError(f"{scene.source}: tube {t.path}: {outside}: expected {expected(RADIUS_M)}")
