"""USD ends of centerline extraction: scenes written from extracted tubes, Mesh prims read as tubes.

:func:`write_scene` writes a scene ``.usda`` per the DESIGN scene contract: stage metadata, a
``/World`` default prim, the tube as a linear ``BasisCurves`` with ``warptube:`` attributes
(hubs as points, widths from the spokes' sections (:func:`section_radius`), measured ``spokeLengths``, anchors at both
ends), and a ``/World/Push`` force that ramps up on the middle hub, holds, and is released, so the
scene simulates as written. Side branches left out of the tube and open loops that are not ends
(openings) are recorded in the tube prim's ``customData`` (``warptube:branches:*``,
``warptube:openings:*``), and the caps are on when both ends are rounded closed tips.

:func:`tube_from_mesh_prim` is the extraction hook of :func:`warp_tube.scene.usd.load_scene` for
``Mesh`` prims carrying ``warptube:extract = true``.

Default material (soft tissue): density 1050 kg/m^3 (water-like tissue); Young's modulus 1e5 Pa,
within the 1e4-1e6 Pa measured for intestine wall and arteries at small strain; mass-proportional
damping 2 1/s. Anchor springs of 0.1 x the axial stiffness of one segment (E pi r^2 / l) hold the
two first and two last hubs, like tissue attached at both ends.
"""

from __future__ import annotations

import logging
import math
import os
import re

import numpy as np

from ..scene.attributes import missing, samples_differ, where as attribute_where
from ..scene.curves import curves_extent, half_width
from ..scene.files import USD_EXTENSIONS, output_path, write_atomically
from .pipeline import ExtractedTube, extract_centerline
from ..model.frames import rotation_minimizing_frames
from .mesh_io import load_usd_mesh
from .polyline import arclength
from .tube_check import side_branches
from ..scene.spec import FRAME_MODES, SceneError, StageInfo, TubeParams, TubeSpec
from ..scene.ranges import RADIUS_M, check_attribute, expected, lengths_outside
from ..scene.shape_notes import FLOAT32_SHARE

__all__ = ["write_scene", "tube_from_mesh_prim", "prim_name", "push_force"]

log = logging.getLogger(__name__)

DENSITY = 1050.0  # kg/m^3
YOUNGS_MODULUS = 1.0e5  # Pa
DAMPING = 2.0  # 1/s


def prim_name(text: str) -> str:
    """A valid USD prim name from a file name or label (``"VHF aorta.ply"`` -> ``"VHF_aorta"``)."""
    stem = os.path.splitext(os.path.basename(str(text)))[0]
    name = re.sub(r"[^A-Za-z0-9_]", "_", stem).strip("_") or "Tube"
    name = name if not name[0].isdigit() else "_" + name
    # the output writes a Centerline and a Surface under each tube: a tube of either name would
    # read as a tube's part
    return name + "_tube" if name in ("Centerline", "Surface") else name


def section_radius(spoke_lengths: np.ndarray) -> np.ndarray:
    """Per hub, the radius [same units] of the circle of the spokes' polygon's area.

    The tube's physical radius (its mass and stiffness come from the widths): the spoke lengths are
    fitted so that the rings follow the wall between the spokes too, which makes their mean longer
    than the radius as the spokes get fewer (a circle of radius r: 1.01 r at 16 spokes, 1.27 r at
    4, 1.7 r at 3), while the polygon's area stays close to the section's (1.00 r at 16, 1.09 r at 3).

    Args:
        spoke_lengths: (hubs, spokes), spokes equally spaced in angle around each hub.
    """
    s = np.asarray(spoke_lengths, dtype=np.float64)
    area = 0.5 * math.sin(2.0 * math.pi / s.shape[1]) * np.sum(s * np.roll(s, -1, axis=1), axis=1)
    return np.sqrt(np.maximum(area, 0.0) / math.pi)


