"""Centerline extraction: hubs and spokes of a tube from its surface mesh.

The seed paper's "distance mapping" (Wan et al. 2002), with the hubs put on the tube's axis and the
rings made so that the simulator rebuilds the input at rest:

1. Clean the mesh, find its boundary loops: loops of a tube's size are open ends or openings, small
   ones holes; all are capped for the inside test (:mod:`warp_tube.extract.mesh_io`), and flat faces
   that seal cut ends are found. The tube's size is measured first: chords across it from its wall,
   checked against widths from inside, which a rough wall (a scan's or a segmentation's noise) does
   not fool (:mod:`warp_tube.extract.scale`).
2. Distance-from-boundary field on inside voxels and its voxel graph (:mod:`warp_tube.extract.distance_map`).
3. Ends (:mod:`warp_tube.extract.ends`): at open loops where the mesh ends, then sealed cuts, else
   (closed meshes) the two ends of the longest geodesic; a most-centred voxel path joins them.
   Openings that are not ends are closed like holes for what follows.
4. Axis: the path, resampled densely, is moved onto the centroids of its cross-sections (rays in
   the plane normal to it, :mod:`warp_tube.extract.sections`); its ends are trimmed to complete
   sections at open loops and sealed cuts, and fitted to the simulator's cap at rounded tips.
5. Hubs: N points equally spaced along the cubic spline through the axis (the open and cut ends
   trimmed until the end rings, normal to their edges, lie inside the mesh), each then re-centred in
   its own ring plane (the simulator's, normal to the bisector tangent); spoke lengths by rays along
   the simulator's spoke directions (:func:`warp_tube.model.frames.rotation_minimizing_frames`,
   :func:`warp_tube.model.frames.spoke_directions`, reference normal
   :func:`warp_tube.model.frames.initial_normal` of the first tangent, turned onto the sections' long
   axis where they are flat, :mod:`warp_tube.extract.flat`), fitted to rays between
   them too (:func:`warp_tube.extract.sections.fit_polygon`). By default the hub count
   grows until the measured rings cover the mesh to :data:`AUTO_FIDELITY`.
6. Rest surface: where the simulator's inner-bend guard would cut a ring at rest, the axis is
   smoothed there, or its hubs pushed away from the bend's centre (:mod:`warp_tube.extract.rings`);
   the simulator's own rebuild (guard and caps included, :mod:`warp_tube.extract.fidelity`) is then
   compared with the mesh both ways.

Side branches (e.g. of a coronary artery) are the parts of the inside farther than their own
diameter beyond the main tube's surface; each is reported with its junction hub and length. The
tube-likeness check (:mod:`warp_tube.extract.tubelike`) warns about inputs that are not tubes. A
closed ring (a torus: watertight, ``V - E + F = 0``) has no ends: it is cut open across a gap of
about one tube radius at its widest point, its two ends cut ends sealed by the gap's planes, and the
tube records where and how much of the ring it leaves out (:mod:`warp_tube.extract.closed_ring`). Lengths are in the mesh's units after ``scale``.
"""

from __future__ import annotations

import dataclasses
import logging
import time
from dataclasses import dataclass, field

import numpy as np
import trimesh
import warp as wp
from scipy.spatial import cKDTree

from . import distance_map as dmap, wording
from ..model.frames import hub_tangents, initial_normal, rotation_minimizing_frames, spoke_directions
from ..scene.spec import SceneError
from .branches import find_branches
from .closed_ring import RingCut, is_closed_ring, open_ring, ring_cut
from .flat import ALIGN_ASPECT, SPOKES, default_spokes, long_axis_turn, section_aspect, turned_normal
from .ends import choose_ends, cut_closed_tail, fit_closed_end, settle_end, trim_open_end
from .fidelity import Distances, Fidelity, fidelity_of, measured_branch_path, measured_vertices, mesh_distances, plain_surface
from .mesh_io import BoundaryLoop, boundary_loops, cap_loops, clean_mesh, flat_cuts
from .polyline import arclength, project_points, resample, resample_spline, smooth
from .queries import MeshQueries
from .scale import rough_scale, tube_scale
from .sections import bridged_branch, measure_spokes, open_rays, recentre, recentre_hubs

