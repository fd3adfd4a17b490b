"""Host side of the hubs-and-spokes surface: allocation, rest frames and launch.

:class:`SurfaceBuilder` serves one tube prim (one spoke count S; all its curves). It is built once
from the rest centerline and the spoke lengths, allocates everything then, and at every output
frame rebuilds the boundary from the deformed centerline with one launch (``kernel``):

- ``"world"`` (the CPU's default): :func:`~warp_tube.kernels.surface_world.surface_world_kernel`,
  a thread per world;
- ``"block"`` (the GPU's default): :func:`~warp_tube.kernels.surface_block.make_surface_block_kernel`'s
  kernel, a warp per world, or per span of whole tubes of a world where the worlds are too few to
  fill the device (:mod:`warp_tube.surface.spans`; then a second launch reduces each world's bounds).

Each does the whole rebuild (frames, the inner-bend guard, points, normals, and the bounds of the
points, the ``extent``) with the same functions in the same order, so both give the same points
and normals, bit for bit.

Rest frames (tangent and spoke-0 normal of every hub at rest) follow :mod:`warp_tube.model.frames`
in float64: the first hub's normal is the tube's reference normal (or the convention's default),
and the rest normals are carried along the rest centerline by double reflection.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ..model import frames as ref_frames
from ..kernels.surface_arrays import SurfaceArrays
from ..kernels.surface_block import WORLD_LANES, make_surface_block_kernel, span_extent_kernel
from ..kernels.surface_world import surface_world_kernel
from ..runtime.replay import GraphCache, cpu_blocks
from .spans import block_spans
from .topology import SurfaceTopology, TopologyView, tube_topology

__all__ = ["SurfaceBuilder", "FRAME_MODES", "DEFAULT_GUARD_REACH"]

FRAME_MODES = ("rotationMinimizing", "local")
SURFACE_KERNELS = ("world", "block")
BLOCK_SHAPE = (2, 8)
"""The block kernel's worlds per block and least resident blocks per multiprocessor (the fastest
of the shapes measured for circular tubes on an H100; see BENCHMARKS.md)."""
DEFAULT_GUARD_REACH = 0.95
"""Spoke ends stay within 95% of the way to a neighbouring ring's plane (see
:mod:`warp_tube.kernels.surface_guard`)."""


def rest_frames(
    rest_q: np.ndarray, tube_node_start: np.ndarray, reference_normal: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Rest tangents and normals of every hub, each shaped as ``rest_q``, float64, per
    :mod:`warp_tube.model.frames`.

    Args:
        rest_q: rest hub positions, (N, 3), or (W, N, 3) for W worlds of one layout.
        tube_node_start: first hub of each tube, (T + 1,), starting at 0.
        reference_normal: None, one direction (3,) for every tube, or (T, 3) with NaN rows for
            tubes without one.
    """
    x = np.asarray(rest_q, dtype=np.float64)
    starts = np.asarray(tube_node_start, dtype=np.int64)
    n_tubes = len(starts) - 1
    refs = None
    if reference_normal is not None:
        refs = np.asarray(reference_normal, dtype=np.float64)
        refs = np.broadcast_to(refs, (n_tubes, 3)) if refs.ndim == 1 else refs
    t = np.empty_like(x)
    r = np.empty_like(x)
    lead = x.shape[:-2]  # (the worlds, or none)
    W = int(np.prod(lead))
    # Tubes of one length at once, of every world (ref_frames.rotation_minimizing_frames_many).
    counts = np.diff(starts)
    for n in np.unique(counts):
        tubes = np.flatnonzero(counts == n)
        rows = starts[tubes][:, None] + np.arange(n)  # (tubes, n) hub indices
        ref = None if refs is None else np.tile(refs[tubes], (W, 1))
        tt, rr = ref_frames.rotation_minimizing_frames_many(x[..., rows, :].reshape(-1, n, 3), ref)
        t[..., rows, :] = tt.reshape(lead + (len(tubes), n, 3))
        r[..., rows, :] = rr.reshape(lead + (len(tubes), n, 3))
    return t, r


