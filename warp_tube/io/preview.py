"""Headless contact sheet of an output stage's Surface meshes (Warp ray casting, Pillow).

Each tile is one frame, rendered by an orthographic camera fitted to the bounding sphere of all
shown frames (so motion between tiles is visible at one scale), looking down a fixed oblique
direction with the stage's up axis up, with two-sided Lambert shading lit from the camera
(:func:`~warp_tube.kernels.shading.shade_orthographic_kernel` against a ``wp.Mesh``). Every tile
after the first shows the first frame's silhouette in light grey behind the tube, so that motion
small against the tube's size (a sag, a push of a few radii) shows. A tube thinner than a pixel,
which the rays would mostly miss, shows as its ``Centerline`` drawn one pixel wide.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import warp as wp

from .export import checked_points, open_output_stage, surface_at, surface_frames, surface_meshes
from ..kernels.shading import shade_orthographic_kernel
from ..scene.spec import SceneError

__all__ = ["preview"]

BACKGROUND = np.array([245, 245, 242], dtype=np.float64)
TISSUE = np.array([214, 120, 112], dtype=np.float64)
GHOST = np.array([222, 221, 216], dtype=np.float64)  # the first frame's silhouette behind later tiles
LABEL = (70, 70, 70)  # the frame label's colour (RGB)
LABEL_MIN_TILE = 96  # tiles smaller than this [pixels] get no label
log = logging.getLogger(__name__)

SHEET_COLUMNS = 8  # tiles per row of the sheet; more frames wrap into further rows
#: tiles on a sheet when none are asked for
DEFAULT_FRAMES = 4
THIN_SHADE = 0.6  # brightness of a centerline drawn where its tube is thinner than a pixel


def _centerlines_at(mesh, time, usd_path=None) -> list[np.ndarray]:
    """World-space points (P, 3) [stage units] of each curve of the ``Centerline`` beside a
    Surface mesh at a time code (none where there is no such BasisCurves, or it has no points).

    Raises:
        SceneError: naming the file, the prim and the time, where a point is not finite, or
            curveVertexCounts hold a count below 1 or do not sum to the points.
    """
    from pxr import UsdGeom

    curves = UsdGeom.BasisCurves(mesh.GetPrim().GetParent().GetChild("Centerline"))
    points = curves.GetPointsAttr().Get(time) if curves else None
    if points is None or len(points) == 0:
        return []
    prim = curves.GetPrim()
    pts = checked_points(points, prim, time, usd_path)
    counts = curves.GetCurveVertexCountsAttr().Get(time)
    counts = np.asarray([len(pts)] if counts is None or len(counts) == 0 else counts, dtype=np.int64)
    if counts.min() < 1 or counts.sum() != len(pts):
        raise SceneError(f"{usd_path or prim.GetStage().GetRootLayer().realPath}: {prim.GetPath()} at time "
                         f"{np.format_float_positional(float(time), trim='-')}: curveVertexCounts {_short(counts)} do not "
                         f"split its {len(pts):,} points into curves")  # fmt: skip
    xform = np.asarray(UsdGeom.XformCache(time).GetLocalToWorldTransform(prim), dtype=np.float64)
    pts = pts @ xform[:3, :3] + xform[3, :3]
    return np.split(pts, np.cumsum(counts)[:-1])


def _short(values) -> str:
    """An array in a message: ``[21]``, ``[3, 0, 5]``, ``[7, 7, 7, ... 7] (40 values)``."""
    values = [int(v) for v in values]
    if len(values) <= 6:
        return str(values)
    return f"[{', '.join(map(str, values[:3]))}, ... {values[-1]}] ({len(values):,} values)"


def _line_mask(polylines: list[np.ndarray], size: int) -> np.ndarray:
    """Boolean (size, size) image of polylines given in pixel coordinates (x right, y down), one
    pixel wide."""
    from PIL import Image, ImageDraw

    mask = Image.new("1", (size, size), 0)
    draw = ImageDraw.Draw(mask)
    for line in polylines:
        if len(line) > 1 and np.all(np.isfinite(line)):
            draw.line([tuple(p) for p in line], fill=1, width=1)
    return np.asarray(mask, dtype=bool)


def _pick_frames(times: list[float], count: int) -> list[float]:
    if len(times) <= count:
        return list(times)
    picks = np.round(np.linspace(0, len(times) - 1, count)).astype(int)
    return [times[i] for i in picks]


def preview(usd_path, png_path, frames: int | None = None, size: int = 320, device=None) -> Path:
    """Render ``frames`` evenly spaced frames of the Surface meshes side by side into a PNG
    (:data:`SHEET_COLUMNS` to a row, further rows below), the first and last frames included; each
    tile after the first shows the first frame's silhouette in light grey (:data:`GHOST`) behind.

    Args:
        usd_path: output stage written by ``warp-tube run``.
        png_path: the PNG to write (``.png``, in an existing folder); an existing file is replaced
            only by a complete image, and never the stage itself.
        frames: tiles (frames shown), >= 1; fewer if the stage has fewer samples (a warning says so
            where they were asked for); None: :data:`DEFAULT_FRAMES`.
        size: tile width and height [pixels].
        device: Warp device for the ray caster (default: Warp's default).

    Returns:
        The PNG path.

    Raises:
        SceneError: missing or unreadable stage, no Surface mesh, a Surface or Centerline that is
            not sound at a frame shown (no points, points not finite, faces or curves that do not
            match the points: :func:`~warp_tube.io.export.surface_at`), frames < 1, or a PNG path
            that cannot be written.
    """
    from PIL import Image
    from pxr import UsdGeom

    from ..runtime.warp_setup import init_warp
    from ..scene.files import output_path, write_atomically

    asked, frames = frames is not None, DEFAULT_FRAMES if frames is None else frames
    if frames < 1:
        raise SceneError(f"preview needs at least one frame, got {frames}")
    if not 1 <= size <= 8192:
        raise SceneError(f"preview tile size {size}: expected 1 to 8192 pixels")
    png_path = Path(output_path(png_path, (".png",), inputs=[usd_path], what="PNG"))
    usd_path = Path(usd_path)
    init_warp()
    stage = open_output_stage(usd_path)
    meshes = surface_meshes(stage, usd_path)
    times = surface_frames(meshes) or [stage.GetStartTimeCode()]
    if frames > len(times) and asked:  # (the default asks for no more than the stage has)
        log.warning("%s: %d frames asked for: the stage has %d, all shown", usd_path, frames, len(times))
    shown = _pick_frames(times, frames)

    geometry = []
    for time in shown:
        parts = [surface_at(m, time, usd_path) for m in meshes]
        offsets = np.cumsum([0] + [len(v) for v, _, _ in parts])
        verts = np.concatenate([v for v, _, _ in parts])
        faces = np.concatenate([f + o for (_, f, _), o in zip(parts, offsets)])
        geometry.append((verts, faces, [c for m in meshes for c in _centerlines_at(m, time, usd_path)]))
    all_points = np.concatenate([v for v, _, _ in geometry])
    if not np.all(np.isfinite(all_points)):
        raise SceneError(f"{usd_path}: Surface points are not finite")
    lo, hi = all_points.min(axis=0), all_points.max(axis=0)
    centre = 0.5 * (lo + hi)
    radius = max(0.5 * float(np.linalg.norm(hi - lo)), 1e-9)

    if UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z:
        world_up, toward_camera = np.array([0.0, 0.0, 1.0]), np.array([0.55, -1.0, 0.45])
    else:
        world_up, toward_camera = np.array([0.0, 1.0, 0.0]), np.array([0.55, 0.45, 1.0])
    view_dir = -toward_camera / np.linalg.norm(toward_camera)
    right = np.cross(view_dir, world_up)
    right /= np.linalg.norm(right)
    up = np.cross(right, view_dir)
    origin = centre - 2.0 * radius * view_dir
    pixel = 2.1 * radius / size

    device = wp.get_device(device)
    columns = min(len(shown), SHEET_COLUMNS)  # many frames wrap into rows
    rows = -(-len(shown) // columns)
    sheet = np.empty((size * rows, size * columns, 3), dtype=np.uint8)
    sheet[:] = BACKGROUND.astype(np.uint8)  # (a last row's empty tiles)
    image = wp.zeros((size, size), dtype=float, device=device)
    first = None  # the first frame's silhouette, drawn behind the later tiles
    for k, (verts, faces, lines) in enumerate(geometry):
        mesh = wp.Mesh(
            points=wp.array(verts.astype(np.float32), dtype=wp.vec3, device=device),
            indices=wp.array(faces.reshape(-1).astype(np.int32), dtype=wp.int32, device=device),
        )
        wp.launch(
            shade_orthographic_kernel,
            dim=(size, size),
            inputs=[mesh.id, wp.vec3(*origin), wp.vec3(*right), wp.vec3(*up), wp.vec3(*view_dir), pixel, 4.0 * radius],
            outputs=[image],
            device=device,
        )
        shade = image.numpy()[..., None].astype(np.float64)
        # a tube thinner than a pixel, which the rays mostly miss, is drawn as its centerline
        projected = [np.c_[(c - centre) @ right / pixel + 0.5 * size, 0.5 * size - (c - centre) @ up / pixel] for c in lines]
        thin = _line_mask(projected, size)[..., None] & (shade < 0.0)
        shade = np.where(thin, THIN_SHADE, shade)
        if first is None:
            first = shade >= 0.0
        behind = np.where(first, GHOST, BACKGROUND) if k > 0 else BACKGROUND
        tile = np.where(shade < 0.0, behind, TISSUE * np.clip(shade, 0.0, 1.0))
        r, c = divmod(k, columns)
        sheet[r * size : (r + 1) * size, c * size : (c + 1) * size] = np.clip(np.round(tile), 0, 255).astype(np.uint8)
    picture = Image.fromarray(sheet)
    if size >= LABEL_MIN_TILE:  # each tile's time code at its bottom left (too small a tile: none)
        from PIL import ImageDraw

        draw = ImageDraw.Draw(picture)
        for k, time in enumerate(shown):
            r, c = divmod(k, columns)
            draw.text((c * size + 6, (r + 1) * size - 16), f"frame {time:g}", fill=LABEL)
    write_atomically(png_path, lambda tmp: picture.save(tmp, format="PNG"))
    return png_path
