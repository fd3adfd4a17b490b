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
import warp as wp

from ..kernels.frame_store import gather_columns_kernel, scatter_rows_kernel
from ..sim.control import AL_MIN_ANGLE, AL_REBUILD_ANGLE, AssistantLineArrays
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
        self._host = {}  # device array address -> its reused page-locked host copy
        self._columns = {}  # (node, node) -> their column indices and gather buffers on the device
        self._al_host = None  # the lines' rest lengths (as on the device) and rows to build in
        self._row_buffers = {}  # line length -> device buffers for the rows of new lines

    def _fetch(self, a):
        """Device array ``a`` copied to the host: into a page-locked buffer kept for it (on CUDA;
        fresh pageable memory and its page faults made each copy cost ~0.25 ms), as a NumPy view
        valid until the next fetch of ``a``."""
        if not a.device.is_cuda:
            return a.numpy()
        buf = self._host.get(a.ptr)
        if buf is None:
            buf = self._host[a.ptr] = wp.empty(a.shape, dtype=a.dtype, device="cpu", pinned=True)
        wp.copy(buf, a)
        wp.synchronize_device(a.device)
        return buf.numpy()

    def _off_axis(self, a: int, build: np.ndarray, d: np.ndarray, before: int, after: int, state) -> np.ndarray:
        """Whether each world in ``build`` would build force ``a``'s line (direction ``d``, (W, 3))
        or drop it (a push within AL_MIN_ANGLE of the axis, with a line), from the tangent between nodes ``before``
        and ``after`` alone (two columns of the state read back, not all of it); (W,) bool. The
        same float64 arithmetic as the build below, so the two agree."""
        cols = self._columns.get((before, after))
        if cols is None:
            idx = wp.array(np.array([before, after], dtype=np.int32), dtype=int, device=self.control.node_f_ext.device)
            out = [wp.empty((self.worlds.world_count, 2), dtype=wp.vec3, device=idx.device) for _ in range(2)]
            cols = self._columns[(before, after)] = (idx, out)
        idx, (hi, lo) = cols
        for src, dst in ((state.node_q, hi), (state.node_q_lo, lo)):
            wp.launch(gather_columns_kernel, dim=dst.shape, inputs=[src, idx, dst], device=idx.device)
        q = self._fetch(hi).astype(np.float64) + self._fetch(lo)
        tangent = q[:, 1] - q[:, 0]
        tangent = tangent / np.maximum(np.linalg.norm(tangent, axis=-1), 1e-30)[:, None]
        across = d - np.sum(d * tangent, axis=-1)[:, None] * tangent
        axial = np.linalg.norm(across, axis=-1) < math.sin(AL_MIN_ANGLE)
        return build & (~axial | (self._al_active[:, a] != 0))

    @property
    def moving_pins(self) -> bool:
        return bool(self._pins)

    def forces_at(self, t: float) -> np.ndarray:
        """Each world's model forces at time ``t`` [s], (W, F, 3) [N]; 0 in dead worlds."""
        W = self.worlds.world_count
        out = np.zeros((W, len(self._forces), 3))
        for a, groups in enumerate(self._forces):
            for times, ws, values in groups:
                out[ws, a] = interpolate(t, times, values)
        out[self.dead] = 0.0
        return out

    def update(self, frame: int, state) -> None:
        """Set the control for advancing output frame ``frame`` to ``frame + 1`` from ``state``."""
        m, c = self.worlds.model, self.control
        W, N = m.world_count, m.node_count
        if m.force_count:
            f = self.forces_at((frame + 0.5) * self.frame_dt)
            if self._f_last is None or not np.array_equal(f, self._f_last):  # held forces: written once
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
        positions = lines = None
        cos_rebuild, sin_min = math.cos(AL_REBUILD_ANGLE), math.sin(AL_MIN_ANGLE)
        for a in range(m.force_count):
            if not self.uses_al[a]:
                continue
            mag = np.linalg.norm(f[:, a], axis=-1)
            zero = mag == 0.0
            drop = zero & (active[:, a] != 0)
            if drop.any():
                active[drop, a] = 0
                changed = True
            d = f[:, a] / np.where(zero, 1.0, mag)[:, None]
            keep = (active[:, a] != 0) & (np.sum(d * self._al_dir[:, a], axis=-1) >= cos_rebuild)
            build = ~zero & ~keep
            if not build.any():
                continue
            t = h.force_tube[a]
            s, e = h.tube_node_start[t], h.tube_node_start[t + 1]
            k = h.force_node[a]
            if positions is None and not self._off_axis(a, build, d, max(k - 1, s), min(k + 1, e - 1), state).any():
                # the worlds to build are all within AL_MIN_ANGLE of the axis, and none has a line
                # to drop: nothing changes (the whole state is not read)
                continue
            if positions is None:
                # float64, compensated (float32 + low-order part), as Simulation builds lines
                q = self._fetch(state.node_q).astype(np.float64) + self._fetch(state.node_q_lo)
                positions = (q, self._fetch(state.node_qd))
            state_q, state_qd = positions
            ws = np.flatnonzero(build)
            tangent = state_q[ws, min(k + 1, e - 1)] - state_q[ws, max(k - 1, s)]
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
            ws, across, norm_across = ws[~axial], across[~axial], norm_across[~axial]
            if not len(ws):
                continue
            if lines is None:
                lines = self._lines()
            offset_dir = across / norm_across[:, None]
            p0 = h.al_start[a]
            off = self.worlds.host.node_radius[ws, s:e, None] * offset_dir[:, None, :]
            x = state_q[ws, s:e]
            lines.build(ws, slice(p0, p0 + e - s), x, x + off, state_qd[ws, s:e])
            self._write_rows(lines, ws, p0, e - s, state)
            active[ws, a] = 1
            changed = True
        if lines is not None:
            for n, v in lines.lengths.items():
                getattr(c, n).assign(v)
        if changed:
            c.al_active.assign(active)

    def _lines(self) -> AssistantLineArrays:
        """The lines' rest lengths as the device holds them (this class is their only writer, so
        it keeps them on the host and never reads them back), with host rows to build new lines
        in: only the rows built are written to the device (:meth:`_write_rows`)."""
        if self._al_host is None:
            W, L = self.worlds.world_count, max(self.worlds.model.al_slots, 1)
            rows = [np.zeros((W, L, 3), dtype=np.float32) for _ in range(3)]
            self._al_host = AssistantLineArrays(*rows, {n: np.zeros((W, L), dtype=np.float32) for n in AssistantLineArrays.LENGTHS})
        return self._al_host

    def _write_rows(self, lines: AssistantLineArrays, ws: np.ndarray, p0: int, n: int, state) -> None:
        """Copy the line points just built (worlds ``ws``, slots ``p0 .. p0 + n``) into ``state``,
        through device buffers kept for it (no allocation per frame)."""
        dev = state.al_q.device
        W, R = self.worlds.world_count, len(ws)
        held = self._row_buffers.get(n)
        if held is None:
            held = self._row_buffers[n] = (wp.empty(W, dtype=int, device=dev), [wp.empty((W, n), dtype=wp.vec3, device=dev) for _ in range(3)])
        rows, src = held
        rows[:R].assign(ws.astype(np.int32))
        for buf, a in zip(src, (lines.q_hi, lines.q_lo, lines.qd)):
            buf[:R].assign(np.ascontiguousarray(a[ws, p0 : p0 + n]))
        wp.launch(scatter_rows_kernel, dim=(R, n), inputs=[rows, int(p0), *src, state.al_q, state.al_q_lo, state.al_qd], device=dev)
