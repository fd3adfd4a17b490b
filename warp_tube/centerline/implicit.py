"""Implicit (backward) Euler solver: launch order and scratch allocation for
:mod:`warp_tube.kernels.implicit`.

``solver.integrate(state_in, state_out, control, dt, substeps)`` advances a whole frame in one
launch of the per-tube kernel (one thread per (world, tube), all substeps in a loop), on the CPU
and on CUDA; ``solver.step(...)`` is one substep. Each substep solves the tube's coupled linear
system (M + h C + h^2 K) dv = h (f - K u - C g) by a banded block LDL^T, so the step is not
limited by the stiffness: any stiffness at 1/60 s stays finite and, without forces doing work or
damping, loses energy instead of gaining it (backward Euler's numerical damping).
"""

from __future__ import annotations

import warp as wp

from warp_tube.kernels.implicit import ImplicitScratch, make_implicit_kernel
from warp_tube.kernels.springs import ControlArrays, ModelArrays, StateArrays, pack

from ..model.tube import TubeControl, TubeModel, TubeState

__all__ = ["ImplicitEulerSolver", "ITERATIONS", "TOLERANCE", "AL_ITERATIONS", "AL_TOLERANCE"]

#: Newton iterations per substep at most, and the stopping tolerance (a fraction of the shortest
#: segment), of a model without assistant lines: 2 keeps a stiff rod in large motion from gaining
#: energy (measured: 1 iteration gains up to 2% a step at 1e9 Pa, 1/60 s).
ITERATIONS, TOLERANCE = 2, 1e-6
#: The same where tubes carry assistant lines, whose springs the iterations converge on slowly (a
#: linear rate that falls as the tube is refined: a 20 cm tube pushed in its middle came out 1.9%
#: short of the converged answer at frame 4 with 1,001 points and two iterations, 67% short with
#: 10,001; iterating to 1e-3 of the shortest segment, 64 at most, gives the converged answer to
#: 1e-4 of the displacement, at about 5x the cost of two iterations with 1,001 points).
AL_ITERATIONS, AL_TOLERANCE = 64, 1e-3


class ImplicitEulerSolver:
    """Linearised backward Euler, one banded solve per tube per substep.

    Args:
        model: the discretised scene; its assistant lines are integrated with the centerline
            (their points are unknowns of the same solve).
        iterations: Newton iterations per substep at most; 1 is the linearised backward Euler
            step (with a line search). Default :data:`ITERATIONS`, or :data:`AL_ITERATIONS`
            where tubes carry assistant lines.
        tolerance: stop iterating once an iteration moves no node by more than this fraction of
            the shortest segment. Default :data:`TOLERANCE`, or :data:`AL_TOLERANCE` with
            assistant lines.
    """

    name = "implicitEuler"

    def __init__(self, model: TubeModel, iterations: int | None = None, tolerance: float | None = None):
        self.model = model
        has_lines = model.features.assistant_line and model.al_lines > 0
        self.iterations = int(iterations if iterations is not None else (AL_ITERATIONS if has_lines else ITERATIONS))
        self.tolerance = float(tolerance if tolerance is not None else (AL_TOLERANCE if has_lines else TOLERANCE))
        seg = model.host.seg_rest_length
        self._tol = self.tolerance * float(seg[seg > 0].min()) if (seg > 0).any() else 0.0
        self.device = wp.get_device(model.device)
        lines = model.al_lines if model.features.assistant_line else 0
        self.kernel = make_implicit_kernel(model.features, lines)
        W, N = model.world_count, model.node_count
        U, B = N * (1 + lines), 2 * (1 + lines)  # unknowns a world, block bandwidth
        s = ImplicitScratch()
        s.node_kappa_target = wp.zeros((W, N), dtype=wp.vec3, device=self.device)
        s.node_f_frame = wp.zeros((W, N), dtype=wp.vec3, device=self.device)
        for name in ("x0", "v0", "v_it", "r"):
            setattr(s, name, wp.zeros((W, U), dtype=wp.vec3d, device=self.device))
        for name in ("mat_d", "mat_dinv"):
            setattr(s, name, wp.zeros((W, U), dtype=wp.mat33d, device=self.device))
        s.mat_l = wp.zeros((W, U, B), dtype=wp.mat33d, device=self.device)
        self._scratch = s
        self._model_arrays = pack(ModelArrays, model)
        self._commands = {}

    def step(self, state_in: TubeState, state_out: TubeState, control: TubeControl, dt: float):
        """Advance one substep of ``dt`` [s]; pins reach ``control.pin_q_end``."""
        self.integrate(state_in, state_out, control, dt, 1)

    def integrate(self, state_in: TubeState, state_out: TubeState, control: TubeControl, dt: float, substeps: int):
        """Advance ``substeps`` substeps of ``dt`` [s] from ``state_in`` into ``state_out``.

        ``state_in`` is left unchanged; pins move linearly from ``control.pin_q_start`` to
        ``control.pin_q_end`` over the interval.
        """
        # A recorded launch replays without re-packing its arguments (~15 us a launch on the CPU).
        key = (id(state_in), id(state_out), id(control))
        cached = self._commands.get(key)
        if cached is not None:
            cmd = cached[-1]
            cmd.set_param_at_index(0, int(substeps))
            cmd.set_param_at_index(1, float(dt))
            cmd.set_param_at_index(2, self.iterations)
            cmd.set_param_at_index(3, self._tol)
            cmd.launch()
            return
        m = self.model
        cmd = wp.launch(
            self.kernel, (m.world_count, m.tube_count), device=self.device,
            inputs=[int(substeps), float(dt), self.iterations, self._tol, self._model_arrays, pack(StateArrays, state_in), pack(ControlArrays, control),
                    self._scratch],
            outputs=[pack(StateArrays, state_out)],
            record_cmd=True,
        )  # fmt: skip
        cmd.launch()
        if len(self._commands) > 16:
            self._commands.clear()
        # Hold the states and control: the recorded launch points at their arrays, and while they
        # are held no new object can reuse their ids.
        self._commands[key] = (state_in, state_out, control, cmd)
