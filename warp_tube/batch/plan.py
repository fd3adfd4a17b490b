"""Which variants run together: groups that share everything a run fixes once, cut into chunks.

Variants run as the worlds of one model (:mod:`warp_tube.batch.worlds`) when they agree on what
the model, the solver and the surface builders hold once for all worlds, so that each world
computes what the variant alone would (``warp-tube run``):

- topology: per tube prim its curve point counts, pinned points, spoke count, frames, caps and
  reference normal; per force its tube, point and assistant line; moving pins or not;
- time stepping: the integrator and substeps the variant alone gets (``Simulation``'s choice from
  its own stability bound), gravity, and the stage's frames, time codes and units;
- with the implicit integrator, its shortest rest segment (the solver's convergence tolerance).

Everything else (materials, damping, forces and their samples, anchors, the rest shape and the
widths, whose rest frames and inner-bend guard window the surface builders hold per world) may
differ from world to world. A group is cut into chunks of at
most ``chunk`` variants in batch order; chunks are the unit of work of a worker and of resuming.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import repeat
from operator import attrgetter, eq, is_, itemgetter
from types import SimpleNamespace
from typing import NamedTuple

import numpy as np

from ..centerline.policy import explain_integrator, is_forced
from ..scene.spec import Scene

__all__ = ["Chunk", "RunChoice", "run_choice", "run_choices", "group_key", "plain_group_keys", "plan_chunks", "by_identity"]


class RunChoice(NamedTuple):
    """What ``Simulation`` would pick for a scene alone: integrator, substeps per frame and the
    substep [s]; ``min_segment`` [m] is its shortest rest segment; ``why``: what the choice was
    made from (settings, stability bound [s], frame duration [s], implicit cost ratio), which
    :attr:`reason` puts in words when asked. (A named tuple: one per variant, made faster than a
    frozen dataclass.)"""

    integrator: str
    substeps: int
    dt: float
    min_segment: float
    why: tuple

    @property
    def reason(self) -> str:
        """Why, in words (``Simulation.reason``)."""
        return explain_integrator(*self.why)

    @property
    def forced(self) -> bool:
        """Whether the scene forces a substep beyond its stability bound (expect a blow-up)."""
        return is_forced(*self.why[:3])


@dataclass(frozen=True)
class Chunk:
    """Variants (batch indices, increasing) that run as the worlds of one model."""

    id: int
    group: int
    indices: tuple[int, ...]


def by_identity(memo: dict, arrays: tuple, extra: tuple, make, of):
    """``make(of)``, worked out once per set of ``arrays`` (and plain values ``extra``) in
    ``memo``: by the arrays' identities, a batch's variants mostly sharing their tubes' arrays
    (the arrays are kept in ``memo``, so that their ids stay theirs while it lives)."""
    key = (*map(id, arrays), *extra)
    hit = memo.get(key)
    if hit is None:
        hit = memo[key] = (make(of), arrays)
    return hit[0]


def _tube_key(t, memo: dict) -> tuple:
    """What of a tube prim the stability bound depends on (content, not identity): its geometry
    (read once per set of arrays, :func:`by_identity`) and its parameters."""
    geometry = by_identity(memo, (t.points, t.radius, t.curve_counts, t.pinned, t.anchors), (), _geometry_key, t)
    return geometry, t.params


def _geometry_key(t) -> tuple:
    return t.points.tobytes(), t.radius.tobytes(), tuple(t.curve_counts.tolist()), t.pinned.tobytes(), t.anchors.tobytes()


def _group_arrays(t) -> tuple:
    """The parts of a tube's :func:`group_key` read from its arrays."""
    return tuple(t.curve_counts.tolist()), t.pinned.tobytes()


#: scenes of one layout are discretised together up to this many nodes at a time (run_choices)
CHOICE_BLOCK_NODES = 1 << 20


