"""Read a USD stage into a validated :class:`~warp_tube.scene.spec.Scene`, and write one back.

The scene contract (README, "Scene format"): a tube is a ``BasisCurves`` prim of type "linear"
carrying at least one ``warptube:`` attribute, each curve one tube; the settings are the one prim
carrying ``warptube:timeStep``, ``warptube:integrator`` or ``warptube:gravity``; a force is any prim
with a ``warptube:target`` relationship; a ``Mesh`` with ``warptube:extract = true`` is a tube given
as a surface, extracted at load. Every error names the file, the prim, the attribute, what was
found and what was expected.
"""

from __future__ import annotations

import logging
import math
import os

import numpy as np

from .curves import BEYOND_WORLD, MAX_WORLD_M, check_curve_type, check_points_type, curve_counts, curve_widths, moving_pin_track
from .attributes import (KNOWN_ATTRS, TARGET, check_names, check_namespace, check_relationships, kind_of, missing, not_defined, not_simulated,
                         samples_differ, undefined, where)  # fmt: skip
from .ranges import GRAVITY, METERS_PER_UNIT, RADIUS_M, RANGES, TIME_STEP, expected, lengths_outside, number_text, out_of_range
from .spec import (
    FRAME_MODES,
    INTEGRATORS,
    MAX_FORCE_N,
    ForceSpec,
    Scene,
    SceneError,
    SimulationSettings,
    StageInfo,
    TubeParams,
    TubeSpec,
)
from ..runtime.log_filters import same_for_many
from .opening import open_stage, usd_error_in_user_terms
from .transforms import section_scale, to_world, warn_about_layer_units, warn_about_transforms
from .shape_notes import check_world_precision, warn_about_shape
from .save import save_scene

log = logging.getLogger(__name__)

#: a stage holds at most this many frames after its first; a moving pin's track as many
MAX_FRAMES = 1_000_000

__all__ = ["load_scene", "open_stage", "save_scene", "usd_error_in_user_terms", "SceneReader"]

REAL = ("float", "double", "half")
REAL3 = ("float3", "double3", "half3", "vector3f", "vector3d", "vector3h", "point3f", "point3d", "normal3f", "normal3d")


class _Reader:
    """Typed access to one prim's ``warptube:`` attributes with contract-style errors."""

    def __init__(self, file: str, prim, start: float | None = None):
        self.file = file
        self.prim = prim
        self.start = start  # the stage's startTimeCode: where time-sampled values are read

    def where(self, name: str) -> str:
        return where(self.file, self.prim, name)

    def missing(self, name: str, expected: str, instead=()):
        """An error: ``name`` (nor any of ``instead``, which may take its place) is not authored."""
        raise SceneError(f"{self.where(name)}: {missing(self.prim, (name, *instead))}: expected {expected}")

    def fail(self, name: str, found, expected: str):
        raise SceneError(f"{self.where(name)}: found {found}: expected {expected}")

    def attr(self, name: str):
        a = self.prim.GetAttribute(name)
        return a if a and a.HasAuthoredValue() else None

    def _typed(self, name, allowed, expected, time=None):
        a = self.attr(name)
        if a is None:
            return None, None
        tname = str(a.GetTypeName())
        if tname not in allowed:
            self.fail(name, f"type {tname}", expected)
        from pxr import Usd

        if time is not None:
            return a, a.Get(time)
        # A value authored as time samples (as DCC tools often write them) is read at the first
        # frame; the parameters are not animated, which a warning says where the samples differ.
        at = Usd.TimeCode.EarliestTime() if self.start is None else Usd.TimeCode(self.start)
        v = a.Get(at)
        if v is None:
            raise SceneError(f"{self.where(name)}: no value at the first frame: expected a value (a default or time samples)")
        if samples_differ(a):
            log.warning("%s: time-sampled: its value at the first frame (%s) is used for the whole run (only "
                        "warptube:force and points are followed in time)", self.where(name), v)  # fmt: skip
        return a, v

    def real(self, name, default=None, required=False, minimum=None, positive=False):
        a, v = self._typed(name, REAL, "a float or double")
        if a is None:
            if required:
                self.missing(name, "a float or double (required)")
            return default
        v = float(v)
        if not math.isfinite(v):
            self.fail(name, v, "a finite number")
        if positive and v <= 0.0:
            self.fail(name, v, "a number > 0")
        if minimum is not None and v < minimum:
            self.fail(name, v, f"a number >= {minimum}")
        within = RANGES.get(name, TIME_STEP if name == "warptube:timeStep" else None)
        if within is not None and out_of_range(v, within):
            self.fail(name, number_text(v), expected(within))
        return v

    def integer(self, name, default=None, required=False, lo=None, hi=None):
        a, v = self._typed(name, ("int", "int64", "uint", "uchar"), "an int")
        if a is None:
            if required:
                self.missing(name, "an int (required)")
            return default
        v = int(v)
        if (lo is not None and v < lo) or (hi is not None and v > hi):
            self.fail(name, v, f"an int from {lo} to {hi}")
        return v

    def ints(self, name):
        a, v = self._typed(name, ("int[]", "int64[]", "uint[]"), "an int[] array")
        return np.zeros(0, dtype=np.int64) if a is None else np.asarray(v, dtype=np.int64).reshape(-1)

    def reals(self, name):
        a, v = self._typed(name, ("float[]", "double[]", "half[]"), "a float[] or double[] array")
        if a is None:
            return None
        arr = np.asarray(v, dtype=np.float64).reshape(-1)
        if not np.isfinite(arr).all():
            i = int(np.argmax(~np.isfinite(arr)))
            self.fail(name, f"{arr[i]} at index {i}", "finite values")
        return arr

    def vec3(self, name, default=None, time=None):
        a, v = self._typed(name, REAL3, "a float3 or double3", time)
        if a is None:
            return default
        if v is None:  # (a sample authored as None blocks the value at its time)
            self.fail(name, f"a blocked sample (None) at time {time:g}", "a float3 at every sample")
        arr = np.asarray(v, dtype=np.float64).reshape(3)
        if not np.isfinite(arr).all():
            self.fail(name, tuple(arr.tolist()), "finite values")
        return tuple(float(x) for x in arr)

    def token(self, name, allowed, default):
        a, v = self._typed(name, ("token", "string"), "a token")
        if a is None:
            return default
        if v not in allowed:
            self.fail(name, repr(v), " | ".join(repr(x) for x in allowed))
        return str(v)

    def boolean(self, name, default):
        a, v = self._typed(name, ("bool",), "a bool")
        return default if a is None else bool(v)


