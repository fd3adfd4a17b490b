"""How well the simulator's rest surface of extracted hubs and spokes reproduces the input mesh.

The surface measured is the one the simulator writes at frame 0: :class:`~warp_tube.surface.builder.SurfaceBuilder`
(the same class, kernels, frames, inner-bend guard and caps the simulation uses) rebuilt from the
rest hubs as float32 positions, exactly as :class:`~warp_tube.Simulation` does before its first step
(``tests/test_extract_fidelity.py`` checks that the two agree).

Distances are measured both ways with ``wp.Mesh`` closest-point queries, as fractions of the mean
spoke length (the tube's mean radius):

- from the input's vertices to the surface, leaving out the vertices of side branches (nearer to a
  branch's path than to the centerline), those within one end radius of either end of the tube
  (along the centerline extended to where the mesh ends: the open loop's centre, or the cap's tip)
  and those on the flat faces that seal a cut end (the trimmed end leaves them open);
- from the surface's vertices (rings and caps) to the input, leaving nothing out: a spike, a fold or a
  cap that does not meet the mesh shows here. Openings of the mesh that are not the tube's ends
  (where a branch was cut flush) are closed by fans first (:func:`closed_openings`): the tube keeps
  its wall across them, as the spokes measured against the same closure do.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import warp as wp

from ..kernels import raycast
from ..model.frames import rotation_minimizing_frames, spoke_directions
from ..surface.builder import SurfaceBuilder
from .polyline import arclength, nearest_on_polyline

if TYPE_CHECKING:
    import trimesh

    from .pipeline import ExtractedTube

__all__ = [
    "FIDELITY_BOUNDS", "RestSurface", "rest_surface", "plain_surface", "Distances", "Fidelity", "fidelity_of", "surface_fidelity",
    "mesh_distances", "measured_vertices", "closed_openings",
]  # fmt: skip


FIDELITY_BOUNDS = (0.04, 0.15, 0.40)
"""Bounds on the two-way distances (mean, 99th percentile, largest), as fractions of the mean
radius, that an extracted tube's rest surface is expected to meet (README, "Centerline extraction")."""


@dataclass(frozen=True)
class RestSurface:
    """The frame-0 surface of a tube as the simulator builds it.

    Attributes:
        points: vertices [mesh units], shape (V, 3): ring ``i`` spoke ``j`` at ``i * S + j``, caps after.
        faces: triangles, int (F, 3).
        unguarded: the same vertices with the inner-bend guard off [mesh units], shape (V, 3).
        hubs: N, spokes: S.
    """

    points: np.ndarray
    faces: np.ndarray
    unguarded: np.ndarray
    hubs: int
    spokes: int

    def ring_lengths(self, hub_points: np.ndarray) -> np.ndarray:
        """Distances of each body ring's vertices from their hub [mesh units], shape (N, S)."""
        ring = self.points[: self.hubs * self.spokes].reshape(self.hubs, self.spokes, 3)
        return np.linalg.norm(ring - np.asarray(hub_points)[:, None, :], axis=-1)

    def guard_moves(self) -> np.ndarray:
        """How far the guard moved each vertex [mesh units], shape (V,)."""
        return np.linalg.norm(self.points - self.unguarded, axis=1)


def rest_surface(points, spoke_lengths, reference_normal, caps: bool, device=None, *, unguarded: bool = True
                 ) -> RestSurface:  # fmt: skip
    """Frame-0 surface of hubs and spokes, rebuilt by the simulator's :class:`SurfaceBuilder`.

    Args:
        points: rest hubs [mesh units], shape (N, 3).
        spoke_lengths: shape (N, S) [mesh units].
        reference_normal: direction of spoke 0 at hub 0, shape (3,).
        caps: whether the scene closes both ends with caps.
        device: Warp device (default: Warp's default device).
        unguarded: rebuild it with the guard off too (:attr:`RestSurface.unguarded`; else that is
            the rings ``hub + length * direction`` of :func:`plain_surface` and the guarded caps).
    """
    device = wp.get_device(device)
    p = np.asarray(points, dtype=np.float64)
    lengths = np.asarray(spoke_lengths, dtype=np.float64)
    n, s = lengths.shape
    q = wp.array(p.astype(np.float32)[None], dtype=wp.vec3, device=device)
    out = []
    for reach in (None, 0.0) if unguarded else (None,):
        kw = {} if reach is None else {"guard_reach": reach}
        b = SurfaceBuilder(np.array([0, n]), p, s, lengths, reference_normal, caps=caps, device=device, **kw)
        pts, _ = b.compute(q)
        out.append(pts.numpy()[0].astype(np.float64))
    faces = np.asarray(b.face_vertex_indices, dtype=np.int64).reshape(-1, 3)
    if not unguarded:
        plain = out[0].copy()
        plain[: n * s] = plain_surface(p, lengths, reference_normal)[0]
        out.append(plain)
    return RestSurface(out[0], faces, out[1], n, s)


