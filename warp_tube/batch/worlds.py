"""Variants of one topology as the worlds of one model: per-world parameter arrays, one launch.

:func:`build_worlds` discretises all the variants at once (the per-node parameters of a scene
holding every variant's tubes, one after another) and reads the result as ``(world, node)`` arrays:
each model parameter array of shape (1, N) becomes (W, N), so world ``w`` holds variant ``w``'s masses,
stiffnesses, rest shape and damping (the kernels read parameters at ``[w % rows, i]``). The
topology (tube and force layout) is the first variant's, which every variant of a group shares
(:mod:`warp_tube.batch.plan`). The surface of each tube prim is one ``SurfaceBuilder`` over all
worlds, with per-world spoke lengths.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from itertools import chain
from operator import attrgetter

import numpy as np
import warp as wp

from ..model.tube import MATERIALS, TubeModel, build_model, model_features, node_parameters, rest_is_curved
from ..scene.spec import Scene, replace_checked
from .fastread import PlainScenes

__all__ = ["Worlds", "WorldArrays", "build_worlds", "combined_tubes", "scenes_node_parameters"]


@dataclass(frozen=True)
class WorldArrays:
    """Each world's per-node parameters as NumPy (float64) arrays [SI units], shape (W, N) or
    (W, N, 3): :class:`warp_tube.model.host.HostArrays`' per-node fields, one row per variant."""

    node_rest_q: np.ndarray  # (W, N, 3) [m]
    node_mass: np.ndarray  # (W, N) [kg]
    node_inv_mass: np.ndarray  # (W, N) [1/kg], 0 for pinned nodes
    node_damping: np.ndarray  # (W, N) [1/s]
    seg_rest_length: np.ndarray  # (W, N) [m]
    seg_ke: np.ndarray  # (W, N) [N/m]
    seg_kd: np.ndarray  # (W, N) [N s/m]
    node_bend_k: np.ndarray  # (W, N) [N m]
    node_kappa_rest: np.ndarray  # (W, N, 3) [1]
    node_anchor_k: np.ndarray  # (W, N) [N/m]
    node_anchor_kd: np.ndarray  # (W, N) [N s/m]
    node_radius: np.ndarray  # (W, N) [m]


def combined_tubes(scenes: list[Scene]) -> Scene:
    """One scene holding every scene's tubes, scene after scene, and no forces: what the per-node
    parameters (:func:`~warp_tube.model.tube.node_parameters`) of them all are made from."""
    tubes = tuple(chain.from_iterable(map(attrgetter("tubes"), scenes)))
    return replace_checked(scenes[0], tubes=tubes, forces=())  # (the scenes' prims repeat: not one scene's)


def scenes_node_parameters(scenes) -> dict:
    """The per-node parameters of every scene's tubes, scene after scene
    (:func:`~warp_tube.model.tube.node_parameters` of :func:`combined_tubes`); for
    :class:`~warp_tube.batch.fastread.PlainScenes` from their columns, without making the scenes:
    the base scene's prims, repeated, with each scene's materials."""
    if isinstance(scenes, PlainScenes):
        base = scenes.base
        combined = replace_checked(base, tubes=base.tubes * len(scenes), forces=())
        return node_parameters(combined, materials=scenes.materials(MATERIALS))[0]
    return node_parameters(combined_tubes(scenes))[0]


@dataclass
class Worlds:
    """A chunk's variants as worlds.

    Attributes:
        scenes: the variants' scenes, one per world.
        model: the model, ``world_count`` = W, parameter arrays (W, N).
        host: each world's per-node parameters, :class:`WorldArrays`.
        prim_start: first node of each tube prim, (prims + 1,) (the last entry: N).
        surfaces: per tube prim a ``SurfaceBuilder`` over the W worlds, or None.
        vertex_start: first surface vertex of each prim in a world's concatenated vertices,
            (prims + 1,), or None.
    """

    scenes: list
    model: TubeModel
    host: WorldArrays
    prim_start: np.ndarray
    surfaces: list | None
    vertex_start: np.ndarray | None

    @property
    def world_count(self) -> int:
        return self.model.world_count

    def rest_q(self) -> np.ndarray:
        """Rest positions [m], (W, N, 3) float64."""
        return self.host.node_rest_q

    @property
    def rest_shared(self) -> bool:
        """Whether every world has world 0's rest positions (a chunk of plain variants): what
        follows from them alone may be worked out for one world and repeated, the same numbers."""
        shared = self.__dict__.get("_rest_shared")
        if shared is None:
            q = self.host.node_rest_q
            shared = self.__dict__["_rest_shared"] = bool((q == q[:1]).all())
        return shared


