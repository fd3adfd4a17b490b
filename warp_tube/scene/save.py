"""Writing a :class:`~warp_tube.scene.spec.Scene` as a USD stage that the scene reader reads back
(points in stage units, every ancestor an Xform, the settings prim under a free name)."""

from __future__ import annotations

import os

import numpy as np

from .attributes import TARGET
from .curves import curves_extent, half_width
from .files import USD_EXTENSIONS, output_path, write_atomically
from .spec import Scene, SceneError

__all__ = ["save_scene"]


def save_scene(scene: Scene, path: str) -> None:
    """Write ``scene`` as a USD stage following the scene contract (points in stage units).

    ``path`` is ``.usda`` (text), ``.usdc`` or ``.usd`` (binary) in an existing folder, and not the
    scene's own file; an existing file there is replaced only by the complete stage.

    Raises:
        TypeError: ``scene`` is not a :class:`Scene`.
        SceneError: a path that cannot be written (named with the reason).
    """
    if not isinstance(scene, Scene):
        raise TypeError(f"save_scene: scene is a {type(scene).__name__}: expected a warp_tube.Scene (load_scene reads a file)")
    inputs = [scene.source] if scene.source and os.path.exists(scene.source) else []
    target = output_path(path, USD_EXTENSIONS, inputs=inputs, what="scene")

    def write(tmp: str) -> None:
        try:
            _write(scene, tmp)
        except SceneError:
            raise
        except Exception as e:  # (usd-core's own errors carry C++ locations: their first line only)
            why = str(e).strip().splitlines()[-1] if str(e).strip() else type(e).__name__
            raise SceneError(f"{target}: cannot write the scene ({why})") from None

    write_atomically(target, write)