def _stage_info(stage) -> StageInfo:
    from pxr import UsdGeom

    authored = tuple(
        k for k in ("metersPerUnit", "upAxis", "timeCodesPerSecond", "framesPerSecond", "startTimeCode", "endTimeCode")
        if stage.HasAuthoredMetadata(k)
    )  # fmt: skip
    mpu = float(UsdGeom.GetStageMetersPerUnit(stage))
    tcps = float(stage.GetTimeCodesPerSecond())
    fps = float(stage.GetFramesPerSecond())
    start, end = float(stage.GetStartTimeCode()), float(stage.GetEndTimeCode())
    path = stage.GetRootLayer().identifier
    if not (math.isfinite(mpu) and mpu > 0):
        raise SceneError(f"{path}: metersPerUnit {mpu}: expected a positive number")
    if out_of_range(mpu, METERS_PER_UNIT):
        raise SceneError(f"{path}: metersPerUnit {number_text(mpu)}: expected {expected(METERS_PER_UNIT)}")
    if not (math.isfinite(tcps) and tcps > 0):
        raise SceneError(f"{path}: timeCodesPerSecond {tcps}: expected a positive number")
    for name, v in (("startTimeCode", start), ("endTimeCode", end)):
        if not math.isfinite(v):
            raise SceneError(f"{path}: {name} {v}: expected a finite time code")
    # An unauthored end or start takes USD's fallback 0, which may lie on the wrong side of the
    # one authored: the range is then that one time code (--frames N runs on from it).
    if end < start and "endTimeCode" not in authored:
        end = start
    elif end < start and "startTimeCode" not in authored:
        start = end
    if end < start:
        raise SceneError(f"{path}: startTimeCode {start}, endTimeCode {end}: expected end >= start")
    if end - start > MAX_FRAMES:
        raise SceneError(f"{path}: {end - start:.0f} frames: expected at most {MAX_FRAMES:,}")
    if "upAxis" in authored and str(stage.GetMetadata("upAxis")) not in ("Y", "Z"):
        raise SceneError(f"{path}: upAxis {str(stage.GetMetadata('upAxis'))!r}: expected \"Y\" or \"Z\"")
    return StageInfo(
        meters_per_unit=mpu, up_axis=str(UsdGeom.GetStageUpAxis(stage)), time_codes_per_second=tcps,
        frames_per_second=fps, start_time_code=start, end_time_code=end, authored=authored,
    )  # fmt: skip