def plain_surface(points, spoke_lengths, reference_normal):
    """Rings ``hub + spoke_length * direction`` as measured (no guard, no caps), joined by strips.

    Args:
        points: hubs, shape (n, 3); spoke_lengths: shape (n, S); reference_normal: shape (3,).

    Returns:
        ``(vertices (n * S, 3), faces (2 * (n - 1) * S, 3))``; vertex ``i * S + j`` is spoke j of hub i.
    """
    p = np.asarray(points, dtype=np.float64)
    n, m = np.shape(spoke_lengths)
    _, r, s = rotation_minimizing_frames(p, None, reference_normal)
    v = (p[:, None, :] + np.asarray(spoke_lengths)[..., None] * spoke_directions(r, s, m)).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(n - 1), np.arange(m), indexing="ij")
    a = i * m + j
    b = i * m + (j + 1) % m
    faces = np.concatenate(
        [np.stack([a, b, b + m], -1).reshape(-1, 3), np.stack([a, b + m, a + m], -1).reshape(-1, 3)]
    )
    return v, faces


def mesh_distances(query: np.ndarray, vertices: np.ndarray, faces: np.ndarray, device=None) -> np.ndarray:
    """Distance from each query point to the triangle mesh ``(vertices, faces)``, shape (Q,).

    Coordinates are shifted to the mesh's centre first, so float32 queries keep their precision.
    """
    device = wp.get_device(device)
    v = np.asarray(vertices, dtype=np.float64)
    q = np.asarray(query, dtype=np.float64)
    if len(q) == 0:
        return np.zeros(0)
    shift = 0.5 * (v.min(axis=0) + v.max(axis=0))
    pts = wp.array((v - shift).astype(np.float32), dtype=wp.vec3, device=device)
    idx = wp.array(np.asarray(faces, dtype=np.int32).reshape(-1), dtype=wp.int32, device=device)
    mesh = wp.Mesh(points=pts, indices=idx)
    qa = wp.array((q - shift).astype(np.float32), dtype=wp.vec3, device=device)
    out = wp.empty(len(q), dtype=float, device=device)
    big = 4.0 * float(np.ptp(np.concatenate([v, q]), axis=0).max()) + 1.0
    wp.launch(raycast.closest_distance, dim=len(q), inputs=[mesh.id, qa, big], outputs=[out], device=device)
    return out.numpy().astype(np.float64)


@dataclass(frozen=True)
class Distances:
    """Distances of one direction, as fractions of the tube's mean radius.

    Attributes:
        mean, p99, max: mean, 99th percentile and largest distance / mean radius.
        counted: points measured; left_out: points not measured.
    """

    mean: float
    p99: float
    max: float
    counted: int
    left_out: int

    @staticmethod
    def of(d: np.ndarray, radius: float, left_out: int = 0) -> Distances:
        if len(d) == 0:
            return Distances(float("nan"), float("nan"), float("nan"), 0, left_out)
        d = np.asarray(d) / radius
        return Distances(float(d.mean()), float(np.percentile(d, 99)), float(d.max()), len(d), left_out)

    def within(self, mean: float, p99: float, max_: float) -> bool:
        """Whether all three figures are within the given bounds (nothing measured: within)."""
        return self.counted == 0 or (self.mean <= mean and self.p99 <= p99 and self.max <= max_)