__all__ = ["ExtractedTube", "TubeEnd", "Branch", "Opening", "extract_centerline", "default_hub_count", "AUTO_FIDELITY"]

log = logging.getLogger(__name__)

_END_LOOP_FRACTION = 0.3  # a boundary loop may be an end if its radius >= this x median tube radius
_CUT_AREA = 0.25  # a flat face may seal a cut end if its area >= this x pi x median tube radius^2
_DENSE_SPACING = 0.5  # spacing of the dense axis, in median distances from the wall
#: a mesh's edges are split to at most this fraction of its bounds' diagonal before the extraction
_MAX_EDGE_FRACTION = 1.0 / 32.0


def _refined(m: trimesh.Trimesh) -> trimesh.Trimesh:
    """A coarse ``m`` with every edge longer than :data:`_MAX_EDGE_FRACTION` of its bounds'
    diagonal split: the same surface, finer triangles. Coarse: half the edges' total length is in
    edges longer than that (their length-weighted median), as in a box of 12 triangles, or a
    cylinder or capsule whose wall has vertices at its end rings only (whatever its length: its few
    long edges hold most of the length, however many short ones its rings and caps have). The
    extraction samples the wall at the mesh's vertices (the radius estimate, the fit of the rebuilt
    surface): such a mesh is then sampled as a fine mesh of the same shape would be. Any other mesh
    comes back as it is (a fine mesh's few long edges, e.g. across a flat cut, are left alone)."""
    limit = _MAX_EDGE_FRACTION * float(np.linalg.norm(m.bounds[1] - m.bounds[0]))
    if not len(m.edges_unique) or _weighted_median(np.asarray(m.edges_unique_length, dtype=np.float64)) <= limit:
        return m
    v, f = trimesh.remesh.subdivide_to_size(m.vertices, m.faces, max_edge=limit, max_iter=16)
    out = trimesh.Trimesh(v, f, process=False)
    out.merge_vertices()  # (the new vertices on an edge two faces share, once)
    return out


def _branch_radius(q: MeshQueries, path: np.ndarray, diag: float) -> float:
    """A side branch's radius [mesh units]: the largest distance from the wall of its points
    (``path``: its inside voxels beyond the tube's cover, or the points of a cut one)."""
    return float(q.distance(path, diag).max()) if len(path) else 0.0


def _weighted_median(lengths: np.ndarray) -> float:
    """The length-weighted median of ``lengths``: half their total is in lengths at least this."""
    x = np.sort(lengths)
    total = np.cumsum(x)
    return float(x[np.searchsorted(total, 0.5 * total[-1])])


AUTO_FIDELITY = (0.03, 0.12, 0.35)
"""Default hub count: from one hub per mean radius, 1.5 times more until the mesh's vertices (ends
and side branches left out) lie within these fractions of the mean radius (mean, 99th percentile,
largest) of the surface of the measured rings and the end rings are as round as the mesh allows
(:data:`END_RATIO_SLACK`), or more hubs stop helping, or the least hub spacing is reached; the
count that came closest is kept. What hub spacing misses falls with its square: a try that lowered
the score by a fraction ``x`` of it foretells about ``0.44 x`` for the next, so more hubs stop
helping where the last try lowered it by less than 10 % (on a rough wall, each try follows the
noise a little closer, by 5 to 8 %, and only that)."""
END_RATIO_SLACK = 1.25
"""Default hub count: the end rings' spoke ratios (longest over shortest) are to stay within this
factor of those of the rings one hub in (the mesh's own section there), like the fidelity."""
MAX_AUTO_HUBS = 1000
_MIN_SPACING = 0.3  # least automatic hub spacing, in median tube radii
_HELPS = 0.9  # more hubs help while the last try lowered the hub-count score below this x the one before


@dataclass(frozen=True)
class TubeEnd:
    """One end of the extracted tube.

    Attributes:
        kind: "open" (at a boundary loop of the mesh), "closed" (a rounded tip: capped when both
            ends are) or "cut" (closed by a flat cut: trimmed, left open).
        center: position of the end hub [mesh units], shape (3,).
        radius: mean spoke length of the end hub [mesh units].
        tip: where the mesh ends [mesh units], shape (3,): the open loop's centre, or where the
            axis continued from the end hub meets the closed surface.
        trimmed: distance from the tip to the end hub [mesh units].
        seal: for a "cut" end, the flat face that seals the mesh there: ``(point (3,), outward unit
            normal (3,), radius)`` [mesh units]; None otherwise.
    """

    kind: str
    center: np.ndarray
    radius: float
    tip: np.ndarray
    trimmed: float
    seal: tuple | None = None