def push_force(tube: ExtractedTube, meters_per_unit: float, youngs_modulus: float) -> np.ndarray:
    """Force [N] on the middle hub that would bend a straight tube by about two mean radii.

    An estimate (``warp-tube extract`` then sizes the written push by simulating the scene,
    :mod:`warp_tube.sim.calibrate`: a winding tube is held like an arch and moves far less).
    From the midpoint load of a simply supported beam, ``F = 48 E I d / L^3`` with ``d = 2 r``,
    ``I = pi r^4 / 4`` (mean radius r, length L, in metres); directed along the middle hub's
    spoke-0 direction (perpendicular to the tube there).
    """
    r = float(section_radius(tube.spoke_lengths).mean()) * meters_per_unit
    length = max(tube.length * meters_per_unit, 1e-12)
    magnitude = 48.0 * youngs_modulus * (math.pi * r**4 / 4.0) * (2.0 * r) / length**3
    _, normal, _ = rotation_minimizing_frames(tube.points, None, tube.reference_normal)
    return magnitude * normal[tube.hubs // 2]


def _anchor_stiffness(tube: ExtractedTube, meters_per_unit: float, youngs_modulus: float) -> float:
    r = float(section_radius(tube.spoke_lengths).mean()) * meters_per_unit
    seg = max(tube.length * meters_per_unit / max(tube.hubs - 1, 1), 1e-12)
    return 0.1 * youngs_modulus * math.pi * r**2 / seg


def _float32_origin(points: np.ndarray) -> np.ndarray | None:
    """Where to put a tube's points' origin [mesh units] so that float32 (``point3f``) keeps their
    segments to a tenth of the precision the scene's check asks (:data:`~warp_tube.scene.shape_notes.FLOAT32_SHARE`),
    or None where the points as they are do: the middle of their bounds, for a tube far from the
    mesh's origin (a scan in scanner coordinates, a part of a large assembly)."""
    p = np.asarray(points, dtype=np.float64)
    seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
    shortest = float(seg[seg > 0].min()) if (seg > 0).any() else 0.0
    if shortest == 0.0 or float(np.abs(p).max()) * 2.0**-23 <= 0.1 * FLOAT32_SHARE * shortest:
        return None
    return 0.5 * (p.min(axis=0) + p.max(axis=0))


def write_scene(
    extracted: ExtractedTube,
    path_usda,
    *,
    meters_per_unit: float,
    density: float = DENSITY,
    youngs_modulus: float = YOUNGS_MODULUS,
    damping: float = DAMPING,
    anchor_stiffness: float | None = None,
    anchor_count: int = 2,
    push: bool = True,
    name: str | None = None,
    up_axis: str = "Y",
    end_time_code: int = 96,
    inputs=(),
    final_name: str | None = None,
) -> str:
    """Write a simulation scene for an extracted tube (DESIGN scene contract).

    Args:
        extracted: the tube; its lengths are stage units.
        path_usda: output file: ``.usda`` (text), ``.usdc`` (binary) or ``.usd`` (binary); written
            under a temporary name and renamed when complete, with the umask's permissions.
        meters_per_unit: metres per stage unit (1.0 for a mesh in metres, 0.001 for mm).
        density: [kg/m^3].
        youngs_modulus: [Pa].
        damping: mass-proportional damping [1/s].
        anchor_stiffness: returning springs [N/m]; default 0.1 E pi r^2 / segment length.
        anchor_count: hubs anchored at each end (0: none).
        push: add ``/World/Push``: a force on the middle hub (:func:`push_force`), ramped from 0 at
            frame 0 to full at 24, held to 48, released at 60.
        name: tube prim name (default from :attr:`ExtractedTube.source`).
        up_axis: "Y" or "Z".
        end_time_code: last frame (24 per second).
        inputs: files the scene must not be written over (the mesh it was extracted from).
        final_name: the name the scene will have, where ``path_usda`` is a name it is edited under
            first (the scene's doc string names it); default ``path_usda``.

    Returns:
        The tube prim's path.

    Raises:
        SceneError: invalid arguments or an output path that cannot be written.
    """
    from pxr import Gf, Sdf, Usd, UsdGeom, Vt

    if not (math.isfinite(meters_per_unit) and meters_per_unit > 0.0):
        raise SceneError(f"meters_per_unit {meters_per_unit!r}: expected a positive finite number")
    if up_axis not in ("Y", "Z"):
        raise SceneError(f"up_axis {up_axis!r}: expected 'Y' or 'Z'")
    path_usda = output_path(path_usda, USD_EXTENSIONS, inputs=inputs, what="scene")
    TubeParams(density=density, youngs_modulus=youngs_modulus, damping=damping)  # validates
    tube_name = prim_name(name or extracted.source)
    n, spokes = extracted.spoke_lengths.shape
    k = anchor_stiffness if anchor_stiffness is not None else _anchor_stiffness(extracted, meters_per_unit,
                                                                                youngs_modulus)
    anchors = sorted(set(range(min(anchor_count, n))) | set(range(max(n - anchor_count, 0), n)))

    stage = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageMetersPerUnit(stage, float(meters_per_unit))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y if up_axis == "Y" else UsdGeom.Tokens.z)
    stage.SetTimeCodesPerSecond(24.0)
    stage.SetFramesPerSecond(24.0)
    stage.SetStartTimeCode(0.0)
    stage.SetEndTimeCode(float(end_time_code))
    world = UsdGeom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(world.GetPrim())
    ends = ", ".join(e.kind for e in extracted.ends)
    if extracted.ring is not None:
        ends += f" (a closed ring cut open, {extracted.ring.left_out:.0%} of its surface left out)"
    stage.GetRootLayer().documentation = (
        f"warp_tube scene extracted from {os.path.basename(str(extracted.source))}: {n} hubs x {spokes} spokes, "
        f"{extracted.tip_to_tip:.4g} units long tip to tip ({extracted.length:.4g} between its end hubs), ends {ends}, "
        f"{side_branches(len(extracted.branches))} left out.\n"
        "Success criteria: the tube bends smoothly under the push on its middle hub (frames 0-48), is "
        "released at frame 60 and returns to its extracted rest shape, held by its anchored ends.\n"
        f"Runs: `warp-tube run {os.path.basename(final_name or path_usda)}`."
    )

    curves = UsdGeom.BasisCurves.Define(stage, f"/World/{tube_name}")
    curves.CreateTypeAttr(UsdGeom.Tokens.linear)
    points = extracted.points.astype(np.float32)
    origin = _float32_origin(extracted.points)
    if origin is not None:  # (float32 points near the origin, placed by a double-precision translate)
        points = (extracted.points - origin).astype(np.float32)
        curves.AddTranslateOp(UsdGeom.XformOp.PrecisionDouble).Set(Gf.Vec3d(*origin.tolist()))
    widths = (2.0 * section_radius(extracted.spoke_lengths)).astype(np.float32)
    curves.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(points))
    curves.CreateCurveVertexCountsAttr(Vt.IntArray([n]))
    curves.CreateWidthsAttr(Vt.FloatArray.FromNumpy(widths))
    curves.SetWidthsInterpolation(UsdGeom.Tokens.vertex)
    # the prim's own bounds as usd-core finds them (its points padded by half the largest width),
    # which viewports cull by: not the mesh's, which the points and widths need not lie within
    curves.CreateExtentAttr(Vt.Vec3fArray.FromNumpy(curves_extent(points, half_width(widths))))
    prim = curves.GetPrim()
    D = Sdf.ValueTypeNames.Double
    prim.CreateAttribute("warptube:density", D).Set(float(density))
    prim.CreateAttribute("warptube:youngsModulus", D).Set(float(youngs_modulus))
    prim.CreateAttribute("warptube:damping", D).Set(float(damping))
    prim.CreateAttribute("warptube:spokes", Sdf.ValueTypeNames.Int).Set(int(spokes))
    prim.CreateAttribute("warptube:spokeLengths", Sdf.ValueTypeNames.FloatArray).Set(
        Vt.FloatArray.FromNumpy(extracted.spoke_lengths.reshape(-1).astype(np.float32))
    )
    prim.CreateAttribute("warptube:referenceNormal", Sdf.ValueTypeNames.Float3).Set(
        Gf.Vec3f(*extracted.reference_normal.astype(float))
    )
    prim.CreateAttribute("warptube:caps", Sdf.ValueTypeNames.Bool).Set(bool(extracted.caps))
    if anchors:
        prim.CreateAttribute("warptube:anchorPoints", Sdf.ValueTypeNames.IntArray).Set(Vt.IntArray(anchors))
        prim.CreateAttribute("warptube:anchorStiffness", D).Set(float(k))
    prim.SetCustomDataByKey("warptube:extractedFrom", os.path.basename(str(extracted.source)))
    prim.SetCustomDataByKey("warptube:ends", Vt.StringArray([e.kind for e in extracted.ends]))
    prim.SetCustomDataByKey("warptube:branches:junctionHubs", Vt.IntArray([int(j) for j, _ in extracted.branches]))
    prim.SetCustomDataByKey("warptube:branches:lengths", Vt.DoubleArray([float(x) for _, x in extracted.branches]))
    openings = extracted.openings
    prim.SetCustomDataByKey("warptube:openings:hubs", Vt.IntArray([o.hub for o in openings]))
    prim.SetCustomDataByKey("warptube:openings:radii", Vt.DoubleArray([o.radius for o in openings]))
    prim.SetCustomDataByKey("warptube:openings:kinds", Vt.StringArray([o.kind for o in openings]))

    if push:
        f = push_force(extracted, meters_per_unit, youngs_modulus)
        force = UsdGeom.Scope.Define(stage, "/World/Push").GetPrim()
        force.CreateRelationship("warptube:target").SetTargets([curves.GetPath()])
        force.CreateAttribute("warptube:point", Sdf.ValueTypeNames.Int).Set(int(n // 2))
        attr = force.CreateAttribute("warptube:force", Sdf.ValueTypeNames.Float3)
        for tc, scale in ((0.0, 0.0), (24.0, 1.0), (48.0, 1.0), (60.0, 0.0)):
            attr.Set(Gf.Vec3f(*(scale * f).astype(float)), tc)
        force.CreateAttribute("warptube:assistantLine", Sdf.ValueTypeNames.Bool).Set(True)

    def export(tmp: str):
        # The temporary name keeps the target's extension, so usd-core writes the format it names.
        if not stage.GetRootLayer().Export(tmp):
            raise SceneError(f"{path_usda}: cannot write")

    write_atomically(path_usda, export)
    return str(curves.GetPath())


def _attr_value(file: str, prim, name, types, start: float):
    """The attribute's value at the first frame (time code ``start``), or None where unauthored; a
    value authored as time samples, as DCC tools often write them, is read there (with a warning
    where the samples may differ: parameters are not animated)."""
    from pxr import Usd

    a = prim.GetAttribute(name)
    if not a or not a.HasAuthoredValue():
        return None
    if str(a.GetTypeName()) not in types:
        raise SceneError(f"{attribute_where(file, prim, name)}: found type {a.GetTypeName()}: expected {' or '.join(types)}")
    v = a.Get(Usd.TimeCode(start))
    if v is None:
        raise SceneError(f"{attribute_where(file, prim, name)}: no value at the first frame: expected a value (a default or time samples)")
    if samples_differ(a):
        log.warning("%s.%s: time-sampled: its value at the first frame (%s) is used for the whole run", prim.GetPath(), name, v)
    return v


def tube_from_mesh_prim(file: str, prim, info: StageInfo) -> TubeSpec:
    """Extract a tube from a ``Mesh`` prim with ``warptube:extract = true`` (scene loader hook).

    Reads ``warptube:hubs`` (int, default automatic), ``warptube:spokes`` (int, default 16) and the
    material attributes of a tube prim (``density`` required; ``youngsModulus`` or both
    ``stretchStiffness`` and ``bendStiffness``; ``damping``, ``springDamping``, ``anchorStiffness``,
    ``pinnedPoints`` and ``anchorPoints`` as hub indices, ``frames``, ``caps``). The mesh is taken
    in world space (parent transforms applied) at the earliest time sample. Without
    ``anchorPoints``, a positive ``anchorStiffness`` anchors the two first and two last hubs.

    Returns:
        The tube in SI metres, path = the prim's path; side branches in ``metadata["branches"]``.
    """
    where = f"{file}: {prim.GetPath()}"
    real = ("float", "double")
    t0 = info.start_time_code
    hubs = _attr_value(file, prim, "warptube:hubs", ("int", "int64", "uint"), t0)
    spokes = _attr_value(file, prim, "warptube:spokes", ("int", "int64", "uint"), t0)
    spokes = 16 if spokes is None else int(spokes)
    vals = {k: _attr_value(file, prim, f"warptube:{k}", real, t0) for k in (
        "density", "youngsModulus", "stretchStiffness", "bendStiffness", "damping", "springDamping",
        "anchorStiffness")}  # fmt: skip
    frames = _attr_value(file, prim, "warptube:frames", ("token", "string"), t0)
    caps = _attr_value(file, prim, "warptube:caps", ("bool",), t0)
    pinned = _attr_value(file, prim, "warptube:pinnedPoints", ("int[]", "int64[]"), t0)
    anchors = _attr_value(file, prim, "warptube:anchorPoints", ("int[]", "int64[]"), t0)
    if vals["density"] is None:
        raise SceneError(f"{where}.warptube:density: {missing(prim, ('warptube:density',))}: expected a float or double "
                         "[kg/m^3] (required)")  # fmt: skip
    for k, v in vals.items():
        if v is not None:
            check_attribute(attribute_where(file, prim, f"warptube:{k}"), f"warptube:{k}", float(v))
    if frames is not None and str(frames) not in FRAME_MODES:
        raise SceneError(f"{attribute_where(file, prim, 'warptube:frames')}: found {frames!r}: expected one of {', '.join(FRAME_MODES)}")
    from ..runtime.warp_setup import init_warp
    from .fidelity import surface_fidelity
    from .tube_check import tube_warnings

    init_warp()
    mesh = load_usd_mesh(prim, source=where)
    tube = extract_centerline(mesh, hubs=None if hubs is None else int(hubs), spokes=spokes, source=where)
    # as `warp-tube extract` has it: measured by the extraction on the mesh as it refined it (a coarse
    # mesh's long edges split: the raw one of a plain cylinder has no vertex to measure away from its ends)
    fid = tube.fidelity
    if fid is None and tube.hubs * tube.spokes <= 2_000_000:
        fid = surface_fidelity(tube, mesh)
    for w in tube_warnings(tube, fid, automatic_hubs=hubs is None, units="stage units"):
        log.warning("%s: %s", where, w)
    mpu = info.meters_per_unit
    n = tube.hubs
    outside = lengths_outside(section_radius(tube.spoke_lengths) * mpu, "the extracted tube's radius")
    if outside:
        raise SceneError(f"{where}: {outside}: expected {expected(RADIUS_M)}")
    k_anchor = float(vals["anchorStiffness"] or 0.0)
    if anchors is None:
        anchors = [0, 1, n - 2, n - 1] if k_anchor > 0.0 else []
    try:
        params = TubeParams(
            density=float(vals["density"]),
            youngs_modulus=None if vals["youngsModulus"] is None else float(vals["youngsModulus"]),
            stretch_stiffness=None if vals["stretchStiffness"] is None else float(vals["stretchStiffness"]),
            bend_stiffness=None if vals["bendStiffness"] is None else float(vals["bendStiffness"]),
            damping=float(vals["damping"] or 0.0), spring_damping=float(vals["springDamping"] or 0.0),
            anchor_stiffness=k_anchor, spokes=spokes, frames=str(frames or "rotationMinimizing"),
            caps=bool(caps) if caps is not None else tube.caps,
            reference_normal=tuple(float(x) for x in tube.reference_normal),
        )  # fmt: skip
        return TubeSpec(
            path=str(prim.GetPath()), points=tube.points * mpu, curve_counts=np.array([n]),
            radius=section_radius(tube.spoke_lengths) * mpu, params=params,
            pinned=np.asarray(pinned if pinned is not None else [], dtype=np.int64),
            anchors=np.asarray(anchors, dtype=np.int64), spoke_lengths=tube.spoke_lengths * mpu,
            metadata={"branches": [(j, x * mpu) for j, x in tube.branches], "extracted": True,
                      "ends": tuple(e.kind for e in tube.ends), "length_m": float(arclength(tube.points)[-1] * mpu)},
        )  # fmt: skip
    except SceneError as e:
        raise SceneError(f"{where}: {e}") from None