def _read_tube(file: str, prim, info: StageInfo, frame_times, varying: dict | None = None) -> TubeSpec:
    from pxr import Usd, UsdGeom

    r = _Reader(file, prim, info.start_time_code)
    curves = UsdGeom.BasisCurves(prim)
    check_curve_type(r, curves)
    pattr = curves.GetPointsAttr()
    if pattr.HasAuthoredValue():
        check_points_type(r, pattr)
    pts = pattr.Get(Usd.TimeCode(info.start_time_code)) if pattr.HasAuthoredValue() else None
    if pts is None or len(pts) == 0:
        raise SceneError(f"{r.where('points')}: missing or empty: expected point3f[] with at least 2 points")
    pts = np.asarray(pts, dtype=np.float64)
    if not np.isfinite(pts).all():
        i = int(np.argmax(~np.isfinite(pts).all(axis=1)))
        r.fail("points", f"{pts[i].tolist()} at index {i}", "finite values")
    start_tc = Usd.TimeCode(info.start_time_code)
    counts = curve_counts(r, curves, len(pts), start_tc)  # (also where time-sampled)
    world, scale, matrix = to_world(prim, pts, start_tc, file)
    mpu = info.meters_per_unit
    widths = curve_widths(r, curves, counts, start_tc)
    across = section_scale(pts, counts, matrix)  # (an uneven scale: per point; None: the one scale)
    radius = 0.5 * widths * (scale if across is None else across) * mpu
    coordinate, largest_radius = float(np.abs(world).max()) * mpu, float(radius.max())
    if max(coordinate, largest_radius) > MAX_WORLD_M:
        name, what = ("points", "coordinate") if coordinate >= largest_radius else ("widths", "radius")
        r.fail(name, f"a {what} of {max(coordinate, largest_radius):.3g} m (after the transforms and metersPerUnit)", BEYOND_WORLD)
    outside = lengths_outside(radius, "a radius")
    if outside:
        r.fail("widths", outside, expected(RADIUS_M))
    warn_about_transforms(prim, matrix, curves.GetPointsAttr().GetNumTimeSamples() > 1, r.where("points"), varying)
    warn_about_layer_units(prim, pattr, matrix, mpu, info.up_axis, r.where("points"))
    E = r.real("warptube:youngsModulus", positive=True)
    EA = r.real("warptube:stretchStiffness", minimum=0.0)
    EI = r.real("warptube:bendStiffness", minimum=0.0)
    if E is None and (EA is None or EI is None):
        r.missing("warptube:youngsModulus", "youngsModulus [Pa], or both warptube:stretchStiffness [N] and "
                  "warptube:bendStiffness [N m^2]", ("warptube:stretchStiffness", "warptube:bendStiffness"))
    if EA is not None and EA == 0.0:
        r.fail("warptube:stretchStiffness", 0.0, "a positive axial stiffness [N]")
    if E is not None and EA is not None and EI is not None:
        log.warning("%s: not used: stretchStiffness and bendStiffness are both given and take its place",
                    r.where("warptube:youngsModulus"))  # fmt: skip
    spokes = r.integer("warptube:spokes", default=16, lo=3, hi=1024)
    rn = r.vec3("warptube:referenceNormal")
    if rn is not None and max(map(abs, rn)) == 0.0:
        r.fail("warptube:referenceNormal", rn, "a non-zero direction")
    mirrored = np.linalg.det(matrix[:3, :3]) < 0.0
    if rn is not None:  # a direction in the prim's space, turned (and scaled, and mirrored) as its points
        d = np.asarray(rn, dtype=np.float64) / max(map(abs, rn)) @ (matrix[:3, :3] / np.abs(matrix[:3, :3]).max())
        rn = tuple(float(x) for x in d / np.linalg.norm(d))
        first = np.concatenate([[0], np.cumsum(counts)[:-1]])
        seg = world[first + 1] - world[first]
        along = np.abs(seg @ np.asarray(rn)) / np.maximum(np.linalg.norm(seg, axis=1), 1e-300)
        if (along > math.cos(math.radians(1.0))).any():  # (within 1 degree of a curve's first segment)
            log.warning("%s: along the first segment of curve %d: spoke 0 points across the tube, so the part of it across "
                        "the tube sets its direction (none: the world axis least along the tube)",
                        r.where("warptube:referenceNormal"), int(np.argmax(along)))  # fmt: skip
    # The reader's errors name file, prim and attribute already; TubeParams' own checks do not.
    values = dict(
        density=r.real("warptube:density", required=True, positive=True),
        youngs_modulus=E, stretch_stiffness=EA, bend_stiffness=EI,
        damping=r.real("warptube:damping", 0.0, minimum=0.0),
        spring_damping=r.real("warptube:springDamping", 0.0, minimum=0.0),
        anchor_stiffness=r.real("warptube:anchorStiffness", 0.0, minimum=0.0),
        spokes=spokes, frames=r.token("warptube:frames", FRAME_MODES, "rotationMinimizing"),
        caps=r.boolean("warptube:caps", False), reference_normal=rn,
    )  # fmt: skip
    try:
        params = TubeParams(**values)
    except SceneError as e:
        raise SceneError(f"{file}: {prim.GetPath()}: {e}") from None
    n = len(pts)
    idx = {}
    for attr in ("warptube:pinnedPoints", "warptube:anchorPoints"):
        v = r.ints(attr)
        if len(v) and (v.min() < 0 or v.max() >= n):
            b = int(v[(v < 0) | (v >= n)][0])
            r.fail(attr, f"index {b}", f"indices 0..{n - 1} into points")
        idx[attr] = v
    if len(idx["warptube:anchorPoints"]) and params.anchor_stiffness == 0.0:
        log.warning("%s: anchorPoints given with anchorStiffness 0: the returning springs do nothing", r.where("warptube:anchorStiffness"))
    if not len(idx["warptube:anchorPoints"]) and params.anchor_stiffness > 0.0:
        log.warning("%s: no anchorPoints: the returning springs act on none of the points", r.where("warptube:anchorStiffness"))
    sl = r.reals("warptube:spokeLengths")
    if sl is not None:
        if len(sl) != n * spokes:
            r.fail("warptube:spokeLengths", f"{len(sl)} values", f"points x spokes = {n} x {spokes} = {n * spokes}")
        if (sl <= 0).any():
            i = int(np.argmax(sl <= 0))
            r.fail("warptube:spokeLengths", f"{sl[i]} at index {i}", "positive lengths")
        sl = sl.reshape(n, spokes) * (scale if across is None else across[:, None]) * mpu
        outside = lengths_outside(sl, "a length")
        if outside:
            r.fail("warptube:spokeLengths", outside, expected(RADIUS_M))
        if mirrored:  # spoke j at angle 2 pi j / S in the prim's space lies at -2 pi j / S in the world's
            sl = sl[:, (-np.arange(spokes)) % spokes]
    pin_track = None
    pinned = np.unique(idx["warptube:pinnedPoints"])
    if pattr.GetNumTimeSamples() > 1 and not len(pinned):
        log.warning("%s: time-sampled, but the tube has no pinnedPoints: only pinned points follow the samples "
                    "(the rest shape is the first frame's): nothing here follows them", r.where("points"))  # fmt: skip
    if pattr.GetNumTimeSamples() > 1 and len(pinned):
        times = pin_frame_times(frame_times, pattr.GetTimeSamples()[-1])
        pin_track = moving_pin_track(r, prim, pattr, times, pts, pinned, mpu, file)
    try:
        spec = TubeSpec(
            path=str(prim.GetPath()), points=world * mpu, curve_counts=counts, radius=radius, params=params,
            pinned=pinned, anchors=idx["warptube:anchorPoints"], spoke_lengths=sl, pin_track=pin_track,
        )  # fmt: skip
    except SceneError as e:
        raise SceneError(f"{file}: {e}") from None
    check_world_precision(r.where("points"), world * mpu, counts)  # (after the points' own checks)
    warn_about_shape(r.where("points"), pts, world * mpu, counts, radius, pinned, idx["warptube:anchorPoints"],
                     r.where("warptube:anchorPoints"))  # fmt: skip
    return spec