@dataclass(frozen=True)
class Fidelity:
    """Two-way distances between an input mesh and the frame-0 surface of its extracted tube.

    Attributes:
        to_surface: from the input's vertices to the surface (branches and ends left out).
        to_input: from the surface's vertices to the input (those across a side branch's mouth left out).
        rings_to_input: from the body rings' vertices to the input (caps left out): what the hub
            count can change.
        mean_radius: mean spoke length [mesh units].
        end_ratios: longest over shortest spoke of the first and last ring of the frame-0 surface.
        guard_moved: largest distance the inner-bend guard moved a vertex / mean radius.
    """

    to_surface: Distances
    to_input: Distances
    rings_to_input: Distances
    mean_radius: float
    end_ratios: tuple[float, float]
    guard_moved: float

    @property
    def mean(self) -> float:
        """The larger of the two mean distances / mean radius."""
        return max(self.to_surface.mean, self.to_input.mean)

    @property
    def p99(self) -> float:
        """The larger of the two 99th percentiles / mean radius."""
        return max(self.to_surface.p99, self.to_input.p99)

    @property
    def max(self) -> float:
        """The larger of the two largest distances / mean radius."""
        return max(self.to_surface.max, self.to_input.max)

    def within(self, mean: float, p99: float, max_: float) -> bool:
        """Whether both directions are within the bounds."""
        return self.to_surface.within(mean, p99, max_) and self.to_input.within(mean, p99, max_)


def measured_vertices(points, radius_first: float, radius_last: float, vertices, tips=None, branch_paths=(),
                      seals=()):  # fmt: skip
    """Which input vertices the input-to-surface distances count, bool shape (V,).

    Left out: vertices whose nearest point on the centerline (the hubs, extended by ``tips``, the
    two points where the mesh ends, when given) lies within one end radius of either end of it,
    vertices nearer to a side branch's path than to the centerline, and vertices on the flat faces
    that seal a cut end (``seals``: ``(point, unit normal, radius)`` of each; within 2 % of the radius
    of the plane and two radii of the point), which a trimmed end leaves open.
    """
    line = _with_tips(points, tips)
    verts = np.asarray(vertices, dtype=np.float64)
    step = 0.125 * min(radius_first, radius_last)
    dist_line, arc = nearest_on_polyline(verts, line, step)
    total = arclength(line)[-1]
    keep = (arc > radius_first) & (arc < total - radius_last) & off_branches(verts, dist_line, branch_paths, step)
    for point, normal, radius in seals:
        rel = verts - np.asarray(point)
        keep &= ~((np.abs(rel @ np.asarray(normal)) <= 0.02 * radius) & (np.linalg.norm(rel, axis=1) <= 2.0 * radius))
    return keep


def _with_tips(points, tips) -> np.ndarray:
    """The centerline ``points`` (n, 3), extended by ``tips`` (the two points where the mesh ends)
    when given."""
    line = np.asarray(points, dtype=np.float64)
    if tips is None:
        return line
    return np.concatenate([np.asarray(tips[0], dtype=np.float64)[None], line, np.asarray(tips[1], dtype=np.float64)[None]])


def measured_branch_path(path: np.ndarray, root: np.ndarray, bridged: bool) -> np.ndarray:
    """A side branch's path as the fit leaves it out: ``path`` (k, 3), beyond the tube's wall, or
    for a branch whose mouth the tube's sections were bridged over, from ``root``, the centerline
    point where it leaves (its root, in its mouth, counts with the branch, not with the tube's
    wall that the surface runs across it)."""
    return np.vstack([np.asarray(root, dtype=np.float64)[None], path]) if bridged else path


def off_branches(verts: np.ndarray, dist_line: np.ndarray, branch_paths, step: float) -> np.ndarray:
    """Which points ``verts`` (V, 3) lie no nearer to a side branch's path than to the centerline
    (their distances from it ``dist_line``, (V,)), bool (V,); ``step``: the paths' sampling."""
    keep = np.ones(len(verts), dtype=bool)
    for path in branch_paths:
        path = np.asarray(path, dtype=np.float64).reshape(-1, 3)
        if len(path) > 1:
            keep &= ~(nearest_on_polyline(verts, path, step)[0] < dist_line)
        elif len(path) == 1:
            keep &= ~(np.linalg.norm(verts - path[0], axis=1) < dist_line)
    return keep


