"""Per-world control of a batch: each world's point forces, moving pins and assistant lines.

The same rules as ``Simulation``'s control (see :mod:`warp_tube.sim.simulation`), applied to every
world at once with its own variant's data: forces are evaluated at the middle of each frame
(linear between samples, held outside them, as ``ForceSpec.at``) and held over it; time-sampled
pins move linearly between frames; a force's assistant line is built from the world's current
shape when the force starts or turns by more than ``AL_REBUILD_ANGLE``, removed when it becomes
zero, and not built within ``AL_MIN_ANGLE`` of the tube's axis (on the device, each world with
its own forces, shape and radii: :mod:`warp_tube.sim.assistant_lines`). Worlds marked dead (a variant that
failed) get no forces, so their state stays finite while the others go on.
"""

from __future__ import annotations

from itertools import repeat
from operator import attrgetter, is_

import numpy as np

from ..sim.assistant_lines import AssistantLines
from .fastread import PlainScenes
from .worlds import Worlds

__all__ = ["WorldControl", "interpolate"]


def interpolate(t: float, times: np.ndarray, values: np.ndarray) -> np.ndarray:
    """``np.interp`` of every row at ``t``: ``times`` (K,) increasing [s], ``values`` (R, K, 3)
    [N]; returns (R, 3). The same arithmetic as ``np.interp`` (held before the first and after
    the last sample; ``slope * (t - t_j) + v_j`` between), for every row in one pass."""
    K = len(times)
    if K == 1 or t <= times[0]:
        return values[:, 0].copy()
    if t >= times[-1]:
        return values[:, -1].copy()
    j = int(np.searchsorted(times, t, side="right")) - 1
    if times[j] == t:
        return values[:, j].copy()
    slope = (values[:, j + 1] - values[:, j]) / (times[j + 1] - times[j])
    out = slope * (t - times[j]) + values[:, j]
    bad = np.isnan(out)
    if bad.any():  # as np.interp: try from the other end of the interval
        other = slope * (t - times[j + 1]) + values[:, j + 1]
        out = np.where(bad, other, out)
    return out


class WorldControl:
    """Fills a batch's ``TubeControl`` (and assistant-line state) frame by frame.

    Args:
        worlds: the batch's worlds.
        control: its ``TubeControl``.
        frame_dt: time between output frames [s].
    """

    def __init__(self, worlds: Worlds, control, frame_dt: float):
        m = worlds.model
        self.worlds, self.control, self.frame_dt = worlds, control, frame_dt
        W = m.world_count
        h = m.host  # the topology, shared by every world
        self.force_node = np.asarray(h.force_node, dtype=np.int64)
        order = np.asarray(h.force_order, dtype=np.int64)
        # Per model force: worlds grouped by their sample times, with their values (the times
        # read once per array: variants made from one scene share it).
        self._forces = []
        scenes = worlds.scenes
        plain = isinstance(scenes, PlainScenes)  # (every world's samples at the same times: from the columns)
        for a, k in enumerate(order):
            if plain:
                self._forces.append([(scenes.force_times(k), np.arange(W), scenes.force_values(k))])
                continue
            fs = [s.forces[k] for s in scenes]
            times_of = list(map(attrgetter("times"), fs))
            if all(map(is_, times_of, repeat(times_of[0]))):  # (one array: variants made from one scene)
                self._forces.append([(times_of[0], np.arange(W), np.stack(list(map(attrgetter("values"), fs))))])
                continue
            by_array: dict = {}
            for w, f in enumerate(fs):
                by_array.setdefault(id(f.times), []).append(w)
            groups: dict = {}  # sample times' bytes -> (times, worlds)
            for ws in by_array.values():
                times = fs[ws[0]].times
                groups.setdefault(times.tobytes(), (times, []))[1].extend(ws)
            per_force = []
            for times, ws in groups.values():
                ws = sorted(ws)
                per_force.append((times, np.asarray(ws), np.stack([fs[w].values for w in ws])))
            self._forces.append(per_force)
        self.dead = np.zeros(W, dtype=bool)
        self.lines = AssistantLines(m, worlds.host.node_radius) if m.features.assistant_line else None
        # Moving pins: per world its pinned points' track, (W, frames, pinned, 3) [m], per prim.
        self._pins = []
        for k, t in enumerate(worlds.scenes[0].tubes):
            if t.pin_track is not None:
                tracks = [t.pin_track] * W if plain else [s.tubes[k].pin_track for s in scenes]  # (plain: the base's)
                F = max(len(tr) for tr in tracks)  # (a shorter track holds its last frame, as it would alone)
                track = np.stack([np.concatenate([tr, np.repeat(tr[-1:], F - len(tr), axis=0)]) for tr in tracks])
                self._pins.append((worlds.prim_start[k] + t.pinned, track))
        self._f_last = None  # the forces last written to the control, (W, F, 3) [N]
        self._constant = all(len(times) == 1 for groups in self._forces for times, _, _ in groups)
        self._f_const = self._f_const_dead = None  # constant forces, and the dead worlds they were made for

    @property
    def moving_pins(self) -> bool:
        return bool(self._pins)

    def forces_at(self, t: float) -> np.ndarray:
        """Each world's model forces at time ``t`` [s], (W, F, 3) [N]; 0 in dead worlds. Where
        every force is held constant (one sample each) the same array comes back frame after
        frame until a world dies (read only)."""
        if self._constant and self._f_const is not None and np.array_equal(self.dead, self._f_const_dead):
            return self._f_const
        W = self.worlds.world_count
        out = np.zeros((W, len(self._forces), 3))
        for a, groups in enumerate(self._forces):
            for times, ws, values in groups:
                out[ws, a] = interpolate(t, times, values)
        out[self.dead] = 0.0
        if self._constant:
            out.flags.writeable = False
            self._f_const, self._f_const_dead = out, self.dead.copy()
        return out

    def update(self, frame: int, state) -> None:
        """Set the control for advancing output frame ``frame`` to ``frame + 1`` from ``state``."""
        m, c = self.worlds.model, self.control
        W, N = m.world_count, m.node_count
        if m.force_count:
            f = self.forces_at((frame + 0.5) * self.frame_dt)
            if self._f_last is None or (f is not self._f_last and not np.array_equal(f, self._f_last)):  # held: written once
                fe = np.zeros((W, N, 3))
                for a, node in enumerate(self.force_node):  # in force order, as np.add.at sums them
                    fe[:, node] += f[:, a]
                c.node_f_ext.assign(fe)
                self._f_last = f
            if self.lines is not None:
                self.lines.set_forces(f)
                self.lines.update(state, c)
        if self._pins:
            q0 = c.pin_q_end.numpy()
            q1 = q0.copy()
            for nodes, track in self._pins:
                q1[:, nodes] = track[:, min(frame + 1, track.shape[1] - 1)]
            c.pin_q_start.assign(q0)
            c.pin_q_end.assign(q1)
