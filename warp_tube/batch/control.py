"""Per-world control of a batch: each world's point forces, moving pins and assistant lines.

The same rules as ``Simulation``'s control (see :mod:`warp_tube.sim.simulation`), applied to every
world at once with its own variant's data: forces are evaluated at the middle of each frame
(linear between samples, held outside them, as ``ForceSpec.at``) and held over it; time-sampled
pins move linearly between frames; a force's assistant line is built from the world's current
shape when the force starts or turns by more than ``AL_REBUILD_ANGLE``, removed when it becomes
zero, and not built within ``AL_MIN_ANGLE`` of the tube's axis. Worlds marked dead (a variant that
failed) get no forces, so their state stays finite while the others go on.
"""

from __future__ import annotations

import math

import numpy as np

from ..sim.control import AL_MIN_ANGLE, AL_REBUILD_ANGLE, AssistantLineArrays
from .rows import WorldRows
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
        # Per model force: worlds grouped by their sample times, with their values.
        self._forces = []
        for a, k in enumerate(order):
            groups: dict = {}
            for w, s in enumerate(worlds.scenes):
                f = s.forces[k]
                groups.setdefault(f.times.tobytes(), (f.times, [], []))
                groups[f.times.tobytes()][1].append(w)
                groups[f.times.tobytes()][2].append(f.values)
            self._forces.append([(times, np.asarray(ws), np.stack(vals)) for times, ws, vals in groups.values()])
        self.dead = np.zeros(W, dtype=bool)
        self.uses_al = np.asarray(h.force_uses_al, dtype=bool)
        self._al_dir = np.zeros((W, m.force_count, 3))
        self._al_active = np.zeros((W, max(m.force_count, 1)), dtype=np.int32)
        # Moving pins: per world its pinned points' track, (W, frames, pinned, 3) [m], per prim.
        self._pins = []
        for k, t in enumerate(worlds.scenes[0].tubes):
            if t.pin_track is not None:
                track = np.stack([s.tubes[k].pin_track for s in worlds.scenes])
                self._pins.append((worlds.prim_start[k] + t.pinned, track))
        self._f_last = None  # the forces last written to the control, (W, F, 3) [N]
        self._constant = all(len(times) == 1 for groups in self._forces for times, _, _ in groups)
        self._f_const = self._f_const_dead = None  # constant forces, and the dead worlds they were made for
        self._directions: dict = {}  # force -> (the forces array they are of, zero per world, unit direction per world)
        self.rows = WorldRows(m.device)  # the few worlds' rows a frame's new lines read and write

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
            if m.features.assistant_line:
                self._update_assistant_lines(f, state)
        if self._pins:
            q0 = c.pin_q_end.numpy()
            q1 = q0.copy()
            for nodes, track in self._pins:
                q1[:, nodes] = track[:, min(frame + 1, track.shape[1] - 1)]
            c.pin_q_start.assign(q0)
            c.pin_q_end.assign(q1)

    def _update_assistant_lines(self, f: np.ndarray, state) -> None:
        m, c, h = self.worlds.model, self.control, self.worlds.model.host
        active = self._al_active
        changed = False
        cos_rebuild, sin_min = math.cos(AL_REBUILD_ANGLE), math.sin(AL_MIN_ANGLE)
        for a in range(m.force_count):
            if not self.uses_al[a]:
                continue
            held = self._directions.get(a)
            if held is None or held[0] is not f:  # (the same forces as last frame: the same directions)
                mag = np.linalg.norm(f[:, a], axis=-1)
                zero = mag == 0.0
                held = self._directions[a] = (f, zero, f[:, a] / np.where(zero, 1.0, mag)[:, None])
            _, zero, d = held
            drop = zero & (active[:, a] != 0)
            if drop.any():
                active[drop, a] = 0
                changed = True
            keep = (active[:, a] != 0) & (np.sum(d * self._al_dir[:, a], axis=-1) >= cos_rebuild)
            build = ~zero & ~keep
            if not build.any():
                continue
            t = h.force_tube[a]
            s, e = h.tube_node_start[t], h.tube_node_start[t + 1]
            k = h.force_node[a]
            ws = np.flatnonzero(build)
            # Only these worlds' tube rows come to the host: positions float64, compensated
            # (float32 + low-order part), as Simulation builds lines.
            q_hi, q_lo, qd = self.rows.take((state.node_q, state.node_q_lo, state.node_qd), ws, s, e)
            x = q_hi.astype(np.float64) + q_lo
            tangent = x[:, min(k + 1, e - 1) - s] - x[:, max(k - 1, s) - s]
            tangent = tangent / np.maximum(np.linalg.norm(tangent, axis=-1), 1e-30)[:, None]
            dw = d[ws]
            across = dw - np.sum(dw * tangent, axis=-1)[:, None] * tangent
            self._al_dir[ws, a] = dw
            norm_across = np.linalg.norm(across, axis=-1)
            axial = norm_across < sin_min
            off_axis = ws[axial & (active[ws, a] != 0)]
            if len(off_axis):
                active[off_axis, a] = 0
                changed = True
            laid = ~axial
            ws, x = ws[laid], x[laid]
            if not len(ws):
                continue
            offset_dir = across[laid] / norm_across[laid][:, None]
            off = self.worlds.host.node_radius[ws, s:e, None] * offset_dir[:, None, :]
            self._lay_lines(c, state, ws, h.al_start[a], x, x + off, qd[laid])
            active[ws, a] = 1
            changed = True
        if changed:
            c.al_active.assign(active)

    def _lay_lines(self, c, state, ws: np.ndarray, p0: int, x: np.ndarray, xp: np.ndarray, xd: np.ndarray) -> None:
        """Lay the lines of worlds ``ws`` in slots ``p0 ...`` beside tube points ``x`` (float64,
        (len(ws), n, 3) [m]) at ``xp``, moving with ``xd`` [m/s]: built compact
        (:meth:`AssistantLineArrays.build`) and written into those worlds' rows only; every other
        entry keeps its value bit for bit."""
        n = x.shape[1]
        lines = AssistantLineArrays(np.zeros((len(ws), n, 3), np.float32), np.zeros((len(ws), n, 3), np.float32),
                                    np.zeros((len(ws), n, 3), np.float32),
                                    {name: np.zeros((len(ws), n), np.float32) for name in AssistantLineArrays.LENGTHS})  # fmt: skip
        lines.build(slice(None), slice(0, n), x, xp, xd)
        L = lines.lengths
        self.rows.put(ws, [
            (state.al_q, p0, lines.q_hi, 0, n), (state.al_q_lo, p0, lines.q_lo, 0, n), (state.al_qd, p0, lines.qd, 0, n),
            (c.al_link_length, p0, L["al_link_length"], 0, n),
            (c.al_chord_length, p0, L["al_chord_length"], 0, n - 1), (c.al_fwd_length, p0, L["al_fwd_length"], 0, n - 1),
            (c.al_bwd_length, p0 + 1, L["al_bwd_length"], 1, n - 1),
        ])  # fmt: skip
