"""What drives a frame: point forces, moving pins and the assistant line, written into the
model's :class:`~warp_tube.model.tube.TubeControl` before each frame.

- Point forces are evaluated at the middle of each frame and held over it; :meth:`FrameControl.set_force`
  overrides a scene force from then on.
- Pinned points move linearly over a frame towards their target at the frame's end: a time-sampled
  ``points`` attribute's next sample, or what :meth:`FrameControl.set_pin_targets` gave.
- The assistant line of a force (section 2.2 of the paper) is built from the current shape when
  the force starts or turns by more than :data:`AL_REBUILD_ANGLE` from the direction it was built
  with, and removed when the force becomes zero. It is offset along the force's part across the
  tube at its point, by the tube's radius, and not built while the force is within
  :data:`AL_MIN_ANGLE` of the tube's axis.
"""

from __future__ import annotations

import logging
import math

import numpy as np

from ..scene.spec import Scene

log = logging.getLogger(__name__)

__all__ = ["FrameControl", "AssistantLineArrays", "AL_REBUILD_ANGLE", "AL_MIN_ANGLE"]

#: the assistant line is rebuilt when its force turns by more than this [rad].
AL_REBUILD_ANGLE = math.radians(45.0)
#: no assistant line is built for a force within this angle of the tube's axis [rad].
AL_MIN_ANGLE = math.radians(15.0)


class AssistantLineArrays:
    """The assistant lines' state and rest lengths, read to the host to build lines and written back
    whole: entries of lines not rebuilt keep their values bit for bit (the low-order part of the
    positions included).

    Shapes (W worlds, L line slots): ``q_hi``, ``q_lo``, ``qd`` (W, L, 3) float32 [m, m/s];
    ``lengths`` by name (W, L) float32 [m] (``al_link_length``, ``al_chord_length``,
    ``al_fwd_length``, ``al_bwd_length``, as :class:`~warp_tube.model.tube.TubeControl`).
    """

    LENGTHS = ("al_link_length", "al_chord_length", "al_fwd_length", "al_bwd_length")

    def __init__(self, q_hi: np.ndarray, q_lo: np.ndarray, qd: np.ndarray, lengths: dict):
        self.q_hi, self.q_lo, self.qd, self.lengths = q_hi, q_lo, qd, lengths

    @classmethod
    def read(cls, state, control, fetch=None) -> AssistantLineArrays:
        """Copy the lines' state and rest lengths of ``state`` and ``control`` to the host
        (``fetch``: a device array to a writable NumPy array; default ``wp.array.numpy``)."""
        fetch = fetch or (lambda a: a.numpy())
        lengths = {n: fetch(getattr(control, n)) for n in cls.LENGTHS}
        return cls(fetch(state.al_q), fetch(state.al_q_lo), fetch(state.al_qd), lengths)

    def build(self, worlds, slots: slice, x: np.ndarray, xp: np.ndarray, xd: np.ndarray) -> None:
        """Lay a line: slots ``slots`` of ``worlds`` (an index or a slice) at ``xp`` beside the tube
        points ``x``, both float64 (w, n, 3) [m], moving with the tube's velocities ``xd`` [m/s];
        its links, chords and diagonals get their rest lengths from these positions (unstrained)."""
        hi = xp.astype(np.float32)
        self.q_hi[worlds, slots] = hi
        self.q_lo[worlds, slots] = (xp - hi).astype(np.float32)
        self.qd[worlds, slots] = xd
        p0, n = slots.start, slots.stop - slots.start
        L = self.lengths
        L["al_link_length"][worlds, slots] = np.linalg.norm(xp - x, axis=-1)
        L["al_chord_length"][worlds, p0 : p0 + n - 1] = np.linalg.norm(xp[:, 1:] - xp[:, :-1], axis=-1)
        L["al_fwd_length"][worlds, p0 : p0 + n - 1] = np.linalg.norm(x[:, 1:] - xp[:, :-1], axis=-1)
        L["al_bwd_length"][worlds, p0 + 1 : p0 + n] = np.linalg.norm(x[:, :-1] - xp[:, 1:], axis=-1)

    def write(self, state, control) -> None:
        """Copy the lines back into ``state`` and ``control``."""
        state.al_q.assign(self.q_hi)
        state.al_q_lo.assign(self.q_lo)
        state.al_qd.assign(self.qd)
        for n, v in self.lengths.items():
            getattr(control, n).assign(v)


