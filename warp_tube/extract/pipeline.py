"""Centerline extraction: hubs and spokes of a tube from its surface mesh.

The seed paper's "distance mapping" (Wan et al. 2002) in five steps:

1. Clean the mesh, find its boundary loops: large loops are open ends, small ones holes; all are
   capped for the inside test (:mod:`warp_tube.extract.mesh_io`).
2. Distance-from-boundary field on inside voxels and its voxel graph (:mod:`warp_tube.extract.distance_map`).
3. End points: the two open ends farthest apart along the graph; for closed (capped) meshes the
   farthest pair found by a double sweep of geodesic distances. A most-centred path joins them;
   at a closed end the path's off-centre tail is cut and the path extended along its tangent to
   the cap; at an open end it runs to the loop centroid.
4. Smoothing and re-centring: each hub is moved to the centroid of its cross-section, measured
   by rays in its ring plane, then the polyline is resampled to N equally spaced hubs.
5. Spoke lengths: rays from each hub along the package's spoke directions
   (:func:`warp_tube.model.frames.rotation_minimizing_frames`, :func:`warp_tube.model.frames.spoke_directions`,
   reference normal :func:`warp_tube.model.frames.initial_normal` of the first tangent), nearest hit on
   the mesh; rays that miss (open ends, holes) take the value of the nearest hub along the tube
   that hit with the same spoke.

Side branches (e.g. of a coronary artery) are the parts of the inside farther than their own
diameter beyond the main tube's surface; each is reported with its junction hub and length.
Lengths are in the mesh's units after ``scale``.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field

import numpy as np
import trimesh
import warp as wp
from scipy.spatial import cKDTree

from . import distance_map as dmap
from ..model.frames import hub_tangents, initial_normal, rotation_minimizing_frames, spoke_directions
from ..kernels import raycast
from .branches import find_branches
from .fidelity import fidelity_of
from .mesh_io import BoundaryLoop, boundary_loops, cap_loops, clean_mesh
from .polyline import arclength, resample, smooth
from ..scene.spec import SceneError

__all__ = ["ExtractedTube", "TubeEnd", "Branch", "extract_centerline", "default_hub_count"]

log = logging.getLogger(__name__)

_END_LOOP_FRACTION = 0.3  # a boundary loop is an open end if its radius >= this x median tube radius
_RECENTRE_RAYS = 32
_RECENTRE_ITERATIONS = 3
_SMOOTH_RADII = 1.5  # smoothing of the re-centred line: sigma in units of the median distance from boundary
_OUTLIER_RATIO = 2.5  # a ray hit longer than this x its ring's median is not the tube's wall
# Default hub count: from one hub per mean radius, 1.5 times more until the rest surface rebuilt
# from hubs and spokes lies within these fractions of the mean radius of the mesh (mean, 95th
# percentile of vertex distances), or _MAX_AUTO_HUBS is reached.
_AUTO_FIDELITY = (0.04, 0.12)
_MAX_AUTO_HUBS = 1000


@dataclass(frozen=True)
class TubeEnd:
    """One end of the extracted tube.

    Attributes:
        kind: "open" (a boundary loop of the mesh) or "closed" (a capped end).
        center: position of the end hub [mesh units], shape (3,).
        radius: radius of the end loop, or distance from boundary at the end [mesh units].
    """

    kind: str
    center: np.ndarray
    radius: float


@dataclass(frozen=True)
class Branch:
    """A side branch left out of the tube.

    Attributes:
        junction_hub: index of the hub nearest to where the branch's centre path meets the tube.
        length: branch centre-path length from the junction to its tip [mesh units].
        path: the branch's centre path beyond the main tube's surface [mesh units], shape (k, 3).
    """

    junction_hub: int
    length: float
    path: np.ndarray


@dataclass
class ExtractedTube:
    """Hubs and spokes of a tube extracted from a mesh. Lengths in mesh units after scale.

    Attributes:
        points: hub positions, shape (hubs, 3), equally spaced along the centerline.
        spoke_lengths: shape (hubs, spokes); spoke j of hub i along
            ``spoke_directions(*rotation_minimizing_frames(points, None, reference_normal)[1:], S)[i, j]``.
        reference_normal: direction of spoke 0 at hub 0, unit, shape (3,).
        radius: mean spoke length per hub, shape (hubs,).
        branches: ``(junction_hub, length)`` per side branch left out.
        ends: the tube's first and last end.
        branch_details: the same branches with their paths.
        voxel_size: edge of the distance-map voxels.
        timings: seconds per stage (``"total"`` included).
        missed_spokes: rays that hit nothing and were filled from neighbouring hubs.
        source: where the mesh came from (file or prim), for messages and metadata.
    """

    points: np.ndarray
    spoke_lengths: np.ndarray
    reference_normal: np.ndarray
    radius: np.ndarray
    branches: list[tuple[int, float]]
    ends: tuple[TubeEnd, TubeEnd]
    branch_details: list[Branch] = field(default_factory=list)
    voxel_size: float = 0.0
    timings: dict[str, float] = field(default_factory=dict)
    missed_spokes: int = 0
    source: str = "<mesh>"

    @property
    def hubs(self) -> int:
        """Number of hubs."""
        return len(self.points)

    @property
    def spokes(self) -> int:
        """Spokes per hub."""
        return self.spoke_lengths.shape[1]

    @property
    def length(self) -> float:
        """Centerline length [mesh units]."""
        return float(arclength(self.points)[-1])

    def spoke_directions(self) -> np.ndarray:
        """Unit spoke directions at the hubs, shape (hubs, spokes, 3) (frames.py convention)."""
        _, r, s = rotation_minimizing_frames(self.points, None, self.reference_normal)
        return spoke_directions(r, s, self.spokes)

    def rings(self) -> np.ndarray:
        """Rest surface points ``hub + spoke_length * direction``, shape (hubs, spokes, 3)."""
        return self.points[:, None, :] + self.spoke_lengths[..., None] * self.spoke_directions()


def default_hub_count(length: float, mean_radius: float) -> int:
    """First hub count tried for a tube of ``length`` and ``mean_radius``: one per radius, 8 to 400."""
    return int(np.clip(round(length / max(mean_radius, 1e-12)) + 1, 8, 400))


class _Queries:
    """Warp meshes of the tube (real wall with holes closed; fully closed) and their queries."""

    def __init__(self, wall_v, wall_f, closed_v, closed_f, device):
        self.device = device
        self._keep = []
        self.wall = self._mesh(wall_v, wall_f)
        self.closed = self._mesh(closed_v, closed_f)

    def _mesh(self, v, f):
        pts = wp.array(np.asarray(v, dtype=np.float32), dtype=wp.vec3, device=self.device)
        idx = wp.array(np.asarray(f, dtype=np.int32).reshape(-1), dtype=wp.int32, device=self.device)
        m = wp.Mesh(points=pts, indices=idx)
        self._keep.append((pts, idx))
        return m

    def rays(self, mesh, origins, dirs, max_t) -> np.ndarray:
        """Nearest hit distance per ray, -1 on a miss; origins, dirs shape (..., 3)."""
        shp = np.shape(origins)[:-1]
        o = wp.array(np.asarray(origins, dtype=np.float32).reshape(-1, 3), dtype=wp.vec3, device=self.device)
        d = wp.array(np.asarray(dirs, dtype=np.float32).reshape(-1, 3), dtype=wp.vec3, device=self.device)
        out = wp.empty(o.shape[0], dtype=float, device=self.device)
        wp.launch(raycast.cast_rays, dim=o.shape[0], inputs=[mesh.id, o, d, float(max_t)], outputs=[out],
                  device=self.device)
        return out.numpy().astype(np.float64).reshape(shp)

    def distance(self, points, max_dist) -> np.ndarray:
        """Distance from each point to the wall, shape (n,)."""
        p = wp.array(np.asarray(points, dtype=np.float32).reshape(-1, 3), dtype=wp.vec3, device=self.device)
        out = wp.empty(p.shape[0], dtype=float, device=self.device)
        wp.launch(raycast.closest_distance, dim=p.shape[0], inputs=[self.wall.id, p, float(max_dist)],
                  outputs=[out], device=self.device)
        return out.numpy().astype(np.float64)

    def inner_diameters(self, mesh: trimesh.Trimesh, max_t: float, samples: int = 4000) -> np.ndarray:
        """Distances across the tube from up to ``samples`` face centroids (valid ones only)."""
        step = max(1, len(mesh.faces) // samples)
        c = np.asarray(mesh.triangles_center[::step])
        n = np.asarray(mesh.face_normals[::step])
        ok = np.isfinite(n).all(axis=1) & (np.linalg.norm(n, axis=1) > 0.5)
        c, n = c[ok], n[ok]
        pc = wp.array(c.astype(np.float32), dtype=wp.vec3, device=self.device)
        pn = wp.array(n.astype(np.float32), dtype=wp.vec3, device=self.device)
        out = wp.empty(len(c), dtype=float, device=self.device)
        offset = 1e-4 * max_t
        wp.launch(raycast.inner_diameter, dim=len(c), inputs=[self.closed.id, pc, pn, offset, float(max_t)],
                  outputs=[out], device=self.device)
        t = out.numpy().astype(np.float64)
        return t[t > 2.0 * offset]


def extract_centerline(
    mesh: trimesh.Trimesh,
    hubs: int | None = None,
    spokes: int = 16,
    scale=(1.0, 1.0, 1.0),
    device=None,
    *,
    source: str | None = None,
) -> ExtractedTube:
    """Extract hubs and spokes from a tube surface mesh.

    Args:
        mesh: the tube surface [mesh units]; open or capped ends, either face orientation.
        hubs: number of hubs N >= 2. Default: from :func:`default_hub_count` (one per mean radius)
            up, 1.5 times more each try, until the rest surface rebuilt from the hubs and spokes lies
            within 4 % (mean) and 12 % (95th percentile) of the mean radius of the mesh's vertices
            (ends and side branches left out; see :mod:`warp_tube.extract.fidelity`), at most 1000.
        spokes: spokes per hub S >= 3.
        scale: one factor or (fx, fy, fz) applied to the vertices first (e.g. CT voxel sizes).
        device: Warp device (default: Warp's default device).
        source: name of the mesh for messages (default: ``mesh.metadata["file_name"]`` or "<mesh>").

    Returns:
        The extracted tube, in mesh units after ``scale``.

    Raises:
        SceneError: the mesh is not a usable tube (see :func:`warp_tube.extract.mesh_io.clean_mesh`), encloses
            no volume, or is too thin to resolve.
    """
    t_start = time.perf_counter()
    timings: dict[str, float] = {}
    src = source or str(getattr(mesh, "metadata", {}).get("file_name", "<mesh>"))
    if hubs is not None and int(hubs) < 2:
        raise SceneError(f"hubs {hubs}: expected an integer >= 2")
    if not 3 <= int(spokes) <= 1024:
        raise SceneError(f"spokes {spokes}: expected an integer from 3 to 1024")
    device = wp.get_device(device)
    m = clean_mesh(mesh, src, scale)
    shift = 0.5 * (m.bounds[0] + m.bounds[1])  # work near the origin: float32 queries keep precision
    m = trimesh.Trimesh(np.asarray(m.vertices) - shift, m.faces, process=False)
    lo, hi = m.bounds
    diag = float(np.linalg.norm(hi - lo))

    loops = boundary_loops(m)
    closed_v, closed_f = cap_loops(m, loops)
    q = _Queries(closed_v, closed_f, closed_v, closed_f, device)  # provisional, for the radius estimate
    diam = q.inner_diameters(m, 2.0 * diag)
    if len(diam) < 3:
        raise SceneError(f"{src}: encloses no volume: expected a tube surface (open or closed ends)")
    r_med = 0.5 * float(np.median(diam))
    r_narrow = 0.5 * float(np.percentile(diam, 10))
    ends_loops = [lp for lp in loops if lp.radius >= _END_LOOP_FRACTION * r_med and len(lp.vertices) >= 5]
    holes = [lp for lp in loops if not any(lp is e for e in ends_loops)]
    if holes:
        log.info("%s: %d small holes closed", src, len(holes))
    wall_v, wall_f = cap_loops(m, holes)
    q = _Queries(wall_v, wall_f, closed_v, closed_f, device)
    timings["prepare"] = time.perf_counter() - t_start

    t0 = time.perf_counter()
    h = dmap.voxel_size_for(lo, hi, r_narrow)
    dm = dmap.build_distance_map(q.closed, q.wall, lo, hi, h, device)
    if dm.count < 16:
        raise SceneError(
            f"{src}: {dm.count} inside voxels of {h:.3g}: expected a tube enclosing volume (is it a closed or "
            "open-ended tube surface?)"
        )
    timings["distance_map"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    a, b, loop_a, loop_b = _end_points(dm, ends_loops)
    cdist, pred, _ = dmap.shortest_tree(dm.centred_graph, a)
    if not np.isfinite(cdist[b]):
        raise SceneError(f"{src}: its ends are not connected inside the mesh: expected one tube")
    voxel_path = dmap.trace_path(pred, b)
    if len(voxel_path) < 3:
        raise SceneError(f"{src}: the tube is {len(voxel_path)} voxels long: expected a longer tube")
    path = dm.points[voxel_path]
    d = dm.dfb[voxel_path]
    path, d, end0 = _finish_end(q, path, d, loop_a, h)
    path, d, end1 = _finish_end(q, path[::-1], d[::-1], loop_b, h)
    path, d = path[::-1], d[::-1]
    timings["path"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    length = float(arclength(path)[-1])
    r_path = float(np.median(d))
    dense = resample(path, max(8, int(np.ceil(length / (0.5 * r_path))) + 1))
    step = length / (len(dense) - 1)
    dense = smooth(dense, max(0.5 * r_path, h) / step)
    dense = resample(dense, len(dense))
    dense = _recentre(q, dense, diag)
    for at_end, end in ((False, end0), (True, end1)):
        if end[0] == "closed":
            dense = _extend_to_cap(q, dense[::-1] if at_end else dense, diag)
            dense = dense[::-1] if at_end else dense
    # Cross-section centroids of folded walls (haustra, rugae) wobble from one section to the next;
    # a simulated centerline should not. Gaussian smoothing with twicing (smooth, then add back the
    # smoothed residual) removes the wobble at a scale of a radius while leaving smooth bends
    # almost unshrunk (bias O(sigma^4 k^3) instead of sigma^2 k / 2).
    sigma = _SMOOTH_RADII * r_path / (length / (len(dense) - 1))
    smoothed = smooth(dense, sigma)
    dense = resample(smoothed + smooth(dense - smoothed, sigma), len(dense))
    timings["recentre"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    length = float(arclength(dense)[-1])
    d_ref = initial_normal(hub_tangents(dense)[0])
    dense_spokes, _ = _measure_spokes(q, dense, d_ref, 16, diag)
    used = [lp for lp in (loop_a, loop_b) if lp is not None]
    side_loops = [lp for lp in ends_loops if not any(lp is u for u in used)]
    found = find_branches(dm, voxel_path, dense, dense_spokes.max(axis=1), np.median(dense_spokes, axis=1),
                          side_loops)
    timings["branches"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    verts = np.asarray(m.vertices)
    branch_paths = [fb.path for fb in found]
    if hubs is not None:
        n = int(hubs)
    else:
        n = default_hub_count(length, r_med)
    while True:
        points = resample(dense, n)
        ref = initial_normal(hub_tangents(points)[0])
        spoke_len, missed = _measure_spokes(q, points, ref, int(spokes), diag)
        if hubs is not None or n >= _MAX_AUTO_HUBS:
            break
        fid = fidelity_of(points, spoke_len, ref, verts, branch_paths, device)
        if fid.mean <= _AUTO_FIDELITY[0] and fid.p95 <= _AUTO_FIDELITY[1]:
            break
        n = min(int(np.ceil(1.5 * n)), _MAX_AUTO_HUBS)
    timings["spokes"] = time.perf_counter() - t0

    hub_tree = cKDTree(points)
    branches = []
    for fb in found:
        jh = int(hub_tree.query(dense[fb.junction])[1])
        branches.append(Branch(jh, fb.length, fb.path + shift))
        log.info("%s: side branch (%s) at hub %d, %.4g long: left out of the tube", src, fb.kind, jh, fb.length)
    ends = (
        TubeEnd(end0[0], points[0] + shift, float(end0[1])),
        TubeEnd(end1[0], points[-1] + shift, float(end1[1])),
    )
    timings["total"] = time.perf_counter() - t_start
    return ExtractedTube(
        points=points + shift,
        spoke_lengths=spoke_len,
        reference_normal=ref,
        radius=spoke_len.mean(axis=1),
        branches=[(b_.junction_hub, b_.length) for b_ in branches],
        ends=ends,
        branch_details=branches,
        voxel_size=h,
        timings=timings,
        missed_spokes=missed,
        source=src,
    )


def _end_points(dm: dmap.DistanceMap, loops: list[BoundaryLoop]):
    """Voxel indices of the tube's two ends ``(a, b)`` and their loops (None for closed ends).

    Candidates are the voxels nearest to the open loops' centroids and the two extremes of a
    double sweep of geodesic distances (closed tips); the pair farthest apart along the voxel graph
    wins. An open loop is not necessarily an end: a cut-off side branch leaves a loop in the wall.
    """
    root = int(np.argmax(dm.dfb))
    d_root, _, _ = dmap.shortest_tree(dm.length_graph, root)
    fin = np.isfinite(d_root)
    reach = np.flatnonzero(fin)
    tree = cKDTree(dm.points[reach])
    cands = [int(reach[tree.query(lp.centroid)[1]]) for lp in loops[:8]]
    cand_loops: list[BoundaryLoop | None] = list(loops[:8])
    a = int(np.argmax(np.where(fin, d_root, -1.0)))
    d_a = dmap.shortest_tree(dm.length_graph, a)[0]
    b = int(np.argmax(np.where(np.isfinite(d_a), d_a, -1.0)))
    for x in (a, b):
        near = [i for i, lp in enumerate(cand_loops)
                if lp is not None and np.linalg.norm(dm.points[x] - lp.centroid) <= lp.radius + 2.0 * dm.voxel_size]
        if not near:  # a closed tip (an extreme next to an open loop is that open end)
            cands.append(x)
            cand_loops.append(None)
    dist = np.stack([dmap.shortest_tree(dm.length_graph, c)[0][cands] for c in cands])
    i, j = np.unravel_index(int(np.argmax(np.where(np.isfinite(dist), dist, -1.0))), dist.shape)
    return cands[i], cands[j], cand_loops[i], cand_loops[j]


def _finish_end(q: _Queries, path: np.ndarray, d: np.ndarray, loop: BoundaryLoop | None, h: float):
    """Make the start of a voxel path end where the tube ends.

    Open end: the path is prefixed with the loop centroid. Closed end: the path starts at the far
    rim of the cap (the farthest voxel); its points until the distance from boundary reaches 80 %
    of the nearby maximum are cut, and the path is extended along its tangent to the cap.

    Args:
        path: path points, shape (k, 3); d: their distance from boundary, shape (k,).

    Returns:
        ``(path (k', 3), d (k',), (kind, radius))``.
    """
    if loop is not None:
        return (np.concatenate([loop.centroid[None], path]), np.concatenate([[loop.radius], d]),
                ("open", loop.radius))
    s = arclength(path)
    k = len(path)
    i = 0
    for i in range(k // 3):
        win = (s >= s[i]) & (s <= s[i] + 3.0 * d[i] + 2.0 * h)
        if d[i] >= 0.8 * d[win].max():
            break
    reach = s[i] + 1.5 * max(d[i], h)
    j = min(int(np.searchsorted(s, reach)), k - 1)
    out = path[i] - path[j]
    norm = np.linalg.norm(out)
    info = ("closed", float(d[i]))
    if j == i or norm == 0.0:
        return path[i:], d[i:], info
    out = out / norm
    t = q.rays(q.closed, path[i][None], out[None], 4.0 * max(d[i], h) + 2.0 * h)[0]
    if t > 0.0:
        end = path[i] + out * max(t - 0.05 * d[i], 0.0)
        return np.concatenate([end[None], path[i:]]), np.concatenate([[0.05 * d[i]], d[i:]]), info
    return path[i:], d[i:], info


def _ring_hits(q: _Queries, points: np.ndarray, dirs: np.ndarray, diag: float):
    """Wall hit distances of rays from each hub, shape (n, R), and which of them are valid.

    A hit is valid when the ray stays inside the tube up to it: the same ray against the closed
    mesh (open ends and holes capped) hits nothing nearer, and it lies within 6 times the hub's
    distance from the wall (a ray that leaves through an open end may hit far parts) and within
    2.5 times the median of the ring's valid hits (elliptic sections of aspect up to ~3 pass).
    """
    origins = np.repeat(points[:, None, :], dirs.shape[1], axis=1)
    t = q.rays(q.wall, origins, dirs, diag)
    tc = q.rays(q.closed, origins, dirs, diag)
    dfb = q.distance(points, diag)
    valid = (t > 0.0) & (tc >= t - 1e-5 * diag) & (t < 6.0 * np.maximum(dfb, 1e-12)[:, None])
    # A ray much longer than the others of its ring ran into a side branch (or out of a bulge):
    # it does not belong to this tube's cross-section.
    med = np.array([np.median(ti[vi]) if vi.any() else np.inf for ti, vi in zip(t, valid)])
    valid &= t <= _OUTLIER_RATIO * med[:, None]
    return t, valid, dfb


def _recentre(q: _Queries, points: np.ndarray, diag: float) -> np.ndarray:
    """Move each point to the centroid of its cross-section (rays in its ring plane), smooth, respace."""
    p = np.asarray(points, dtype=np.float64).copy()
    phi = 2.0 * np.pi * np.arange(_RECENTRE_RAYS) / _RECENTRE_RAYS
    c, s_ = np.cos(phi), np.sin(phi)
    for it in range(_RECENTRE_ITERATIONS):
        _, r, s = rotation_minimizing_frames(p)
        t, hit, _ = _ring_hits(q, p, spoke_directions(r, s, _RECENTRE_RAYS), diag)
        good = hit.mean(axis=1) >= 0.75
        med = np.array([np.median(ti[hi]) if hi.any() else 0.0 for ti, hi in zip(t, hit)])
        t = np.where(hit, t, med[:, None])
        x, y = t * c, t * s_
        x1, y1 = np.roll(x, -1, axis=1), np.roll(y, -1, axis=1)
        cross = x * y1 - x1 * y
        area = 0.5 * cross.sum(axis=1)
        ok = good & (area > 0.0)
        safe = np.where(ok, area, 1.0)
        cx = ((x + x1) * cross).sum(axis=1) / (6.0 * safe)
        cy = ((y + y1) * cross).sum(axis=1) / (6.0 * safe)
        shift = cx[:, None] * r + cy[:, None] * s
        ok[[0, -1]] = False  # end hubs stay: open ends on their loop, closed ends re-extended later
        p[ok] += shift[ok]
        # Smoothing removes voxel noise but shrinks bends (by sigma^2 curvature / 2); the last pass
        # only respaces, so the final hubs sit on the measured centroids.
        p = resample(smooth(p, 1.0) if it < _RECENTRE_ITERATIONS - 1 else p, len(p))
    return p


def _extend_to_cap(q: _Queries, p: np.ndarray, diag: float) -> np.ndarray:
    """Move the first point to the cap, 10 % of the local radius inside it, along the line's
    tangent at the second point (from a quadratic through points 1-3, so bends extrapolate)."""
    if len(p) < 4:
        return p
    s = arclength(p[1:4])
    coef = np.polyfit(s, p[1:4], 2)  # (3, 3): rows t^2, t, 1
    out = -coef[1]
    out = out / max(np.linalg.norm(out), 1e-300)
    r1 = q.distance(p[1:2], diag)[0]
    t = q.rays(q.closed, p[1:2], out[None], diag)[0]
    if t > 0.0:
        p = p.copy()
        p[0] = p[1] + out * max(t - 0.1 * r1, 0.5 * t)
    return p


def _measure_spokes(q: _Queries, points: np.ndarray, ref: np.ndarray, spokes: int, diag: float):
    """Spoke lengths (hubs, spokes) by nearest ray hits; misses filled along the tube."""
    _, r, s = rotation_minimizing_frames(points, None, ref)
    t, hit, dfb = _ring_hits(q, points, spoke_directions(r, s, spokes), diag)
    missed = int((~hit).sum())
    if missed:
        idx = np.arange(len(points))
        for j in range(spokes):
            ok = hit[:, j]
            if ok.any():
                t[:, j] = np.where(ok, t[:, j], np.interp(idx, idx[ok], t[ok, j]))
            else:
                t[:, j] = np.nan
        rows = np.isnan(t).any(axis=1)
        if rows.any():
            fill = np.nanmean(t, axis=1)
            fill = np.where(np.isnan(fill), dfb, fill)
            t = np.where(np.isnan(t), fill[:, None], t)
    return np.maximum(t, 1e-6 * diag), missed