def _write(scene: Scene, path: str) -> None:
    from pxr import Gf, Sdf, Usd, UsdGeom, Vt

    info = scene.stage
    mpu = info.meters_per_unit
    stage = Usd.Stage.CreateNew(os.fspath(path))
    UsdGeom.SetStageMetersPerUnit(stage, mpu)
    UsdGeom.SetStageUpAxis(stage, info.up_axis)
    stage.SetTimeCodesPerSecond(info.time_codes_per_second)
    stage.SetFramesPerSecond(info.frames_per_second)
    stage.SetStartTimeCode(info.start_time_code)
    stage.SetEndTimeCode(info.end_time_code)
    paths = [x.path for x in (*scene.tubes, *scene.forces)]
    taken = {str(a) for p in paths for a in Sdf.Path(p).GetPrefixes()}  # the prims and their ancestors
    for p in paths:  # (the ancestors: Xforms, as a DCC tool makes them; the prims' order kept)
        for a in Sdf.Path(p).GetPrefixes()[:-1]:
            if str(a) not in paths and not stage.GetPrimAtPath(a):
                UsdGeom.Xform.Define(stage, a)
    root = Sdf.Path(scene.tubes[0].path).GetPrefixes()[0]
    stage.SetDefaultPrim(stage.GetPrimAtPath(root))
    s = scene.settings
    sim = UsdGeom.Scope.Define(stage, _free_path(f"{root}/Simulation", taken)).GetPrim()
    sim.CreateAttribute("warptube:integrator", Sdf.ValueTypeNames.Token).Set(s.integrator)
    if s.time_step is not None:
        sim.CreateAttribute("warptube:timeStep", Sdf.ValueTypeNames.Double).Set(s.time_step)
    if s.gravity is not None:
        sim.CreateAttribute("warptube:gravity", Sdf.ValueTypeNames.Double3).Set(Gf.Vec3d(*s.gravity))  # (as given: no rounding)
    for t in scene.tubes:
        c = UsdGeom.BasisCurves.Define(stage, t.path)
        c.CreateTypeAttr("linear")
        widths = (2.0 * t.radius / mpu).astype(np.float32)
        half = half_width(widths)
        rest = (t.points / mpu).astype(np.float32)
        points = c.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(rest))
        extent = c.CreateExtentAttr(Vt.Vec3fArray.FromNumpy(curves_extent(rest, half)))  # (usd-core's rule for curves)
        if t.pin_track is not None:  # moving pins: the points (and their extent) time-sampled, one sample a frame
            for k, pins in enumerate(t.pin_track):
                frame = t.points.copy()
                frame[t.pinned] = pins
                frame = (frame / mpu).astype(np.float32)
                time = Usd.TimeCode(scene.stage.start_time_code + k)
                points.Set(Vt.Vec3fArray.FromNumpy(frame), time)
                extent.Set(Vt.Vec3fArray.FromNumpy(curves_extent(frame, half)), time)
        c.CreateCurveVertexCountsAttr(Vt.IntArray([int(v) for v in t.curve_counts]))
        c.CreateWidthsAttr(Vt.FloatArray.FromNumpy(widths))
        c.SetWidthsInterpolation(UsdGeom.Tokens.vertex)
        p, prim = t.params, c.GetPrim()
        D = Sdf.ValueTypeNames.Double
        prim.CreateAttribute("warptube:density", D).Set(p.density)
        for name, v in (("youngsModulus", p.youngs_modulus), ("stretchStiffness", p.stretch_stiffness),
                        ("bendStiffness", p.bend_stiffness)):  # fmt: skip
            if v is not None:
                prim.CreateAttribute(f"warptube:{name}", D).Set(v)
        prim.CreateAttribute("warptube:damping", D).Set(p.damping)
        prim.CreateAttribute("warptube:springDamping", D).Set(p.spring_damping)
        prim.CreateAttribute("warptube:anchorStiffness", D).Set(p.anchor_stiffness)
        prim.CreateAttribute("warptube:spokes", Sdf.ValueTypeNames.Int).Set(p.spokes)
        prim.CreateAttribute("warptube:frames", Sdf.ValueTypeNames.Token).Set(p.frames)
        prim.CreateAttribute("warptube:caps", Sdf.ValueTypeNames.Bool).Set(p.caps)
        if len(t.pinned):
            prim.CreateAttribute("warptube:pinnedPoints", Sdf.ValueTypeNames.IntArray).Set(Vt.IntArray([int(v) for v in t.pinned]))
        if len(t.anchors):
            prim.CreateAttribute("warptube:anchorPoints", Sdf.ValueTypeNames.IntArray).Set(Vt.IntArray([int(v) for v in t.anchors]))
        if t.spoke_lengths is not None:
            prim.CreateAttribute("warptube:spokeLengths", Sdf.ValueTypeNames.FloatArray).Set(
                Vt.FloatArray.FromNumpy((t.spoke_lengths.reshape(-1) / mpu).astype(np.float32)))  # fmt: skip
        if p.reference_normal is not None:
            prim.CreateAttribute("warptube:referenceNormal", Sdf.ValueTypeNames.Float3).Set(Gf.Vec3f(*p.reference_normal))
    for k, f in enumerate(scene.forces):
        prim = UsdGeom.Scope.Define(stage, f.path).GetPrim()
        prim.CreateRelationship(TARGET).SetTargets([scene.tubes[f.tube].path])
        prim.CreateAttribute("warptube:point", Sdf.ValueTypeNames.Int).Set(int(f.point))
        prim.CreateAttribute("warptube:assistantLine", Sdf.ValueTypeNames.Bool).Set(bool(f.assistant_line))
        a = prim.CreateAttribute("warptube:force", Sdf.ValueTypeNames.Double3)  # (as given: no rounding)
        if len(f.times) == 1:
            a.Set(Gf.Vec3d(*f.values[0]))
        for tm, v in zip(f.times, f.values):
            if len(f.times) > 1:
                a.Set(Gf.Vec3d(*v), info.start_time_code + tm * info.time_codes_per_second)
    if not stage.GetRootLayer().Save():
        raise SceneError(f"{path}: usd-core could not save the stage")


def _free_path(path: str, taken: set) -> str:
    """``path``, or ``path`` with the first number appended that makes it none of ``taken``."""
    k, out = 1, path
    while out in taken:
        k, out = k + 1, f"{path}{k}"
    return out