def uniform_hubs(lengths: np.ndarray) -> np.ndarray:
    """1 where a hub and its neighbours (the hubs before and after it in the array) each have one
    spoke length all round, else 0: int32 of shape ``lengths.shape[:2]`` from spoke lengths shaped
    (rows, hubs, S). There the kernels read a ring's length and its step along the tube once."""
    flat = np.all(lengths == lengths[..., :1], axis=-1)
    out = flat.copy()
    out[:, 1:] &= flat[:, :-1]
    out[:, :-1] &= flat[:, 1:]
    return out.astype(np.int32)


class _Launches:
    """Recorded launches run one after the other, as one."""

    def __init__(self, launches):
        self.launches = launches

    def launch(self):
        for launch in self.launches:
            launch.launch()


class SurfaceBuilder(TopologyView):
    """Rebuilds the surface of one tube prim (all its curves, one spoke count) from its centerline.

    Args:
        tube_node_start: first node of each tube as a column index of the ``node_q`` arrays that
            :meth:`compute` gets, int (T + 1,); it may start above 0 when ``node_q`` holds other
            prims' nodes first (their nodes are skipped). Every tube needs >= 2 hubs.
        rest_q: rest hub positions of this prim's N hubs, (N, 3) [length unit L], or
            (world_count, N, 3) for per-world variants, where ``N = tube_node_start[-1] -
            tube_node_start[0]``. The topology's texture coordinates (``topology.st``, which
            follow the rest arclength and the caps' radii) are world 0's.
        spokes: spokes per hub, S >= 3.
        spoke_lengths: spoke lengths [L]: (N, S), (world_count, N, S) for per-world variants, or
            (N,) for a circular tube (the radius per hub).
        reference_normal: direction of spoke 0 at each tube's first hub at rest: None, (3,) for
            all tubes, or (T, 3) with NaN rows for tubes without one.
        frames: "rotationMinimizing" (default) or "local" (the paper's local rotation).
        caps: close both ends of every tube with a rounded cap.
        world_count: worlds W of the batch (rows of ``node_q``).
        device: Warp device (default: Warp's default device).
        guard_reach: inner-bend guard fraction in (0, 1), 0 to turn it off (see
            :mod:`warp_tube.kernels.surface_guard`).
        kernel: how a rebuild runs: ``"world"``, a thread per world (the CPU's default), or
            ``"block"``, a warp per world, or per span of a world's tubes where the worlds are
            too few to fill the device (the GPU's default, :mod:`warp_tube.surface.spans`; on the
            CPU it runs with Warp's CPU blocks, slowly: for tests). Both give the same points and
            normals.
        cell_radius: each tube's radius for the inner-bend guard's window along the tube [L], (T,)
            (several prims in one builder: each tube its prim's mean spoke length) or
            (world_count, T); default: each world's mean of its ``spoke_lengths``, for every tube.

    All lengths share one unit L (the core passes metres); points come out in L.
    """

    def __init__(
        self,
        tube_node_start,
        rest_q,
        spokes: int,
        spoke_lengths,
        reference_normal=None,
        *,
        frames: str = "rotationMinimizing",
        caps: bool = False,
        world_count: int = 1,
        device=None,
        guard_reach: float = DEFAULT_GUARD_REACH,
        kernel: str | None = None,
        cell_radius=None,
    ):
        if frames not in FRAME_MODES:
            raise ValueError(f"frames must be one of {FRAME_MODES}, got {frames!r}")
        if not 0.0 <= guard_reach < 1.0:
            raise ValueError(f"guard_reach must be in [0, 1), got {guard_reach}")
        if world_count < 1:
            raise ValueError(f"world_count must be >= 1, got {world_count}")
        starts = np.asarray(tube_node_start, dtype=np.int64)
        self.node_offset = int(starts[0])
        local_starts = starts - self.node_offset
        rest = np.asarray(rest_q, dtype=np.float64)
        n_hubs = int(local_starts[-1])
        if rest.ndim == 2:
            rest = rest[None]
        if rest.shape[1:] != (n_hubs, 3) or rest.shape[0] not in (1, world_count):
            raise ValueError(f"rest_q must be shaped ({n_hubs}, 3) or ({world_count}, {n_hubs}, 3), got {np.shape(rest_q)}")
        S = int(spokes)
        lengths = np.asarray(spoke_lengths, dtype=np.float64)
        if lengths.ndim == 1:
            lengths = np.repeat(lengths[:, None], S, axis=1)
        if lengths.ndim == 2:
            lengths = lengths[None]
        if lengths.shape[1:] != (n_hubs, S) or lengths.shape[0] not in (1, world_count):
            raise ValueError(
                f"spoke_lengths must be ({n_hubs},), ({n_hubs}, {S}) or ({world_count}, {n_hubs}, {S}), "
                f"got {np.shape(spoke_lengths)}"
            )
        if not np.all(np.isfinite(lengths)) or np.any(lengths <= 0.0):
            raise ValueError("spoke_lengths must be finite and positive")

        self.topology: SurfaceTopology = tube_topology(local_starts, S, lengths[0], caps, rest[0])
        self.spokes = S
        self.frames = frames
        self.caps = bool(caps)
        self.world_count = int(world_count)
        self.hub_count = n_hubs
        self.tube_count = len(starts) - 1
        self.guard_reach = float(guard_reach)
        # the window of the cell guard along each tube: pi of these
        T = len(starts) - 1
        if cell_radius is None:  # (each world's mean as one array's: the same sum, bit for bit, as a run alone)
            cell = np.repeat(lengths.reshape(len(lengths), -1).mean(axis=1)[:, None], T, axis=1)
        else:
            cell = np.asarray(cell_radius, dtype=np.float64)
            cell = cell[None] if cell.ndim == 1 else cell
        if cell.shape[1:] != (T,) or cell.shape[0] not in (1, world_count) or not np.all(np.isfinite(cell) & (cell > 0.0)):
            raise ValueError(f"cell_radius must be ({T},) or ({world_count}, {T}) finite positive lengths, got shape {np.shape(cell_radius)}")
        self._local_starts = local_starts
        self.device = wp.get_device(device)
        if kernel is None:
            kernel = "world" if self.device.is_cpu else "block"
        if kernel not in SURFACE_KERNELS:
            raise ValueError(f"kernel must be one of {SURFACE_KERNELS}, got {kernel!r}")
        self.kernel = kernel
        self.block_shape = BLOCK_SHAPE  # worlds per block, least resident blocks (the block kernel)

        rest_t, rest_r = rest_frames(rest, local_starts, reference_normal)  # (1 or W, N, 3) each
        node_tube = np.repeat(np.arange(self.tube_count), np.diff(local_starts))
        topo = self.topology
        # the block kernel's spans of a world (the world kernel takes a whole world: one span)
        self.spans = block_spans(local_starts, topo.ring_hub, topo.ring_kind, self.world_count,
                                 **({} if kernel == "block" else {"target_warps": 1}))  # fmt: skip
        with wp.ScopedDevice(self.device):
            self._tube_node_start = wp.array(local_starts.astype(np.int32), dtype=wp.int32)
            self._node_tube = wp.array(node_tube.astype(np.int32), dtype=wp.int32)
            self._tube_cell_radius = wp.array(cell.astype(np.float32), dtype=float)  # (1 or W, T)
            self._rest_t = wp.array(rest_t.astype(np.float32), dtype=wp.vec3)
            self._rest_r = wp.array(rest_r.astype(np.float32), dtype=wp.vec3)
            self._spoke_length = wp.array(lengths.astype(np.float32), dtype=float)
            self._hub_reach = wp.array(lengths.max(axis=2).astype(np.float32), dtype=float)
            uniform = uniform_hubs(lengths.astype(np.float32))
            self._hub_uniform = wp.array(uniform, dtype=wp.int32)
            self._ring_hub = wp.array(topo.ring_hub, dtype=wp.int32)
            self._ring_kind = wp.array(topo.ring_kind, dtype=wp.int32)
            self._ring_cos = wp.array(topo.ring_cos, dtype=float)
            self._ring_sin = wp.array(topo.ring_sin, dtype=float)
            self._ring_vertex = wp.array(topo.ring_vertex, dtype=wp.int32)
            phi = 2.0 * np.pi * np.arange(S) / S
            self._spoke_cos = wp.array(np.cos(phi).astype(np.float32), dtype=float)
            self._spoke_sin = wp.array(np.sin(phi).astype(np.float32), dtype=float)
            self.hub_t = wp.zeros((self.world_count, n_hubs), dtype=wp.vec3)
            self.hub_r = wp.zeros((self.world_count, n_hubs), dtype=wp.vec3)
            self._hub_kappa = wp.zeros((self.world_count, n_hubs), dtype=wp.vec3)
            self._hub_chord = wp.zeros((self.world_count, n_hubs), dtype=float)
            self._hub_plane = wp.zeros((self.world_count, n_hubs, 3), dtype=wp.vec4)
            self._hub_cell = wp.zeros((self.world_count, n_hubs), dtype=wp.vec2i)
            self._hub_free = wp.zeros((self.world_count, n_hubs), dtype=wp.vec2)
            self._surface_length = wp.zeros((self.world_count, topo.vertex_count), dtype=float)
            self.points = wp.zeros((self.world_count, topo.vertex_count), dtype=wp.vec3)
            self.normals = wp.zeros((self.world_count, topo.vertex_count), dtype=wp.vec3)
            self._extent = wp.zeros((self.world_count, 2), dtype=wp.vec3)
            self._span_hub_start = wp.array(self.spans.hub_start, dtype=wp.int32)
            self._span_cap_ring = wp.array(self.spans.cap_ring, dtype=wp.int32)
            several = self.spans.count > 1
            self._span_bounds = wp.zeros((self.world_count if several else 1, self.spans.count if several else 1, 2), dtype=wp.vec3)
        arrays = SurfaceArrays()  # the kernels' arguments but node_q, fixed for the builder's life
        for name, value in (
            ("node_offset", self.node_offset), ("spoke_count", self.spokes), ("guard_reach", self.guard_reach),
            ("local_frames", int(self.frames == "local")), ("tube_node_start", self._tube_node_start),
            ("node_tube", self._node_tube), ("tube_cell_radius", self._tube_cell_radius),
            ("node_rest_t", self._rest_t), ("node_rest_r", self._rest_r), ("hub_reach", self._hub_reach),
            ("ring_hub", self._ring_hub), ("ring_kind", self._ring_kind), ("ring_cos", self._ring_cos),
            ("ring_sin", self._ring_sin), ("ring_vertex", self._ring_vertex), ("spoke_cos", self._spoke_cos),
            ("spoke_sin", self._spoke_sin), ("spoke_length", self._spoke_length),
            ("hub_uniform", self._hub_uniform), ("span_count", self.spans.count),
            ("span_hub_start", self._span_hub_start), ("span_cap_ring", self._span_cap_ring),
            ("span_hubs_max", self.spans.hubs_max), ("span_bounds", self._span_bounds), ("hub_t", self.hub_t),
            ("hub_r", self.hub_r), ("hub_kappa", self._hub_kappa), ("hub_chord", self._hub_chord),
            ("hub_plane", self._hub_plane), ("hub_cell", self._hub_cell), ("hub_free", self._hub_free),
            ("surface_length", self._surface_length), ("surface_q_out", self.points),
            ("surface_n_out", self.normals), ("extent_out", self._extent),
        ):  # fmt: skip
            setattr(arrays, name, value)
        self._arrays = arrays
        self._launches: dict = {}
        self._graphs = GraphCache(self.device, size=4)

    # -- topology (and the counts, faces and st of TopologyView) -------------------------------
    def tube_vertex_indices(self, tube: int) -> np.ndarray:
        """Vertex indices (ring vertices, then cap vertices) of tube ``tube`` of this prim."""
        topo = self.topology
        first, last = self._local_starts[tube], self._local_starts[tube + 1]
        mask = (topo.ring_hub >= first) & (topo.ring_hub < last)
        out = []
        for ring in np.flatnonzero(mask):
            count = 1 if topo.ring_sin[ring] == 0.0 else self.spokes
            out.append(topo.ring_vertex[ring] + np.arange(count))
        return np.concatenate(out)

    # -- per frame -----------------------------------------------------------------------------
    def _record(self, node_q: wp.array):
        if self.kernel == "world":
            launch = wp.launch(
                surface_world_kernel, dim=self.world_count, inputs=[self._arrays, node_q], device=self.device, record_cmd=True
            )  # fmt: skip
            return launch
        worlds_per_block, min_blocks = self.block_shape
        kernel = make_surface_block_kernel(worlds_per_block, min_blocks, self.spans.count > 1)
        blocks = -(-self.world_count * self.spans.count // worlds_per_block)
        with cpu_blocks():  # on the CPU a block's threads are fibers (opt-in)
            launch = wp.launch_tiled(
                kernel, dim=(blocks,), block_dim=WORLD_LANES * worlds_per_block, inputs=[self._arrays, node_q],
                device=self.device, record_cmd=True,
            )  # fmt: skip
        if self.spans.count == 1:
            return launch
        bounds = wp.launch(span_extent_kernel, dim=self.world_count, inputs=[self._span_bounds], outputs=[self._extent],
                           device=self.device, record_cmd=True)  # fmt: skip
        return _Launches((launch, bounds))

    def compute(self, node_q: wp.array) -> tuple[wp.array, wp.array]:
        """Rebuild the surface from hub positions; no allocation after the first call per array.

        Args:
            node_q: hub positions [L], ``wp.array2d`` of ``wp.vec3``, shape
                (world_count, >= node_offset + N), on this builder's device.

        Returns:
            ``(points, normals)``: this builder's own arrays, shaped (world_count, V), boundary
            points [L] and unit outward normals; overwritten by the next call.
        """
        key = (node_q.ptr, node_q.shape, node_q.strides)
        launch = self._launches.get(key)
        if launch is None:
            if node_q.dtype != wp.vec3 or node_q.ndim != 2:
                raise ValueError(f"node_q must be a 2-d array of vec3, got {node_q.dtype} with {node_q.ndim} dims")
            if node_q.shape[0] != self.world_count or node_q.shape[1] < self.node_offset + self.hub_count:
                raise ValueError(
                    f"node_q must be shaped ({self.world_count}, >= {self.node_offset + self.hub_count}), "
                    f"got {node_q.shape}"
                )
            if node_q.strides[1] != 12 or node_q.strides[0] % 12:
                raise ValueError(f"node_q's rows must be contiguous vec3, got strides {node_q.strides}")
            if node_q.device != self.device:
                raise ValueError(f"node_q is on {node_q.device}, the surface on {self.device}")
            if len(self._launches) >= 4:  # solvers swap a few state arrays; keep the cache small
                self._launches.clear()
                self._graphs.clear()
            launch = self._record(node_q)
            self._launches[key] = launch
        if self.kernel == "block" and self.device.is_cpu:
            with cpu_blocks():  # for tests only: no graph, fibers
                launch.launch()
        else:
            self._graphs.run(key, launch.launch, hold=(node_q,))
        return self.points, self.normals

    def extent(self) -> wp.array:
        """Bounds of the points of the last :meth:`compute`: ``[min, max]`` corners [L] per world,
        ``wp.array2d`` of ``wp.vec3`` shaped (world_count, 2), this builder's own array (written by
        the rebuild as it goes; zero before the first)."""
        return self._extent

    def points_numpy(self, world: int = 0) -> np.ndarray:
        """Boundary points of one world [L], float32 (V, 3) (a copy)."""
        return self.points.numpy()[world]

    def normals_numpy(self, world: int = 0) -> np.ndarray:
        """Unit normals of one world, float32 (V, 3) (a copy)."""
        return self.normals.numpy()[world]

    def frames_numpy(self, world: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Hub frames ``(t, r, s)`` of one world from the last :meth:`compute`, each (N, 3)."""
        t = self.hub_t.numpy()[world].astype(np.float64)
        r = self.hub_r.numpy()[world].astype(np.float64)
        return t, r, np.cross(t, r)