def fidelity_of(
    points, spoke_lengths, reference_normal, caps: bool, vertices, faces, *, tips=None, branch_paths=(), seals=(),
    device=None, surface: RestSurface | None = None, wall=None,
) -> Fidelity:
    """Two-way fidelity of hubs and spokes to the mesh ``(vertices (V, 3), faces (F, 3))``, same units.

    Args:
        points, spoke_lengths, reference_normal, caps: the tube as the scene holds it.
        tips: the two points where the mesh ends, shape (2, 3) (default: the end hubs).
        branch_paths: side branches' paths, a bridged one's from the centerline point where it
            leaves (their vertices are not counted towards the surface, nor the surface's vertices
            nearer to them than to the centerline, across their mouths, towards the mesh).
        seals: the planes of flat faces sealing cut ends (see :func:`measured_vertices`).
        surface: the frame-0 surface when already built (:func:`rest_surface`).
        wall: ``(vertices, triangles)`` the surface's vertices are measured against (default: the
            mesh itself; :func:`closed_openings` closes the openings the tube keeps).
    """
    points = np.asarray(points, dtype=np.float64)
    lengths = np.asarray(spoke_lengths, dtype=np.float64)
    surf = surface or rest_surface(points, lengths, reference_normal, caps, device)
    radius = float(lengths.mean())
    end_r = lengths.mean(axis=1)
    keep = measured_vertices(points, end_r[0], end_r[-1], vertices, tips, branch_paths, seals)
    d_in = mesh_distances(np.asarray(vertices)[keep], surf.points, surf.faces, device)
    d_out = mesh_distances(surf.points, *(wall if wall is not None else (vertices, faces)), device)
    # (the surface across a side branch's mouth has no wall of the tube to meet: left out as the
    # branch's own vertices are the other way)
    step = 0.125 * min(end_r[0], end_r[-1])
    out = off_branches(surf.points, nearest_on_polyline(surf.points, _with_tips(points, tips), step)[0], branch_paths, step) \
        if len(branch_paths) else np.ones(len(d_out), dtype=bool)  # fmt: skip
    ring = surf.ring_lengths(points)
    ratios = ring.max(axis=1) / np.maximum(ring.min(axis=1), 1e-300)
    body = surf.hubs * surf.spokes
    return Fidelity(
        to_surface=Distances.of(d_in, radius, int((~keep).sum())),
        to_input=Distances.of(d_out[out], radius, int((~out).sum())),
        rings_to_input=Distances.of(d_out[:body][out[:body]], radius, len(d_out) - int(out[:body].sum())),
        mean_radius=radius,
        end_ratios=(float(ratios[0]), float(ratios[-1])),
        guard_moved=float(surf.guard_moves().max() / radius),
    )


def closed_openings(tube: ExtractedTube, mesh: trimesh.Trimesh) -> tuple[np.ndarray, np.ndarray]:
    """``mesh`` with every boundary loop closed by a fan except the tube's open ends: the wall the
    tube's surface is measured against (an opening where a branch was cut flush is part of the tube,
    kept closed). Returns ``(vertices (V', 3), triangles (F', 3))``."""
    from .mesh_io import boundary_loops, cap_loops

    loops = boundary_loops(mesh)
    tips = np.stack([e.tip for e in tube.ends if e.kind == "open"]) if any(e.kind == "open" for e in tube.ends) else None
    tol = 1e-6 * float(np.ptp(np.asarray(mesh.vertices), axis=0).max())
    others = [lp for lp in loops if tips is None or np.min(np.linalg.norm(tips - lp.centroid, axis=1)) > tol]
    return cap_loops(mesh, others)


def surface_fidelity(tube: ExtractedTube, mesh: trimesh.Trimesh, device=None, *, surface: RestSurface | None = None
                     ) -> Fidelity:  # fmt: skip
    """Fidelity of ``tube`` to ``mesh`` (the mesh it was extracted from, after the same scale).

    Args:
        surface: the rest surface to measure (default: the simulator's builder on ``tube``;
            :func:`warp_tube.bench.extraction.simulated_surface` gives the one ``warp-tube run`` writes,
            through the public API).
    """
    tips = np.stack([e.tip for e in tube.ends])
    paths = [measured_branch_path(b.path, tube.points[b.junction_hub], b.bridged) for b in tube.branch_details]
    return fidelity_of(tube.points, tube.spoke_lengths, tube.reference_normal, tube.caps, mesh.vertices, mesh.faces,
                       tips=tips, branch_paths=paths, device=device, surface=surface,
                       seals=[e.seal for e in tube.ends if e.seal is not None],
                       wall=closed_openings(tube, mesh))  # fmt: skip