def run_choices(scenes: list[Scene], block: int | None = None, plain: bool = False, keep=None) -> list[RunChoice]:
    """The integrator and substeps ``Simulation(scene)`` chooses for each scene alone.

    The policy is the one ``Simulation`` applies (:func:`warp_tube.centerline.policy.choose_integrator`), given each scene's stability
    bound (``critical_time_step`` of its own nodes), so the batch cannot drift from it. Scenes of
    one layout (curve point counts, and the forces' tubes and lines) are discretised together,
    ``block`` at a time (the per-node parameters of a scene holding them all, with the layout's
    topology; read per scene), and scenes whose tubes agree in everything the bound depends on
    share one answer. ``block``: scenes at a time (default: up to :data:`CHOICE_BLOCK_NODES`
    nodes). ``plain``: the scenes were made from one base scene by plain values (``Variants.plain``):
    one layout, and equal scenes are not looked for. ``keep``: a
    :class:`~warp_tube.batch.nodes.KeptNodes` that keeps the scenes' per-node parameters, or None.
    """
    out: list = [None] * len(scenes)
    first_of: dict = {}  # content key -> index of the first scene with it
    keys: list = []
    layouts: dict = {}
    memo: dict = {}
    if plain:
        layouts = {None: list(range(len(scenes)))} if scenes else {}
    else:
        for i, s in enumerate(scenes):
            tubes = tuple(_tube_key(t, memo) for t in s.tubes)
            # the forces' tubes and lines: how many lines each tube carries, which the bound counts
            lines = tuple((f.tube, f.assistant_line) for f in s.forces)
            key = (tubes, lines, s.settings, s.stage.frame_dt)
            keys.append(key)
            if first_of.setdefault(key, i) != i:  # (one hash of the key)
                continue
            layout = (tuple(g[2] for g, _ in tubes), lines)  # curve point counts, lines on each tube
            layouts.setdefault(layout, []).append(i)
    for members in layouts.values():
        one = None  # the layout's topology, built once
        nodes = sum(len(t.points) for t in scenes[members[0]].tubes)
        size = block or max(1, CHOICE_BLOCK_NODES // max(nodes, 1))
        for b in range(0, len(members), size):
            idx = members[b : b + size]
            one = one or _topology(scenes[idx[0]])
            # (plain: every scene in order, a slice; of PlainScenes, one that makes no scene)
            part = scenes[idx[0] : idx[-1] + 1] if plain else [scenes[i] for i in idx]
            for i, choice in zip(idx, _choices_of(part, one, idx, keep)):
                out[i] = choice
    for i, key in enumerate(keys):  # (the scenes equal to an earlier one)
        if out[i] is None:
            out[i] = out[first_of[key]]
            if keep is not None:
                keep.same_as(i, first_of[key])
    return out


def _topology(scene: Scene):
    """The model of ``scene`` on the CPU: the topology of the scenes of its layout (nodes, and
    the forces' lines on each tube)."""
    from ..model.tube import build_model

    return build_model(scene, world_count=1, device="cpu")


def _choices_of(scenes: list[Scene], one, indices, keep) -> list[RunChoice]:
    """run_choices for scenes of one layout (``one``: :func:`_topology` of one of them),
    discretised in one build (kept in ``keep`` as those of ``indices``, unless None)."""
    from ..centerline.policy import decide_integrator, decide_integrators, implicit_cost_ratio, substeps_for
    from ..centerline.stability import critical_time_steps
    from .fastread import PlainScenes
    from .worlds import scenes_node_parameters

    per_node = scenes_node_parameters(scenes)  # every scene's nodes, scene after scene
    if keep is not None:
        keep.add(indices, per_node)
    h = SimpleNamespace(**per_node, tube_al_force=one.host.tube_al_force)
    tubes = len(scenes[0].tubes)
    plain = isinstance(scenes, PlainScenes)  # (their columns read, the scenes not made)
    if plain:  # (each scene's largest: of its row of tubes)
        damping = scenes.materials(("spring_damping",)).reshape(len(scenes), tubes).max(axis=1)
    elif all(map(eq, map(len, map(attrgetter("tubes"), scenes)), repeat(tubes))):
        damping = np.fromiter((t.params.spring_damping for s in scenes for t in s.tubes), np.float64, tubes * len(scenes))
        damping = damping.reshape(len(scenes), tubes).max(axis=1)
    else:
        damping = np.array([max([t.params.spring_damping for t in s.tubes], default=0.0) for s in scenes])
    bounds = critical_time_steps(h, len(scenes), one.features.assistant_line, damping)
    seg = np.asarray(h.seg_rest_length).reshape(len(scenes), -1)
    seg_min = np.where(seg > 0, seg, np.inf).min(axis=1)
    cost = implicit_cost_ratio(one)
    seg_min = np.where(np.isfinite(seg_min), seg_min, 0.0).tolist()
    settings, stage = scenes[0].settings, scenes[0].stage
    frame_dt = stage.frame_dt
    shared = plain or ((all(map(is_, map(attrgetter("settings"), scenes), repeat(settings)))
                        or all(s.settings == settings for s in scenes))
                       and (all(map(is_, map(attrgetter("stage"), scenes), repeat(stage)))
                            or all(s.stage.frame_dt == frame_dt for s in scenes)))  # fmt: skip
    decided = decide_integrators(settings, bounds, frame_dt, cost) if shared else None
    if decided is not None:  # (every scene's choice at once: made as RunChoice._make makes it)
        implicit, substeps, dt = decided
        names = map(("semiImplicitEuler", "implicitEuler").__getitem__, implicit.tolist())
        each = repeat(settings) if plain else map(attrgetter("settings"), scenes)  # (plain: the base's, every one)
        why = zip(each, bounds.tolist(), repeat(frame_dt), repeat(cost))
        return list(map(tuple.__new__, repeat(RunChoice), zip(names, substeps.tolist(), dt.tolist(), seg_min, why)))
    out = []
    for scene, hc, seg in zip(scenes, bounds.tolist(), seg_min):
        settings, frame_dt = scene.settings, scene.stage.frame_dt
        integrator, dt = decide_integrator(settings, hc, frame_dt, cost)
        substeps = substeps_for(frame_dt, dt, settings)
        out.append(RunChoice(integrator, substeps, frame_dt / substeps, seg, (settings, hc, frame_dt, cost)))
    return out


def run_choice(scene: Scene) -> RunChoice:
    """:func:`run_choices` of one scene."""
    return run_choices([scene])[0]


def group_key(scene: Scene, choice: RunChoice, memo: dict | None = None) -> tuple:
    """Variants with equal keys run as worlds of one model (see the module docstring).

    ``memo``: a dict kept over the calls for one batch's variants, where the parts of a tube's
    key read from its arrays are worked out once per set of arrays (:func:`by_identity`), or None."""
    s = scene.stage
    memo = {} if memo is None else memo
    tubes = []
    for t in scene.tubes:
        p = t.params
        arrays = by_identity(memo, (t.curve_counts, t.pinned), (), _group_arrays, t)
        tubes.append((t.path, arrays[0], arrays[1], p.spokes, p.frames, p.caps, p.reference_normal, t.pin_track is not None))
    forces = tuple((f.tube, f.point, f.assistant_line) for f in scene.forces)
    run = (choice.integrator, choice.substeps, scene.settings.gravity, s.start_time_code, s.end_time_code,
           s.time_codes_per_second, s.frames_per_second, s.meters_per_unit, s.up_axis)  # fmt: skip
    implicit = choice.min_segment if choice.integrator == "implicitEuler" else None
    return (tuple(tubes), forces, run, implicit)


def plain_group_keys(first: Scene, choices: list[RunChoice], memo: dict | None = None) -> list:
    """:func:`group_key` of each variant made by plain values (``Variants.plain``), ``first`` the
    first of them: they differ only in tube materials and force vectors, which no key holds, so a
    key follows from the run choice's integrator, substeps and shortest segment, worked out once
    for each."""
    ks = list(map(itemgetter(0, 1, 3), choices))  # (integrator, substeps, min_segment)
    by_choice = dict.fromkeys(ks)
    for c in choices:
        k = (c.integrator, c.substeps, c.min_segment)
        if by_choice[k] is None:
            by_choice[k] = group_key(first, c, memo)
            if None not in by_choice.values():
                break
    return list(map(by_choice.__getitem__, ks))


def plan_chunks(keys: list, chunk: int) -> list[Chunk]:
    """Chunks of at most ``chunk`` variants with equal keys, in batch order (groups ordered by
    their first variant); deterministic for given keys and ``chunk``."""
    groups: dict = {}
    of_object: dict = {}  # a key object's id -> its group's members (variants mostly share a few keys)
    for i, k in enumerate(keys):
        members = of_object.get(id(k))
        if members is None:
            members = of_object[id(k)] = groups.setdefault(k, [])
        members.append(i)
    out = []
    for g, members in enumerate(groups.values()):
        for s in range(0, len(members), chunk):
            out.append(Chunk(id=len(out), group=g, indices=tuple(members[s : s + chunk])))
    return out
