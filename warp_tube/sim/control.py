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
  :data:`AL_MIN_ANGLE` of the tube's axis. The rule runs on the model's device, world by world
  (:mod:`warp_tube.sim.assistant_lines`).
"""

from __future__ import annotations

import logging

import numpy as np

from ..scene.spec import MAX_FORCE_N, Scene
from .assistant_lines import AL_MIN_ANGLE, AL_REBUILD_ANGLE, AssistantLines

log = logging.getLogger(__name__)

__all__ = ["FrameControl", "AL_REBUILD_ANGLE", "AL_MIN_ANGLE", "MAX_FORCE_N", "MAX_PIN_M"]

#: the largest pin target coordinate :meth:`FrameControl.set_pin_targets` takes [m] (as the scene
#: reader's largest coordinate: past any tube).
MAX_PIN_M = 1e6


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
        self._pins_written = False  # whether update last moved the pins (pin_q_start holds where from)
        # What this object last wrote into the control (it alone writes these): the point forces
        # are uploaded only when they change.
        self._fe_last = None  # (node_count, 3) [N]
        self.lines = AssistantLines(model, model.host.node_radius) if model.features.assistant_line else None
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
            ValueError: ``vector`` is not three finite numbers of at most :data:`MAX_FORCE_N` (checked
            here, before any step).
        """
        idx = self.force_index(force)
        shown = repr(vector) if len(repr(vector)) <= 80 else repr(vector)[:77] + "..."
        v = _numbers(vector, f"set_force({force!r}): vector {shown}: expected three numbers of at most 1e9 N")
        if v.shape not in ((3,), (1, 3)):
            raise ValueError(f"set_force({force!r}): vector of shape {v.shape}: expected three numbers [N]")
        if not np.isfinite(v).all():
            raise ValueError(f"set_force({force!r}): vector {tuple(v.reshape(3).tolist())}: expected finite numbers [N]")
        if np.abs(v).max() > MAX_FORCE_N:
            raise ValueError(f"set_force({force!r}): vector {tuple(v.reshape(3).tolist())}: expected at most "
                             "1e9 N a component (as a scene's warptube:force)")  # fmt: skip
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
        pinned, path = self.scene.tubes[k].pinned, self.scene.tubes[k].path
        if isinstance(positions, dict):  # point index -> position, every pinned point once
            keys = list(positions)
            if not all(isinstance(i, (int, np.integer)) and not isinstance(i, bool) for i in keys) or \
                    sorted(int(i) for i in keys) != pinned.tolist():  # fmt: skip
                raise ValueError(f"pin targets of {path}: points {keys!r}: expected every pinned point once, "
                                 f"{pinned.tolist()}")  # fmt: skip
            positions = [positions[i] for i in pinned.tolist()]
        p = _numbers(positions, f"pin targets of {path}: {positions!r}: expected numbers") * self.scene.stage.meters_per_unit
        if p.shape != (len(pinned), 3):
            raise ValueError(f"pin targets of {path}: shape {p.shape}, expected ({len(pinned)}, 3)")
        if not np.isfinite(p).all():
            raise ValueError(f"pin targets of {path}: non-finite values: expected finite positions")
        if np.abs(p).max(initial=0.0) > MAX_PIN_M:
            raise ValueError(f"pin targets of {path}: a coordinate of {np.abs(p).max():.3g} m: expected at most "
                             f"1e6 m (metersPerUnit {self.scene.stage.meters_per_unit:g})")  # fmt: skip
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
            if self.lines is not None:
                self.lines.set_forces(f)
                self.lines.update(state, c)
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
            self._pins_written = True

    def undo_pins(self) -> None:
        """Put the pins' end positions back where the frame last written by :meth:`update` started
        them (that frame failed and was not kept: the next one starts from there)."""
        if self._pins_written:
            self.control.pin_q_end.assign(self.control.pin_q_start.numpy().copy())
            self._pins_written = False


def _numbers(value, message: str) -> np.ndarray:
    """``value`` as float64 numbers, or a ValueError with ``message`` (bools, strings and complex
    numbers are not numbers here)."""
    try:
        raw = np.asarray(value)
        if raw.dtype.kind in "bcSUV" or (raw.dtype.kind == "O" and any(isinstance(x, (bool, np.bool_)) for x in raw.flat)):
            raise TypeError
        if isinstance(value, (list, tuple)) and any(isinstance(x, (bool, np.bool_)) for x in np.asarray(value, dtype=object).flat):
            raise TypeError  # ((True, 0, 0) is an int array to NumPy)
        return np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):  # (OverflowError: an integer beyond any float, 10**400)
        raise ValueError(message) from None


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