def pin_frame_times(frame_times: list, last_sample: float) -> list:
    """The time codes of frames a moving pin's track holds: the stage's frames, and on to the
    frame at or after the points' last time sample (a run of more frames than the stage's follows
    the samples to there, as it follows a force's; after it the pins hold, as USD holds a value
    after its last sample), at most :data:`MAX_FRAMES` + 1 frames."""
    start = frame_times[0]
    needed = min(int(math.ceil(last_sample - start - 1e-9)) + 1, MAX_FRAMES + 1)
    return frame_times + [start + k for k in range(len(frame_times), needed)]


def _read_force(file: str, prim, tubes_by_path: dict, tube_specs, info: StageInfo) -> ForceSpec:
    r = _Reader(file, prim, info.start_time_code)
    targets = prim.GetRelationship(TARGET).GetTargets()
    if len(targets) != 1:
        r.fail("warptube:target", f"{len(targets)} targets", "exactly one tube prim")
    tpath = str(targets[0])
    if tpath not in tubes_by_path:
        r.fail("warptube:target", tpath, "the path of a tube (a linear BasisCurves prim with warptube: attributes)")
    t = tubes_by_path[tpath]
    n = len(tube_specs[t].points)
    point = r.integer("warptube:point", required=True)
    if not (0 <= point < n):
        r.fail("warptube:point", point, f"an index 0..{n - 1} into {tpath}.points")
    a = r.attr("warptube:force")
    if a is None:
        r.missing("warptube:force", "a float3 force [N] (may be time-sampled)")
    if str(a.GetTypeName()) not in REAL3:
        r.fail("warptube:force", f"type {a.GetTypeName()}", "a float3 or double3")
    samples = a.GetTimeSamples()
    if samples:
        times = np.array([(tc - info.start_time_code) / info.time_codes_per_second for tc in samples])
        values = np.array([r.vec3("warptube:force", time=tc) for tc in samples])
    else:
        times, values = np.zeros(1), np.array([r.vec3("warptube:force")])
    if np.abs(values).max() > MAX_FORCE_N:
        r.fail("warptube:force", f"a component of {np.abs(values).max():.3g} N", "at most 1e9 N a component")
    if point in set(tube_specs[t].pinned.tolist()):
        log.warning("%s: point %d of %s is pinned: this force does nothing", r.where("warptube:point"), point, tpath)
    return ForceSpec(
        path=str(prim.GetPath()), tube=t, point=point, times=times, values=values,
        assistant_line=r.boolean("warptube:assistantLine", True),
    )  # fmt: skip