@dataclass(frozen=True)
class Branch:
    """A side branch left out of the tube.

    Attributes:
        junction_hub: index of the hub nearest to where the branch's centre path meets the tube.
        length: branch centre-path length from the junction to its tip [mesh units].
        path: the branch's centre path beyond the main tube's surface [mesh units], shape (k, 3).
        bridged: the tube's sections by its junction were bridged over its mouth
            (:func:`~warp_tube.extract.sections.bridged_branch`).
    """

    junction_hub: int
    length: float
    path: np.ndarray
    bridged: bool = False


@dataclass(frozen=True)
class Opening:
    """An open boundary loop of the mesh that is not one of the tube's ends.

    Attributes:
        hub: index of the hub nearest to its centre.
        radius: mean distance of its vertices from its centre [mesh units].
        vertices: number of its vertices.
        distance: distance of its centre from the centerline [mesh units].
        kind: "wall" (an opening in the tube's wall: the tube is kept across it) or "branch" (the
            loop closes a side branch that is left out).
    """

    hub: int
    radius: float
    vertices: int
    distance: float
    kind: str


@dataclass
class ExtractedTube:
    """Hubs and spokes of a tube extracted from a mesh. Lengths in mesh units after scale.

    Attributes:
        points: hub positions, shape (hubs, 3), about equally spaced along the centerline.
        spoke_lengths: shape (hubs, spokes); spoke j of hub i along
            ``spoke_directions(*rotation_minimizing_frames(points, None, reference_normal)[1:], S)[i, j]``.
        reference_normal: direction of spoke 0 at hub 0, unit, shape (3,).
        radius: mean spoke length per hub, shape (hubs,).
        branches: ``(junction_hub, length)`` per side branch left out.
        ends: the tube's first and last end.
        branch_details: the same branches with their paths.
        openings: open loops that are not ends, with their size.
        voxel_size: edge of the distance-map voxels.
        timings: seconds per stage (``"total"`` included).
        missed_spokes: rays whose hit did not belong to the tube's section (filled along the tube).
        fidelity: the rest surface against the mesh (:class:`~warp_tube.extract.fidelity.Fidelity`).
        warnings: what the tube-likeness and hub-count checks found (also logged).
        source: where the mesh came from (file or prim), for messages and metadata.
        ring: for a closed ring (a mesh with no ends), where it was cut open and how much the tube
            leaves out (:class:`~warp_tube.extract.closed_ring.RingCut`, cuts in mesh units); else None.
        aspect: the cross-sections' median aspect, long over short axis (:mod:`warp_tube.extract.flat`).
    """

    points: np.ndarray
    spoke_lengths: np.ndarray
    reference_normal: np.ndarray
    radius: np.ndarray
    branches: list[tuple[int, float]]
    ends: tuple[TubeEnd, TubeEnd]
    branch_details: list[Branch] = field(default_factory=list)
    openings: list[Opening] = field(default_factory=list)
    voxel_size: float = 0.0
    timings: dict[str, float] = field(default_factory=dict)
    missed_spokes: int = 0
    fidelity: Fidelity | None = None
    warnings: list[str] = field(default_factory=list)
    source: str = "<mesh>"
    ring: RingCut | None = None
    aspect: float = 1.0

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

    @property
    def tip_to_tip(self) -> float:
        """Length from end to end [mesh units]: the hubs' span and what was trimmed at the ends."""
        return self.length + sum(e.trimmed for e in self.ends)

    @property
    def caps(self) -> bool:
        """Whether the scene closes the tube with caps (both ends rounded and closed)."""
        return all(e.kind == "closed" for e in self.ends)

    def spoke_directions(self) -> np.ndarray:
        """Unit spoke directions at the hubs, shape (hubs, spokes, 3) (frames.py convention)."""
        _, r, s = rotation_minimizing_frames(self.points, None, self.reference_normal)
        return spoke_directions(r, s, self.spokes)

    def rings(self) -> np.ndarray:
        """Rest rings ``hub + spoke_length * direction`` (no guard), shape (hubs, spokes, 3)."""
        return self.points[:, None, :] + self.spoke_lengths[..., None] * self.spoke_directions()


