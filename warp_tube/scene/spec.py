"""Scene description: frozen dataclasses in SI units, read from USD or built in Python.

A :class:`Scene` holds everything a run needs and nothing about USD. :mod:`warp_tube.scene.usd`
reads one from a stage (validating every attribute) and writes one back.

Geometry (points, widths, spoke lengths) is stored in SI metres here; the stage's
``metersPerUnit`` is kept in :class:`StageInfo` so results go back out in stage units.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

import numpy as np

__all__ = [
    "StageInfo",
    "SimulationSettings",
    "TubeParams",
    "TubeSpec",
    "ForceSpec",
    "Scene",
    "SceneError",
    "replace_checked",
    "INTEGRATORS",
    "FRAME_MODES",
    "MAX_FORCE_N",
]

INTEGRATORS = ("auto", "semiImplicitEuler", "implicitEuler")
FRAME_MODES = ("rotationMinimizing", "local")
#: the largest force component a scene may hold [N] (past any soft tube: a unit is likely wrong)
MAX_FORCE_N = 1e9


class SceneError(ValueError):
    """Invalid scene or request; the message names where and what (CLI exit status 2)."""


def replace_checked(spec, **changes):
    """A copy of frozen spec ``spec`` with ``changes``, without running its checks again: for
    values known to pass them (taken from specs already checked, or checked by the caller), where
    thousands of variants would pay for the checks (arrays, indices) over and over."""
    out = object.__new__(type(spec))
    out.__dict__.update(spec.__dict__)
    out.__dict__.update(changes)
    return out


@dataclass(frozen=True)
class StageInfo:
    """Stage metadata carried from the scene to the output.

    Attributes:
        meters_per_unit: length of one stage unit [m].
        up_axis: "Y" or "Z".
        time_codes_per_second: time codes per second [1/s].
        frames_per_second: frames per second for playback [1/s].
        start_time_code: first frame [time code].
        end_time_code: last frame [time code].
        authored: names of the metadata fields the scene authored (others took USD's fallbacks).
    """

    meters_per_unit: float = 0.01
    up_axis: str = "Y"
    time_codes_per_second: float = 24.0
    frames_per_second: float = 24.0
    start_time_code: float = 0.0
    end_time_code: float = 48.0
    authored: tuple[str, ...] = ()

    def __post_init__(self):
        for name, v in (("metersPerUnit", self.meters_per_unit), ("timeCodesPerSecond", self.time_codes_per_second),
                        ("framesPerSecond", self.frames_per_second)):  # fmt: skip
            if not (isinstance(v, (int, float, np.integer, np.floating)) and math.isfinite(v) and v > 0.0):
                raise SceneError(f"{name} {v!r}: expected a positive finite number")
        for name, v in (("startTimeCode", self.start_time_code), ("endTimeCode", self.end_time_code)):
            if not (isinstance(v, (int, float, np.integer, np.floating)) and math.isfinite(v)):
                raise SceneError(f"{name} {v!r}: expected a finite time code")
        if self.up_axis not in ("Y", "Z"):
            raise SceneError(f"upAxis {self.up_axis!r}: expected \"Y\" or \"Z\"")
        if self.end_time_code < self.start_time_code:
            raise SceneError(f"startTimeCode {self.start_time_code}, endTimeCode {self.end_time_code}: expected end >= start")

    @property
    def frame_count(self) -> int:
        """Number of output frames, one per time code from start to end inclusive."""
        return int(math.floor(self.end_time_code - self.start_time_code + 1e-9)) + 1

    @property
    def frame_dt(self) -> float:
        """Time between output frames [s]."""
        return 1.0 / self.time_codes_per_second


def three_finite(value) -> np.ndarray | None:
    """``value`` as three finite numbers, (3,) float64, or None where it is not that."""
    try:
        v = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        return None
    return v if v.shape == (3,) and np.isfinite(v).all() else None


@dataclass(frozen=True)
class SimulationSettings:
    """Solver settings.

    Attributes:
        time_step: forced substep [s], or None to let the integrator choose.
        integrator: one of :data:`INTEGRATORS`.
        gravity: gravitational acceleration [m/s^2], world frame, or None for none.
    """

    time_step: float | None = None
    integrator: str = "auto"
    gravity: tuple[float, float, float] | None = None

    def __post_init__(self):
        if self.integrator not in INTEGRATORS:
            raise SceneError(f"integrator {self.integrator!r}: expected one of {', '.join(INTEGRATORS)}")
        if self.time_step is not None:
            number("timeStep", self.time_step)
        if self.time_step is not None and not (math.isfinite(self.time_step) and self.time_step > 0.0):
            raise SceneError(f"timeStep {self.time_step!r}: expected a positive finite number of seconds")
        if self.gravity is not None:
            g = three_finite(self.gravity)
            if g is None:
                raise SceneError(f"gravity {self.gravity!r}: expected three finite numbers [m/s^2] or None")
            object.__setattr__(self, "gravity", tuple(float(x) for x in g))


#: an absolute USD prim path: names of letters, digits and underscores (not starting with a digit)
_PRIM_PATH = re.compile(r"(/[^\W\d]\w*)+")


def check_prim_path(path, what: str) -> None:
    """A SceneError unless ``path`` is an absolute USD prim path (what the output's prims are made at)."""
    if not isinstance(path, str) or not _PRIM_PATH.fullmatch(path):
        raise SceneError(f"{what} path {path!r}: expected an absolute USD prim path such as /World/Tube (names of "
                         "letters, digits and underscores, not starting with a digit)")  # fmt: skip


def number(name: str, v) -> None:
    """A SceneError naming ``name`` unless ``v`` is a real number (not a bool or a string)."""
    if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
        raise SceneError(f"{name} {v!r}: expected a number")


def _reals(values, what: str) -> np.ndarray:
    """``values`` as a float64 array, or a SceneError naming ``what`` where they are not real
    numbers (text, complex numbers, objects)."""
    try:
        a = np.asarray(values)
    except (TypeError, ValueError):  # (ragged nesting)
        raise SceneError(f"{what}: a {type(values).__name__} that is no array: expected real numbers") from None
    if a.dtype.kind not in "biuf":  # (bool, integers, floats: not complex, text or objects)
        found = {"U": "text", "S": "text", "c": "complex numbers", "O": "objects"}.get(a.dtype.kind, str(a.dtype))
        raise SceneError(f"{what}: {found}: expected real numbers")
    return np.asarray(a, dtype=np.float64)  # (the same array where it is one already: variants share their geometry by identity)


@dataclass(frozen=True)
class TubeParams:
    """Material and surface parameters of one tube prim (all its curves), SI units.

    Attributes:
        density: mass density [kg/m^3].
        youngs_modulus: Young's modulus [Pa], or None when both stiffnesses are given.
        stretch_stiffness: axial stiffness EA [N]; default E * pi r^2 per segment.
        bend_stiffness: bending stiffness EI [N m^2]; default E * pi r^4 / 4 per hub.
        damping: mass-proportional damping rate [1/s].
        spring_damping: stiffness-proportional damping time [s] (along springs).
        anchor_stiffness: stiffness of the returning springs [N/m].
        spokes: spokes per hub, S.
        frames: "rotationMinimizing" or "local".
        caps: close the ends with rounded caps.
        reference_normal: direction of spoke 0 at each curve's first hub, or None.
    """

    density: float
    youngs_modulus: float | None = None
    stretch_stiffness: float | None = None
    bend_stiffness: float | None = None
    damping: float = 0.0
    spring_damping: float = 0.0
    anchor_stiffness: float = 0.0
    spokes: int = 16
    frames: str = "rotationMinimizing"
    caps: bool = False
    reference_normal: tuple[float, float, float] | None = None

    def __post_init__(self):
        def positive(name, v):
            number(name, v)
            if not (math.isfinite(v) and v > 0.0):
                raise SceneError(f"{name} {v!r}: expected a positive finite number")

        def nonneg(name, v):
            number(name, v)
            if not (math.isfinite(v) and v >= 0.0):
                raise SceneError(f"{name} {v!r}: expected a finite number >= 0")

        positive("density", self.density)
        if self.youngs_modulus is not None:
            positive("youngsModulus", self.youngs_modulus)
        for name, v in (("stretchStiffness", self.stretch_stiffness), ("bendStiffness", self.bend_stiffness)):
            if v is not None:
                nonneg(name, v)
        if self.youngs_modulus is None and (self.stretch_stiffness is None or self.bend_stiffness is None):
            raise SceneError("youngsModulus missing: expected youngsModulus, or both stretchStiffness and bendStiffness")
        if self.youngs_modulus is None and self.stretch_stiffness == 0.0:
            raise SceneError("stretchStiffness 0: expected a positive axial stiffness [N]")
        nonneg("damping", self.damping)
        nonneg("springDamping", self.spring_damping)
        nonneg("anchorStiffness", self.anchor_stiffness)
        if isinstance(self.spokes, bool) or not isinstance(self.spokes, (int, np.integer)) or not (3 <= self.spokes <= 1024):
            raise SceneError(f"spokes {self.spokes!r}: expected an integer from 3 to 1024")
        if self.frames not in FRAME_MODES:
            raise SceneError(f"frames {self.frames!r}: expected one of {', '.join(FRAME_MODES)}")
        if not isinstance(self.caps, (bool, np.bool_)):
            raise SceneError(f"caps {self.caps!r}: expected True or False")
        if self.reference_normal is not None:
            n = three_finite(self.reference_normal)
            if n is None or not np.linalg.norm(n) > 0.0:
                raise SceneError(f"referenceNormal {self.reference_normal!r}: expected three finite numbers, not all 0, or None")

    def axial_stiffness(self, radius: np.ndarray) -> np.ndarray:
        """EA [N] for cross-section radii ``radius`` [m]."""
        if self.stretch_stiffness is not None:
            return np.full_like(radius, self.stretch_stiffness, dtype=np.float64)
        return self.youngs_modulus * np.pi * radius**2

    def bending_stiffness(self, radius: np.ndarray) -> np.ndarray:
        """EI [N m^2] for cross-section radii ``radius`` [m] (solid circular section)."""
        if self.bend_stiffness is not None:
            return np.full_like(radius, self.bend_stiffness, dtype=np.float64)
        return self.youngs_modulus * np.pi * radius**4 / 4.0


@dataclass(frozen=True)
class TubeSpec:
    """One tube prim: one or more curves sharing material parameters.

    Attributes:
        path: prim path (the output writes its Centerline and Surface under it).
        points: rest positions [m], world frame, shape (P, 3), all curves in order.
        curve_counts: points per curve, shape (C,), sum P, each >= 2.
        radius: cross-section radius per point [m], shape (P,).
        params: material and surface parameters.
        pinned: indices into ``points`` of hard-pinned points.
        anchors: indices into ``points`` of points held by returning springs.
        spoke_lengths: per point and spoke [m], shape (P, S), or None for circular sections.
        pin_track: positions of the pinned points per output frame [m], shape (F, len(pinned), 3),
            or None when the points are not time-sampled (pins stay at rest).
    """

    path: str
    points: np.ndarray
    curve_counts: np.ndarray
    radius: np.ndarray
    params: TubeParams
    pinned: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    anchors: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    spoke_lengths: np.ndarray | None = None
    pin_track: np.ndarray | None = None
    metadata: dict = field(default_factory=dict)

    def __post_init__(self):
        check_prim_path(self.path, "tube")
        if not isinstance(self.params, TubeParams):
            raise SceneError(f"tube {self.path}: params {type(self.params).__name__}: expected a TubeParams")
        where = f"tube {self.path}"
        pts = _reals(self.points, f"{where}: points")
        if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) < 2:
            raise SceneError(f"{where}: points shape {pts.shape}: expected (P >= 2, 3)")
        if not np.isfinite(pts).all():
            bad = int(np.argwhere(~np.isfinite(pts).all(axis=1))[0, 0])
            raise SceneError(f"{where}: points[{bad}] = {pts[bad].tolist()}: expected finite values")
        counts = self.curve_counts
        if not (isinstance(counts, np.ndarray) and counts.dtype.kind in "iu"):  # (an integer array: taken as it is)
            counts = _reals(counts, f"{where}: curveVertexCounts")
            if not np.array_equal(counts, np.round(counts)):
                raise SceneError(f"{where}: curveVertexCounts {counts.tolist()!r}: expected whole numbers of points")
        counts = np.asarray(counts, dtype=np.int64)
        if counts.ndim != 1 or counts.sum() != len(pts) or (counts < 2).any():
            raise SceneError(
                f"{where}: curveVertexCounts {counts.tolist()}: expected counts >= 2 summing to {len(pts)} points"
            )
        rad = _reals(self.radius, f"{where}: radius")
        if rad.size == 1:  # one radius for every point
            rad = np.full(len(pts), float(rad.reshape(-1)[0]))
        if rad.shape != (len(pts),):
            raise SceneError(f"{where}: widths give {rad.shape} radii: expected one or {len(pts)}")
        if not (np.isfinite(rad).all() and (rad > 0).all()):
            bad = int(np.argwhere(~(np.isfinite(rad) & (rad > 0)))[0, 0])
            raise SceneError(f"{where}: widths[{bad}] = {float(2 * rad[bad]):g} m: expected a positive finite diameter")
        object.__setattr__(self, "points", pts)
        object.__setattr__(self, "curve_counts", counts)
        object.__setattr__(self, "radius", rad)
        for name in ("pinned", "anchors"):
            given = np.asarray(getattr(self, name)).reshape(-1)
            attr = "pinnedPoints" if name == "pinned" else "anchorPoints"
            if given.size and not (np.issubdtype(given.dtype, np.integer) or (np.issubdtype(given.dtype, np.floating) and
                                                                           np.array_equal(given, np.round(given)))):  # fmt: skip
                raise SceneError(f"{where}: {attr} {given.tolist()!r}: expected point indices (integers)")
            idx = np.unique(given.astype(np.int64))
            if len(idx) and (idx.min() < 0 or idx.max() >= len(pts)):
                bad = idx[(idx < 0) | (idx >= len(pts))][0]
                raise SceneError(f"{where}: {attr} holds {bad}: expected indices 0..{len(pts) - 1}")
            object.__setattr__(self, name, idx)
        if self.spoke_lengths is not None:
            sl = np.asarray(self.spoke_lengths, dtype=np.float64)
            if sl.shape != (len(pts), self.params.spokes):
                raise SceneError(
                    f"{where}: spokeLengths has {sl.size} values: expected points x spokes = "
                    f"{len(pts)} x {self.params.spokes} = {len(pts) * self.params.spokes}"
                )
            if not (np.isfinite(sl).all() and (sl > 0).all()):
                raise SceneError(f"{where}: spokeLengths: expected positive finite lengths")
            object.__setattr__(self, "spoke_lengths", sl)
        if self.pin_track is not None:
            tr = np.asarray(self.pin_track, dtype=np.float64)
            if tr.ndim != 3 or tr.shape[1:] != (len(self.pinned), 3) or not np.isfinite(tr).all():
                raise SceneError(f"{where}: time-sampled points: expected finite (frames, pinned, 3) positions")
            object.__setattr__(self, "pin_track", tr)
        # Coincident or near-coincident consecutive points make segments of no length.
        seg = np.linalg.norm(pts[1:] - pts[:-1], axis=1)
        starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
        inside = np.ones(len(pts) - 1, dtype=bool)
        inside[(starts[1:] - 1)] = False  # the link from one curve's last point to the next curve's first
        scale = float(np.max(np.ptp(pts, axis=0))) or 1.0
        short = inside & (seg <= 1e-6 * scale)
        if short.any():
            i = int(np.argmax(short))
            if seg[i] == 0.0:
                raise SceneError(f"{where}: points[{i}] and points[{i + 1}] coincide: expected distinct consecutive points "
                                 f"(each segment longer than 1e-6 of the tube's extent, {scale:.3g} m)")  # fmt: skip
            raise SceneError(f"{where}: points[{i}] and points[{i + 1}] are {seg[i]:.3g} m apart, a segment shorter than 1e-6 "
                             f"of the tube's extent ({scale:.3g} m): expected every segment longer than {1e-6 * scale:.3g} m "
                             "(a point far from the others, or points nearly on top of each other?)")  # fmt: skip

    @property
    def curve_starts(self) -> np.ndarray:
        """Index of each curve's first point, shape (C,)."""
        return np.concatenate([[0], np.cumsum(self.curve_counts)[:-1]]).astype(np.int64)


@dataclass(frozen=True)
class ForceSpec:
    """A point force on one point of one tube.

    Attributes:
        path: prim path of the force.
        tube: index of the target tube in :attr:`Scene.tubes`.
        point: index into the target's ``points``.
        times: sample times [s] from the first frame, shape (K,), increasing; K >= 1.
        values: force at those times [N], world frame, shape (K, 3). Linear between samples, held
            after the last, held before the first.
        assistant_line: build the assistant line while the force acts.
    """

    path: str
    tube: int
    point: int
    times: np.ndarray
    values: np.ndarray
    assistant_line: bool = True

    def __post_init__(self):
        check_prim_path(self.path, "force")
        t = _reals(self.times, f"force {self.path}: times").reshape(-1)
        v = _reals(self.values, f"force {self.path}: values")
        if v.shape == (3,):
            v = v.reshape(1, 3)
        if v.ndim != 2 or v.shape[1] != 3:
            raise SceneError(f"force {self.path}: values shaped {v.shape}: expected (samples, 3) [N]")
        if not isinstance(self.assistant_line, (bool, np.bool_)):
            raise SceneError(f"force {self.path}: assistant_line {self.assistant_line!r}: expected True or False")
        if len(t) != len(v) or len(t) == 0:
            raise SceneError(f"force {self.path}: {len(t)} times for {len(v)} values")
        if not (np.isfinite(t).all() and np.isfinite(v).all()):
            raise SceneError(f"force {self.path}: force: expected finite values")
        if np.abs(v).max() > MAX_FORCE_N:
            raise SceneError(f"force {self.path}: force: a component of {np.abs(v).max():.3g} N: expected at most 1e9 N a component "
                             "(as a scene's warptube:force)")  # fmt: skip
        if (np.diff(t) <= 0).any():
            raise SceneError(f"force {self.path}: sample times must increase")
        for name, index in (("tube", self.tube), ("point", self.point)):
            if isinstance(index, bool) or not isinstance(index, (int, np.integer)):
                raise SceneError(f"force {self.path}: {name} {index!r}: expected an index (an integer)")
        object.__setattr__(self, "times", t)
        object.__setattr__(self, "values", v)

    def at(self, time: float) -> np.ndarray:
        """Force [N] at ``time`` [s]: linear between samples, held outside them."""
        if len(self.times) == 1:
            return self.values[0].copy()
        return np.array([np.interp(time, self.times, self.values[:, k]) for k in range(3)])


@dataclass(frozen=True)
class Scene:
    """A whole scene: tubes, forces, settings and stage metadata.

    Attributes:
        tubes: the tubes (:class:`TubeSpec`; at least one), in the order their points are laid out
            in the model and the outputs.
        forces: the point forces (:class:`ForceSpec`), each naming its tube by index into ``tubes``.
        settings: the integrator, forced substep and gravity (:class:`SimulationSettings`).
        stage: the time range, frame rate, units and up axis (:class:`StageInfo`).
        source: where the scene came from (a file path, or ``"<python>"``), named in messages.
    """

    tubes: tuple[TubeSpec, ...]
    forces: tuple[ForceSpec, ...] = ()
    settings: SimulationSettings = field(default_factory=SimulationSettings)
    stage: StageInfo = field(default_factory=StageInfo)
    source: str = "<python>"

    def __post_init__(self):
        for name, items, kind in (("tubes", self.tubes, TubeSpec), ("forces", self.forces, ForceSpec)):
            if not isinstance(items, (tuple, list)):
                raise SceneError(f"{self.source}: {name}: {type(items).__name__}: expected a tuple of {kind.__name__}")
            other = next((x for x in items if not isinstance(x, kind)), None)
            if other is not None:
                raise SceneError(f"{self.source}: {name}: a {type(items).__name__} holding a {type(other).__name__}: "
                                 f"expected a tuple of {kind.__name__}")  # fmt: skip
            object.__setattr__(self, name, tuple(items))
        for name, value, kind in (("settings", self.settings, SimulationSettings), ("stage", self.stage, StageInfo)):
            if not isinstance(value, kind):
                raise SceneError(f"{self.source}: {name}: a {type(value).__name__}: expected a {kind.__name__}")
        if not self.tubes:
            raise SceneError(
                f"{self.source}: no tube: expected a BasisCurves prim carrying warptube: attributes "
                "(or a Mesh with warptube:extract = true)"
            )
        for kind, items in (("tubes", self.tubes), ("forces", self.forces)):
            paths = [x.path for x in items]
            if len(set(paths)) != len(paths):
                twice = next(p for p in paths if paths.count(p) > 1)
                raise SceneError(f"{self.source}: two {kind} have the path {twice}: expected one prim path each")
        both = {t.path for t in self.tubes} & {f.path for f in self.forces}
        if both:
            raise SceneError(f"{self.source}: a tube and a force have the path {min(both)}: expected one prim path each")
        for f in self.forces:
            if not (0 <= f.tube < len(self.tubes)):
                raise SceneError(f"force {f.path}: target tube index {f.tube} out of range")
            n = len(self.tubes[f.tube].points)
            if not (0 <= f.point < n):
                raise SceneError(
                    f"force {f.path}: warptube:point {f.point}: expected an index 0..{n - 1} of "
                    f"{self.tubes[f.tube].path}.points"
                )