def _read_settings(file: str, prim, start: float | None = None) -> SimulationSettings:
    r = _Reader(file, prim, start)
    g = r.vec3("warptube:gravity")
    if g is not None:  # (its largest component first: the length of a huge vector overflows)
        size = max(map(abs, g))
        size = float(np.linalg.norm(g)) if size <= GRAVITY.hi else size
        if out_of_range(size, GRAVITY):
            r.fail("warptube:gravity", f"a magnitude of {number_text(size)} m/s^2", expected(GRAVITY))
    ts = r.real("warptube:timeStep", positive=True)
    return SimulationSettings(time_step=ts, integrator=r.token("warptube:integrator", INTEGRATORS, "auto"), gravity=g)


def _check_output_names(path: str, tube_prims) -> None:
    """The output holds ``P/Centerline`` and ``P/Surface`` under each tube prim P: a tube so named
    directly under another tube would take the place of that tube's own (an error); elsewhere its
    parent merely looks like a tube to a reader of the output (a warning)."""
    tube_paths = {p.GetPath() for p in tube_prims}
    for prim in tube_prims:
        for above in prim.GetPath().GetAncestorsRange():  # (the output's gprims hold no prims)
            if above != prim.GetPath() and above.name in ("Centerline", "Surface") and above.GetParentPath() in tube_paths:
                raise SceneError(f"{path}: {prim.GetPath()}: a tube under {above}, where the output writes the tube "
                                 f"{above.GetParentPath()}'s {above.name}: expected it elsewhere (a mesh or curves prim "
                                 f"cannot hold another prim's output)")  # fmt: skip
        if prim.GetName() not in ("Centerline", "Surface"):
            continue
        parent = prim.GetParent().GetPath()
        if parent in tube_paths:
            raise SceneError(f"{path}: {prim.GetPath()}: a tube prim named {prim.GetName()} under the tube {parent}: expected "
                             f"another name (the output writes {parent}'s own {prim.GetName()} there)")  # fmt: skip
        log.warning("%s: %s: a tube prim named %s: in the output %s holds a child %s as a tube does; another name "
                    "keeps the output plain", path, prim.GetPath(), prim.GetName(), parent, prim.GetName())  # fmt: skip