def default_hub_count(length: float, mean_radius: float) -> int:
    """First hub count tried for a tube of ``length`` and ``mean_radius``: one per radius, 8 to 400."""
    return int(np.clip(round(length / max(mean_radius, 1e-12)) + 1, 8, 400))


def extract_centerline(
    mesh: trimesh.Trimesh,
    hubs: int | None = None,
    spokes: int | None = None,
    scale=(1.0, 1.0, 1.0),
    device=None,
    *,
    source: str | None = None,
    strict: bool = False,
) -> ExtractedTube:
    """Extract hubs and spokes from a tube surface mesh.

    Args:
        mesh: the tube surface [mesh units]; open or capped ends, either face orientation.
        hubs: number of hubs N >= 3. Default: from :func:`default_hub_count` (one per mean radius)
            up, 1.5 times more each try, until the simulator's rest surface meets
            :data:`AUTO_FIDELITY` both ways (at most :data:`MAX_AUTO_HUBS`). With a given count
            that misses the bounds of the README (4 % / 15 % / 40 %), a warning names the figures.
        spokes: spokes per hub S >= 3; None: 16, or 32 where the sections are flat
            (:func:`~warp_tube.extract.flat.default_spokes`).
        scale: one factor or (fx, fy, fz) applied to the vertices first (e.g. CT voxel sizes).
        device: Warp device (default: Warp's default device).
        source: name of the mesh for messages (default: ``mesh.metadata["file_name"]`` or "<mesh>").
        strict: refuse (SceneError) a mesh that fails the tube-likeness check instead of warning.

    Returns:
        The extracted tube, in mesh units after ``scale``.

    Raises:
        SceneError: the mesh is not a usable tube (see :func:`warp_tube.extract.mesh_io.clean_mesh`), encloses
            no volume, is too thin to resolve, or (with ``strict``) is not tube-like.
    """
    from . import rings, tubelike

    t_start = time.perf_counter()
    timings: dict[str, float] = {}
    src = source or str(getattr(mesh, "metadata", {}).get("file_name", "<mesh>"))
    if hubs is not None and int(hubs) < 3:
        # (two hubs are the tube's two ends, where its section is not measured: rays across a cut
        # or an open end meet no wall)
        raise SceneError(f"hubs {hubs}: expected an integer >= 3 (the tube's radius is measured at hubs between its ends)")
    if spokes is not None and not 3 <= int(spokes) <= 1024:
        raise SceneError(f"spokes {spokes}: expected an integer from 3 to 1024")
    spokes = None if spokes is None else int(spokes)
    device = wp.get_device(device)
    m = clean_mesh(mesh, src, scale)
    shift = 0.5 * (m.bounds[0] + m.bounds[1])  # work near the origin: float32 queries keep precision
    m = _refined(trimesh.Trimesh(np.asarray(m.vertices) - shift, m.faces, process=False))
    lo, hi = m.bounds
    diag = float(np.linalg.norm(hi - lo))

    loops = boundary_loops(m)
    closed_v, closed_f = cap_loops(m, loops)
    q = MeshQueries(closed_v, closed_f, closed_v, closed_f, device)  # provisional, for the radius estimate
    diam = q.inner_diameters(m, 2.0 * diag)
    if len(diam) < 3:
        raise SceneError(f"{src}: encloses no volume: expected a tube surface (open or closed ends)")
    size = tube_scale(q, diam, lo, hi, diag)
    if size.rough:
        size = rough_scale(size, closed_v, closed_f, lo, hi, diag, device)
    r_med, r_narrow = size.median, size.narrow
    if size.rough:
        log.info("%s: rough wall: chords across the tube from its wall cross folds of it; its radius, from the wall and a "
                 "smoothed copy of it: median %.4g, narrow %.4g", src, r_med, r_narrow)  # fmt: skip
    end_size = [lp for lp in loops if lp.radius >= _END_LOOP_FRACTION * r_med and len(lp.vertices) >= 5]
    holes = [lp for lp in loops if not any(lp is e for e in end_size)]
    if holes:
        log.info("%s: %s closed", src, wording.counted(len(holes), "small hole"))
    wall_v, wall_f = cap_loops(m, holes)
    q = MeshQueries(wall_v, wall_f, closed_v, closed_f, device, raw=(m.vertices, m.faces))
    timings["prepare"] = time.perf_counter() - t_start

    t0 = time.perf_counter()
    h = dmap.voxel_size_for(lo, hi, r_narrow)
    dm = dmap.build_distance_map(q.closed, q.wall, lo, hi, h, device)
    if dm.count < 16:
        raise SceneError(
            f"{src}: {wording.counted(dm.count, 'inside voxel')} of {h:.3g}: expected a tube enclosing volume (is it "
            "a closed or open-ended tube surface?)" + dmap.coarse_grid_note(lo, hi, r_narrow, h)
        )
    timings["distance_map"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    opened = open_ring(dm) if is_closed_ring(m) else None  # a closed ring: cut open across a small gap
    if opened is not None:
        choice, graph = opened.choice, opened.graph
    else:
        cuts = flat_cuts(m, _CUT_AREA * np.pi * r_med**2, depth=lambda o, d: q.rays(q.closed, o, d, 2.0 * diag))
        choice, graph = choose_ends(dm, end_size, cuts), dm.centred_graph
    if choice.others:  # openings that are not ends are part of the tube's wall: closed, like holes
        q = MeshQueries(*cap_loops(m, holes + choice.others), closed_v, closed_f, device, raw=(m.vertices, m.faces))
    cdist, pred, _ = dmap.shortest_tree(graph, choice.a)
    if not np.isfinite(cdist[choice.b]):
        raise SceneError(f"{src}: its ends are not connected inside the mesh: expected one tube")
    voxel_path = dmap.trace_path(pred, choice.b)
    if len(voxel_path) < 3:
        raise SceneError(f"{src}: the tube is {wording.counted(len(voxel_path), 'voxel')} long: expected a longer "
                         "tube" + dmap.coarse_grid_note(lo, hi, r_narrow, h))  # fmt: skip
    path, d = dm.points[voxel_path], dm.dfb[voxel_path]
    path, d = _open_or_cut(path, d, choice.end_a, h, size.rough)
    path, d = _open_or_cut(path[::-1], d[::-1], choice.end_b, h, size.rough)
    path, d = path[::-1], d[::-1]
    timings["path"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    length = float(arclength(path)[-1])
    r_path = float(np.median(d))
    count = max(8, int(np.ceil(length / (_DENSE_SPACING * r_path))) + 1)
    dense = smooth(resample(path, count), 1.0)
    aspect = section_aspect(q, dense, diag)
    q.flat = aspect > ALIGN_ASPECT  # (a local flat spot, a merged hairpin's apex, is not)
    if spokes is None:
        spokes = default_spokes(aspect)
        if spokes != SPOKES:
            log.info("%s: flat sections (aspect %.1f:1): %d spokes a hub", src, aspect, spokes)
    move = np.ones(len(dense), dtype=bool)
    open_a, open_b = (isinstance(e, BoundaryLoop) for e in (choice.end_a, choice.end_b))
    move[[0, -1]] = [not open_a, not open_b]  # a loop's centre stays; closed ends centre
    dense = recentre(q, dense, diag, move=move)
    ends = []
    for at_end, end in ((False, choice.end_a), (True, choice.end_b)):
        line = dense[::-1] if at_end else dense
        seal = None
        if isinstance(end, BoundaryLoop):
            tip = end.centroid.copy()
            line, _ = trim_open_end(q, line, diag, 1.5 * end.radius)
            kind = "open"
        else:
            line, tip, kind, seal = fit_closed_end(q, line, diag, spokes, end, own=opened is not None)
        dense = line[::-1] if at_end else line
        ends.append((kind, tip, seal))
    dense = recentre(q, resample_spline(dense, max(8, len(dense))), diag, iterations=2)
    timings["axis"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    length = float(arclength(dense)[-1])
    d_ref = initial_normal(hub_tangents(dense)[0])
    dense_spokes, _ = measure_spokes(q, dense, d_ref, 16, diag)
    r_dense = np.median(dense_spokes, axis=1)
    found = find_branches(dm, voxel_path, dense, dense_spokes.max(axis=1), r_dense, choice.others)
    r_tube = float(np.median(r_dense))
    bridged = [bridged_branch(fb.length, _branch_radius(q, fb.path, diag), r_tube) for fb in found]
    if any(bridged):  # the hubs' sections by such a branch's junction leave its mouth out
        at = np.array([fb.junction for fb, b in zip(found, bridged) if b])
        q.junctions = (dense[at], r_dense[at])
    timings["branches"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    caps = all(e[0] == "closed" for e in ends)
    seals = [e[2] for e in ends if e[2] is not None]
    max_hubs = int(min(MAX_AUTO_HUBS, max(8, np.floor(length / (_MIN_SPACING * r_med)) + 1)))
    tips = np.stack([ends[0][1], ends[1][1]])
    branch_paths = [fb.path for fb in found]
    rooted = [measured_branch_path(fb.path, dense[fb.junction], b) for fb, b in zip(found, bridged)]
    verts = np.asarray(m.vertices)
    end_radius = dense_spokes.mean(axis=1)
    counted = measured_vertices(dense, end_radius[0], end_radius[-1], verts, tips, rooted, seals)
    n = int(hubs) if hubs is not None else default_hub_count(length, r_med)
    tried = []
    while True:
        # The hub count is chosen on the rings as measured: their spoke ends lie on the mesh, so what
        # the count changes is how closely the strips between rings follow it.
        line = dense
        for k, (kind, _, seal) in enumerate(ends):  # open and cut ends: end rings inside the mesh
            if kind != "closed":
                line = settle_end(q, line[::-1], n, diag, spokes, seal)[::-1] if k else \
                    settle_end(q, line, n, diag, spokes, seal)  # fmt: skip
        points = recentre_hubs(q, resample_spline(line, n), diag, r_path)
        tangent0 = hub_tangents(points)[0]
        lengths, _ = measure_spokes(q, points, initial_normal(tangent0), spokes, diag)
        turn = long_axis_turn(lengths)  # (0 but for flat sections: spokes onto their long axes)
        ref = turned_normal(tangent0, turn)
        if turn:
            lengths, _ = measure_spokes(q, points, ref, spokes, diag)
        cover = Distances.of(mesh_distances(verts[counted], *plain_surface(points, lengths, ref), device),
                             float(lengths.mean()))  # fmt: skip
        score = max(cover.mean / AUTO_FIDELITY[0], cover.p99 / AUTO_FIDELITY[1], cover.max / AUTO_FIDELITY[2],
                    _end_excess(lengths))  # fmt: skip
        tried.append((score, n, points, turn))
        log.debug("hubs %d: coverage %.4f %.4f %.4f score %.4f", n, cover.mean, cover.p99, cover.max, score)
        if hubs is not None or score <= 1.0 or n >= max_hubs:
            break
        if len(tried) > 1 and score > _HELPS * tried[-2][0]:
            break  # more hubs stopped helping: what is left, more do not change (a rough wall's noise)
        n = min(int(np.ceil(1.5 * n)), max_hubs)
    _, n, points, turn = min(tried, key=lambda x: x[:2])
    kept = rings.keep_guard_clear(q, rings.rest_rings(q, points, spokes, caps, diag, device, turn), caps, diag,
                                  verts[counted], device, turn)  # fmt: skip
    points, spoke_len, ref, valid = kept.points, kept.lengths, kept.reference_normal, kept.valid
    fid = fidelity_of(points, spoke_len, ref, caps, m.vertices, m.faces, tips=tips, branch_paths=rooted,
                      seals=seals, device=device, wall=cap_loops(m, choice.others))  # fmt: skip
    ring = None if opened is None else ring_cut(m, points, spoke_len, tips, branch_paths)
    timings["hubs"] = time.perf_counter() - t0

    hub_tree = cKDTree(points)
    branches = []
    for k, fb in enumerate(found):
        jh = int(hub_tree.query(dense[min(fb.junction, len(dense) - 1)])[1])
        if ring is not None and k in ring.rest:
            log.info("%s: the rest of the closed ring, from hub %d, %.4g long: left out of the tube", src, jh,
                     fb.length)
            continue
        branches.append(Branch(jh, fb.length, fb.path + shift, bridged[k]))
        log.info("%s: side branch (%s) at hub %d, %.4g long: left out of the tube", src, fb.kind, jh, fb.length)
    openings = _openings(choice.others, spoke_len, hub_tree, src)
    radius = spoke_len.mean(axis=1)
    tube_ends = tuple(
        TubeEnd(kind, points[i] + shift, float(radius[i]), tip + shift, float(np.linalg.norm(tip - points[i])),
                None if seal is None else (seal[0] + shift, seal[1], float(seal[2])))
        for i, (kind, tip, seal) in zip((0, -1), ends)
    )  # fmt: skip
    tube = ExtractedTube(
        points=points + shift,
        spoke_lengths=spoke_len,
        reference_normal=ref,
        radius=radius,
        branches=[(b_.junction_hub, b_.length) for b_ in branches],
        ends=tube_ends,
        branch_details=branches,
        openings=openings,
        voxel_size=h,
        timings=timings,
        missed_spokes=int((~valid).sum()),
        fidelity=fid,
        source=src,
        ring=None if ring is None else dataclasses.replace(ring, cuts=ring.cuts + shift),
        aspect=section_aspect(q, points, diag),
    )
    volume = dm.count * dm.voxel_size**3  # (the enclosed volume, as the inside voxels measure it)
    tube.warnings = tubelike.check(tube, open_rays(q, points, diag), hubs_given=hubs is not None, mesh_volume=volume,
                                   strict=strict)  # fmt: skip
    refused = [w for w in tube.warnings if w.startswith(tubelike.NOT_A_TUBE)] if strict else []
    for w in tube.warnings:
        if not refused or w != refused[0]:  # the refusal itself is the error message, not a warning too
            log.warning("%s: %s", src, w)
    if refused:
        raise SceneError(f"{src}: {refused[0]} (--strict)")
    timings["total"] = time.perf_counter() - t_start
    return tube


def _end_excess(lengths: np.ndarray) -> float:
    """How far the end rings are more lopsided than the mesh's section next to them: the larger, over
    the two ends, of the end ring's longest over shortest spoke divided by :data:`END_RATIO_SLACK`
    times the same of the ring one hub in (1 or less: as round as the mesh allows). A ring normal to
    its edge leans against the axis where the hubs are sparse for the bend, and at a flat cut its
    spokes on one side meet the cut's face early. ``lengths``: spoke lengths (hubs, spokes)."""
    if len(lengths) < 4:
        return 0.0
    ratio = lengths.max(axis=1) / np.maximum(lengths.min(axis=1), 1e-300)
    return float(max(ratio[0] / (END_RATIO_SLACK * ratio[1]), ratio[-1] / (END_RATIO_SLACK * ratio[-2])))


def _open_or_cut(path: np.ndarray, d: np.ndarray, loop, h: float, rough: bool):
    """Start a voxel path at its open loop's centre, or cut its off-centre tail at a closed end."""
    if isinstance(loop, BoundaryLoop):
        return np.concatenate([loop.centroid[None], path]), np.concatenate([[loop.radius], d])
    return cut_closed_tail(path, d, h, rough)


def _openings(loops, spoke_len, hub_tree, src) -> list[Opening]:
    """Report the open loops that are not ends: in the tube's wall, or closing a side branch."""
    out = []
    hubs = np.asarray(hub_tree.data, dtype=np.float64)
    radii = np.median(spoke_len, axis=1)
    for lp in loops:
        dist, hub = hub_tree.query(lp.centroid)
        wall = float(radii[hub])
        if len(hubs) > 1:  # from the centerline between the hubs: an opening between two is as far from it as the wall
            (dist,), (arc,) = project_points(lp.centroid[None], hubs)
            wall = float(np.interp(arc, arclength(hubs), radii))
        kind = "wall" if dist <= wall else "branch"
        out.append(Opening(int(hub), float(lp.radius), len(lp.vertices), float(dist), kind))
        where = "an opening in the tube's wall" if kind == "wall" else "closing a side branch left out"
        log.info("%s: open loop of %d vertices, radius %.4g, at hub %d: %s", src, len(lp.vertices), lp.radius, hub,
                 where)  # fmt: skip
    return out