def build_worlds(scenes: list[Scene], device: str, surface: bool, per_node: dict | None = None) -> Worlds:
    """Discretise ``scenes`` (one topology) as the worlds of one model on ``device``.

    ``per_node``: the scenes' :class:`WorldArrays` fields, (W, N, ...) each, as
    :func:`~warp_tube.model.tube.node_parameters` of their tubes gives them (planning kept them:
    :mod:`warp_tube.batch.nodes`), or None to work them out here."""
    W = len(scenes)
    one = _topology(scenes[0], device)  # the topology every world shares
    N = one.node_count
    if per_node is None:
        per_node = scenes_node_parameters(scenes)  # every world's nodes, world after world
        if len(per_node["node_mass"]) != W * N:
            raise ValueError(f"variants of one group have {len(per_node['node_mass'])} nodes in all, expected {W} x {N}")
        per_node = {f.name: per_node[f.name].reshape((W, N) + per_node[f.name].shape[1:]) for f in dataclasses.fields(WorldArrays)}
    elif per_node["node_mass"].shape != (W, N):
        raise ValueError(f"per-node parameters of {per_node['node_mass'].shape} (worlds, nodes), expected ({W}, {N})")
    host = WorldArrays(**{f.name: per_node[f.name] for f in dataclasses.fields(WorldArrays)})
    curved = rest_is_curved(host.node_kappa_rest)

    per_world = {}
    for f in dataclasses.fields(one):
        value = getattr(one, f.name)
        if isinstance(value, wp.array) and value.ndim == 2 and value.shape == (1, N):
            per_world[f.name] = wp.array(getattr(host, f.name), dtype=value.dtype, device=device)
    g = scenes[0].settings.gravity
    features = model_features(per_node, curved, g, one.features.external, one.features.assistant_line)
    # (the host copies of world 0's parameters: what build_model of its scene holds, the same numbers)
    world0 = dataclasses.replace(one.host, **{f.name: getattr(host, f.name)[0] for f in dataclasses.fields(WorldArrays)})
    model = dataclasses.replace(one, world_count=W, features=features, host=world0,
                                gravity=wp.vec3(*(g if g is not None else (0.0, 0.0, 0.0))), **per_world)  # fmt: skip
    prim_start = np.append(one.host.prim_node_start, N)
    surfaces = vertex_start = None
    if surface:
        surfaces = _surface_builders(scenes, prim_start, device)
        vertex_start = np.concatenate([[0], np.cumsum([b.vertex_count for b in surfaces])])
    scenes = scenes if isinstance(scenes, PlainScenes) else list(scenes)  # (plain ones: made when asked for)
    return Worlds(scenes=scenes, model=model, host=host, prim_start=prim_start, surfaces=surfaces,
                  vertex_start=vertex_start)  # fmt: skip


#: the topologies build_worlds used last (:func:`_topology`), by device and layout
_TOPOLOGIES: dict = {}
#: topologies kept at most
TOPOLOGIES_KEPT = 4


def _topology(scene: Scene, device: str) -> TubeModel:
    """``build_model(scene)`` on ``device``, for what every world of a group shares: the layout
    (tubes' curve point counts; forces' tubes, points and lines) and the index arrays made from it.
    Built once for the chunks of a layout (its parameter arrays and host copies are another
    scene's: the caller replaces them, and its world count and gravity)."""
    device = str(wp.get_device(device))
    key = (device, tuple(tuple(t.curve_counts.tolist()) for t in scene.tubes),
           tuple((f.tube, f.point, bool(f.assistant_line)) for f in scene.forces))  # fmt: skip
    one = _TOPOLOGIES.get(key)
    if one is None:
        while len(_TOPOLOGIES) >= TOPOLOGIES_KEPT:
            del _TOPOLOGIES[next(iter(_TOPOLOGIES))]
        one = _TOPOLOGIES[key] = build_model(scene, world_count=1, device=device)
    return one