def load_scene(path: str, extract=None) -> Scene:
    """Read and validate the scene at ``path``.

    Args:
        path: a USD file (.usda, .usdc, .usd).
        extract: callable ``(file, prim, info) -> TubeSpec`` for ``Mesh`` prims with
            ``warptube:extract = true`` (:func:`warp_tube.load_scene` passes
            :func:`warp_tube.extract.usd.tube_from_mesh_prim`); without one such prims are an error.

    Raises:
        SceneError: the first problem found, naming file, prim, attribute, found and expected.
    """
    path = os.fspath(path)
    return SceneReader(open_stage(path), path, extract).read()


class SceneReader:
    """Reads a :class:`Scene` from an open stage, and again after some prims' attributes change.

    :func:`load_scene` reads a file once with it; a caller that edits the stage between reads
    (the batch command overrides attributes in the stage's session layer) names the prims it
    changed, and only what depends on them is read again.

    Args:
        stage: the open ``Usd.Stage``.
        path: the file named in messages.
        extract: as for :func:`load_scene`.
    """

    def __init__(self, stage, path: str, extract=None):
        self.stage = stage
        self.path = path
        self.extract = extract
        self._last = None  # what the last read found: prims by kind, their specs

    def read(self, changed=None) -> Scene:
        """The scene as the stage now composes it.

        Args:
            changed: None to read every prim (needed after anything but attribute values changed,
                e.g. a variant selection), or the paths of the prims whose attribute values
                changed since the last read: the tubes at or below them, the forces among them or
                on those tubes and the settings prim if among them are read again, the rest kept.
                A changed prim that is none of these nor an ancestor of one means a full read.

        Raises:
            SceneError: the first problem found, naming file, prim, attribute, found and expected.
        """
        if changed is not None and self._last is not None:
            partial = self._read_changed({str(c) for c in changed})
            if partial is not None:
                return partial
        return self._read_all()

    def _read_all(self) -> Scene:
        stage, path, extract = self.stage, self.path, self.extract
        self._last = None
        info = _stage_info(stage)
        frame_times = [info.start_time_code + k for k in range(info.frame_count)]
        tubes, settings_prims, force_prims, mesh_prims, overs = [], [], [], [], []
        from pxr import Usd, UsdGeom

        # Into instances too: a tube under an instanceable prim is a tube (at its instance's path);
        # and into undefined prims (`over`s alone), whose warptube: attributes are ignored, said so.
        for prim in stage.Traverse(Usd.TraverseInstanceProxies(Usd.PrimIsActive & Usd.PrimIsLoaded & ~Usd.PrimIsAbstract)):
            every = prim.GetPropertyNames()
            check_namespace(path, prim, every)
            names = [n for n in every if n.startswith(("warptube:", "primvars:warptube:")) and prim.GetAttribute(n)]
            if not prim.IsDefined():
                if names:
                    not_defined(path, prim, names)
                    overs += [prim] if prim.IsA(UsdGeom.BasisCurves) or "warptube:extract" in names else []
                continue
            primvars = [n for n in names if n.startswith("primvars:")]
            if primvars:  # (as a DCC tool exports custom attributes)
                raise SceneError(f"{where(path, prim, primvars[0])}: warptube: attributes are plain attributes, not "
                                 f"primvars: author it as {primvars[0].removeprefix('primvars:')}")  # fmt: skip
            check_relationships(path, prim)
            kind = kind_of(prim, names)
            if kind is None:
                if names:
                    check_names(path, prim, names, KNOWN_ATTRS, "warp_tube")
                    not_simulated(path, prim, names)
                continue
            check_names(path, prim, names, kind[1], kind[0])
            if kind[0] == "force":
                force_prims.append(prim)
            elif kind[0] == "simulation settings":
                settings_prims.append(prim)
            elif kind[0] == "tube":
                tubes.append(prim)
            elif _Reader(path, prim, info.start_time_code).boolean("warptube:extract", False):
                mesh_prims.append(prim)
        _check_output_names(path, tubes + mesh_prims)
        _warn_about_prototypes(path, tubes + mesh_prims + force_prims)
        if len(settings_prims) > 1:
            raise SceneError(
                f"{path}: {len(settings_prims)} simulation settings prims "
                f"({', '.join(str(p.GetPath()) for p in settings_prims)}): expected at most one prim carrying "
                "warptube:timeStep, warptube:integrator or warptube:gravity"
            )
        settings = _read_settings(path, settings_prims[0], info.start_time_code) if settings_prims else SimulationSettings()
        g = np.asarray(settings.gravity if settings.gravity is not None else (0.0, 0.0, 0.0), dtype=np.float64)
        down = -np.eye(3)[1 if info.up_axis == "Y" else 2]
        if np.linalg.norm(g) > 0.0 and g @ down < math.cos(math.radians(45.0)) * np.linalg.norm(g):
            vec = lambda v: "(" + ", ".join(f"{x:.4g}" for x in v + 0.0) + ")"  # noqa: E731
            log.warning("%s: %s.warptube:gravity %s is not down the stage's upAxis %s (down is %s): meant for a stage "
                        "with another up axis?", path, settings_prims[0].GetPath(), vec(g), info.up_axis, vec(down))  # fmt: skip
        varying: dict = {}  # ancestors' animated transforms, looked at once
        with same_for_many(log.name):  # (a warning of many prims alike: once, with how many more)
            specs = [_read_tube(path, p, info, frame_times, varying) for p in tubes]
        if mesh_prims:
            if extract is None:
                raise SceneError(
                    f"{path}: {mesh_prims[0].GetPath()}: a Mesh with warptube:extract = true needs centerline "
                    "extraction: load the scene with warp_tube.load_scene"
                )
            specs += [extract(path, p, info) for p in mesh_prims]
        if not specs and overs:
            what, it = undefined(overs[0])
            raise SceneError(f"{path}: no tube: expected a BasisCurves prim carrying warptube: attributes (or a Mesh with "
                             f"warptube:extract = true); {overs[0].GetPath()} is {what}: define {it}")  # fmt: skip
        by_path = {s.path: k for k, s in enumerate(specs)}
        forces = tuple(_read_force(path, p, by_path, specs, info) for p in force_prims)
        scene = Scene(tubes=tuple(specs), forces=forces, settings=settings, stage=info, source=path)
        self._last = dict(info=info, frame_times=frame_times, tube_prims=tubes + mesh_prims, n_curves=len(tubes),
                          settings_prims=settings_prims, force_prims=force_prims, scene=scene)  # fmt: skip
        return scene

    def _read_changed(self, changed: set) -> Scene | None:
        last, path = self._last, self.path
        below = lambda p: any(p == c or p.startswith(c.rstrip("/") + "/") for c in changed)  # noqa: E731
        known = [str(p.GetPath()) for p in last["tube_prims"] + last["force_prims"] + last["settings_prims"]]
        for c in changed:
            if not any(k == c or k.startswith(c.rstrip("/") + "/") for k in known):
                return None  # a prim the last read did not use: it may have become one
        scene = last["scene"]
        specs = list(scene.tubes)
        redo = set()
        for k, prim in enumerate(last["tube_prims"]):
            if below(str(prim.GetPath())):
                if k < last["n_curves"]:
                    specs[k] = _read_tube(path, prim, last["info"], last["frame_times"])
                else:
                    specs[k] = self.extract(path, prim, last["info"])
                redo.add(k)
        by_path = {s.path: k for k, s in enumerate(specs)}
        forces = list(scene.forces)
        for k, prim in enumerate(last["force_prims"]):
            if below(str(prim.GetPath())) or forces[k].tube in redo:
                forces[k] = _read_force(path, prim, by_path, specs, last["info"])
        settings = scene.settings
        if last["settings_prims"] and below(str(last["settings_prims"][0].GetPath())):
            settings = _read_settings(path, last["settings_prims"][0], last["info"].start_time_code)
        scene = Scene(tubes=tuple(specs), forces=tuple(forces), settings=settings, stage=last["info"], source=path)
        last["scene"] = scene
        return scene


def _warn_about_prototypes(path: str, prims) -> None:
    """Warn of tube and force prims inside a PointInstancer: they are simulated once, where they are
    authored; the instancer's instances are not (USD draws a prototype only through them)."""
    from pxr import UsdGeom

    for prim in prims:
        p = prim.GetParent()
        while p and not p.IsPseudoRoot():
            if p.IsA(UsdGeom.PointInstancer):
                log.warning("%s: %s: inside the PointInstancer %s: simulated once, where it is authored; the instancer's "
                            "instances are not simulated (make them instanceable prims, or copies, to simulate each)",
                            path, prim.GetPath(), p.GetPath())  # fmt: skip
                break
            p = p.GetParent()