class FrameControl:
    """Forces, pin targets and assistant lines of a scene's model.

    Args:
        scene: the scene (forces, pin tracks, tube paths).
        model: its :class:`~warp_tube.model.tube.TubeModel`.
        control: the model's :class:`~warp_tube.model.tube.TubeControl`, written by :meth:`update`.
    """

    def __init__(self, scene: Scene, model, control):
        self.scene, self.model, self.control = scene, model, control
        self.frame_dt = scene.stage.frame_dt
        self._force_override: dict[int, np.ndarray] = {}
        self._pin_override: dict[int, np.ndarray] = {}
        self._al_dir = np.zeros((model.force_count, 3))
        # What this object last wrote into the control (it alone writes these): the point forces
        # are uploaded only when they change, and the lines' flags are not read back each frame.
        self._fe_last = None  # (node_count, 3) [N]
        self._active = np.zeros(control.al_active.shape, dtype=np.int32)  # as TubeModel.control() makes it
        prim_start = model.host.prim_node_start
        self.pinned_nodes = [prim_start[k] + t.pinned for k, t in enumerate(scene.tubes)]
        if scene.source == "<python>":  # a scene built in code (the USD reader warns as it reads a stage)
            for f in scene.forces:
                if f.point in scene.tubes[f.tube].pinned:
                    log.warning("force %s: point %d of %s is pinned: this force does nothing", f.path, f.point, scene.tubes[f.tube].path)

    @property
    def moving_pins(self) -> bool:
        """Whether any pinned point moves (time-sampled points or targets set by the user)."""
        return bool(self._pin_override) or any(t.pin_track is not None for t in self.scene.tubes)

    # -- interactive control ---------------------------------------------------------------------
    def set_force(self, force, vector) -> None:
        """Override a scene force from now on: ``force`` is its index or prim path; ``vector`` [N],
        three finite numbers.

        Raises:
            KeyError: no force at that prim path. IndexError: no force with that index. TypeError: neither
            an index nor a path (a float, a bool).
            ValueError: ``vector`` is not three finite numbers (checked here, before any step).
        """
        idx = self.force_index(force)
        try:
            v = np.asarray(vector, dtype=np.float64)
        except (TypeError, ValueError):
            raise ValueError(f"set_force({force!r}): vector {vector!r}: expected three numbers [N]") from None
        if v.shape not in ((3,), (1, 3)):
            raise ValueError(f"set_force({force!r}): vector of shape {v.shape}: expected three numbers [N]")
        if not np.isfinite(v).all():
            raise ValueError(f"set_force({force!r}): vector {tuple(v.reshape(3).tolist())}: expected finite numbers [N]")
        f = self.scene.forces[idx]
        if idx not in self._force_override and np.any(v) and f.point in self.scene.tubes[f.tube].pinned:
            log.warning("set_force(%r): point %d of %s is pinned: this force does nothing", force, f.point,
                        self.scene.tubes[f.tube].path)  # fmt: skip
        self._force_override[idx] = v.reshape(3)

    def set_pin_targets(self, tube, positions) -> None:
        """Move a tube prim's pinned points: ``positions`` [stage units], finite: shape (pinned, 3),
        one row per pinned point in ascending order of its index (``scene.tubes[k].pinned``, not the
        order ``pinnedPoints`` lists them), or a dict from each pinned point's index to its position.

        Raises:
            KeyError / IndexError: no such tube prim. ValueError: wrong shape, points or non-finite values.
        """
        k = self.tube_index(tube)
        pinned = self.scene.tubes[k].pinned
        if isinstance(positions, dict):  # point index -> position, every pinned point once
            if sorted(int(i) for i in positions) != pinned.tolist():
                raise ValueError(f"pin targets of {self.scene.tubes[k].path}: points {sorted(positions)}: expected every "
                                 f"pinned point once, {pinned.tolist()}")  # fmt: skip
            positions = [positions[i] for i in pinned.tolist()]
        try:
            p = np.asarray(positions, dtype=np.float64) * self.scene.stage.meters_per_unit
        except (TypeError, ValueError):
            raise ValueError(f"pin targets of {self.scene.tubes[k].path}: {positions!r}: expected numbers") from None
        if p.shape != (len(self.scene.tubes[k].pinned), 3):
            raise ValueError(f"pin targets of {self.scene.tubes[k].path}: shape {p.shape}, expected ({len(self.scene.tubes[k].pinned)}, 3)")
        if not np.isfinite(p).all():
            raise ValueError(f"pin targets of {self.scene.tubes[k].path}: non-finite values: expected finite positions")
        self._pin_override[k] = p

    def force_index(self, force) -> int:
        """Index of a scene force given by index or prim path (a string or an ``Sdf.Path``)."""
        return _index(force, [f.path for f in self.scene.forces], "force")

    def tube_index(self, tube) -> int:
        """Index of a tube prim given by index or prim path (a string or an ``Sdf.Path``)."""
        return _index(tube, [t.path for t in self.scene.tubes], "tube")

    # -- per frame -------------------------------------------------------------------------------
    def forces_at(self, t: float) -> np.ndarray:
        """Force of each model force (model order) at time t [s] [N], shape (force_count, 3)."""
        order = self.model.host.force_order
        out = np.zeros((len(order), 3))
        for a, k in enumerate(order):
            out[a] = self._force_override.get(int(k), None) if int(k) in self._force_override else self.scene.forces[k].at(t)
        return out

    def update(self, frame: int, state) -> None:
        """Write the control of the frame from ``frame`` to ``frame + 1``; ``state`` is the state
        at its start (read only when an assistant line is built)."""
        m, c = self.model, self.control
        W = m.world_count
        if m.force_count:
            f = self.forces_at((frame + 0.5) * self.frame_dt)
            fe = np.zeros((m.node_count, 3))
            np.add.at(fe, m.host.force_node, f)
            if self._fe_last is None or not np.array_equal(fe, self._fe_last):  # held forces: uploaded once
                c.node_f_ext.assign(np.repeat(fe[None], W, axis=0))
                self._fe_last = fe
            if m.features.assistant_line:
                self._update_assistant_lines(f, state)
        if self.moving_pins:
            q0 = c.pin_q_end.numpy()
            q1 = q0.copy()
            for k, t in enumerate(self.scene.tubes):
                nodes = self.pinned_nodes[k]
                if k in self._pin_override:
                    q1[:, nodes] = self._pin_override[k]
                elif t.pin_track is not None:
                    q1[:, nodes] = t.pin_track[min(frame + 1, len(t.pin_track) - 1)]
            c.pin_q_start.assign(q0)
            c.pin_q_end.assign(q1)

    def _update_assistant_lines(self, f: np.ndarray, state):
        m, c, h = self.model, self.control, self.model.host
        active = self._active
        changed = False
        state_q = state_qd = lines = None
        for a in range(m.force_count):
            if not h.force_uses_al[a]:
                continue
            mag = float(np.linalg.norm(f[a]))
            if mag == 0.0:
                if active[:, a].any():
                    active[:, a] = 0
                    changed = True
                continue
            d = f[a] / mag
            if active[0, a] and float(np.dot(d, self._al_dir[a])) >= math.cos(AL_REBUILD_ANGLE):
                continue
            if state_q is None:
                # Positions in float64 (compensated: float32 + low-order part), so the line is
                # built unstrained in the kernels' arithmetic.
                state_q = state.node_q.numpy().astype(np.float64) + state.node_q_lo.numpy()
                state_qd = state.node_qd.numpy()
            t = h.force_tube[a]
            s, e = h.tube_node_start[t], h.tube_node_start[t + 1]
            # Offset towards the push: the force's part across the tube at its point (world 0).
            k = h.force_node[a]
            tangent = state_q[0, min(k + 1, e - 1)] - state_q[0, max(k - 1, s)]
            tangent = tangent / max(np.linalg.norm(tangent), 1e-30)
            across = d - np.dot(d, tangent) * tangent
            self._al_dir[a] = d
            if np.linalg.norm(across) < math.sin(AL_MIN_ANGLE):
                if active[:, a].any():
                    active[:, a] = 0
                    changed = True
                continue
            if lines is None:
                lines = AssistantLineArrays.read(state, c)
            offset_dir = across / np.linalg.norm(across)
            p0 = h.al_start[a]
            off = h.node_radius[s:e, None] * offset_dir[None]
            x = state_q[:, s:e]
            lines.build(slice(None), slice(p0, p0 + e - s), x, x + off[None], state_qd[:, s:e])
            active[:, a] = 1
            changed = True
        if lines is not None:
            lines.write(state, c)
        if changed:
            c.al_active.assign(active)


def _index(which, paths: list[str], kind: str) -> int:
    """``which`` (an index, or a prim path as a string or anything whose ``str`` is one, such as
    ``Sdf.Path``) as an index into ``paths``.

    Raises:
        KeyError: no prim at that path. IndexError: the index is out of range. TypeError: neither
        an integer nor a path (a float, a bool).
    """
    if isinstance(which, (bool, float, np.floating)) or which is None:
        raise TypeError(f"{kind} {which!r}: expected an index (an integer) or a prim path")
    if isinstance(which, (int, np.integer)):
        k = int(which)
        if not 0 <= k < len(paths):
            raise IndexError(f"{kind} {k}: the scene has {len(paths)} {kind}(s)")
        return k
    path = str(which)
    if path in paths:
        return paths.index(path)
    raise KeyError(f"no {kind} at {path}")