#: the surface builders of the last chunk built (:func:`_surface_builders`), by what they were made of
_BUILDERS: dict = {}


def release_builders() -> None:
    """Drop the surface builders kept for the next chunk (their device arrays); at a batch's end."""
    _BUILDERS.clear()


def _surface_builders(scenes, prim_start, device):
    """Per tube prim, a SurfaceBuilder over all worlds, as ``Simulation`` builds one per prim.

    A chunk whose prims are made of the same things as the last chunk's (world count, rest points
    and spoke lengths shared by its worlds, as a table of plain values makes them) takes the last
    chunk's builders again: their arrays are written afresh each frame, and its frames are stored
    after the last chunk's on the same device."""
    from ..surface.builder import SurfaceBuilder

    out = []
    W = len(scenes)
    key = _builders_key(scenes, prim_start, device)
    if key is not None and key in _BUILDERS:
        return _BUILDERS[key]
    plain = isinstance(scenes, PlainScenes)  # (whose worlds share the base scene's geometry)
    for k, t in enumerate(scenes[0].tubes):
        specs = [t] * W if plain else [s.tubes[k] for s in scenes]
        if all(u.spoke_lengths is None and u.radius is t.radius for u in specs):  # the variants share the radii
            lengths = np.repeat(t.radius[:, None], t.params.spokes, axis=1)
        else:
            lengths = np.stack([u.spoke_lengths if u.spoke_lengths is not None
                                else np.repeat(u.radius[:, None], u.params.spokes, axis=1) for u in specs])  # fmt: skip
            if np.all(lengths == lengths[:1]):
                lengths = lengths[0]  # one row serves every world
        rest = t.points
        if not all(u.points is t.points for u in specs):  # (a table's points or widths: per world where they differ)
            rest = np.stack([u.points for u in specs])
            if np.all(rest == rest[:1]):
                rest = t.points
        out.append(
            SurfaceBuilder(
                tube_node_start=prim_start[k] + np.concatenate([[0], np.cumsum(t.curve_counts)]),
                rest_q=rest, spokes=t.params.spokes, spoke_lengths=lengths,
                reference_normal=t.params.reference_normal, frames=t.params.frames, caps=t.params.caps,
                world_count=W, device=device,
            )  # fmt: skip
        )
    _BUILDERS.clear()
    if key is not None:
        _BUILDERS[key] = out
    return out


def _builders_key(scenes, prim_start, device):
    """What :func:`_surface_builders` makes its builders of, or None where the worlds' rest points
    or spoke lengths differ (or are not the first scene's own arrays)."""
    first = scenes[0].tubes
    parts = [str(wp.get_device(device)), len(scenes), tuple(prim_start.tolist())]
    plain = isinstance(scenes, PlainScenes)  # (whose worlds share the base scene's geometry)
    for k, t in enumerate(first):
        if t.spoke_lengths is not None or not (plain or all(s.tubes[k].points is t.points and s.tubes[k].radius is t.radius
                                                            and s.tubes[k].spoke_lengths is None for s in scenes)):  # fmt: skip
            return None
        p = t.params
        parts.append((t.points.tobytes(), t.radius.tobytes(), tuple(t.curve_counts.tolist()), p.spokes, p.frames, p.caps,
                      None if p.reference_normal is None else tuple(np.asarray(p.reference_normal, dtype=float).tolist())))  # fmt: skip
    return tuple(parts)


def initial_state(worlds: Worlds):
    """``(state, next_state, control)`` at rest: each world at its own rest shape, pins there."""
    m = worlds.model
    q = worlds.rest_q()
    return m.state(q), m.state(q), m.control(q)
