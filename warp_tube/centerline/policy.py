"""Which integrator and substep a run uses: the scene's choice, or ``auto``'s.

``auto`` (the default) picks semi-implicit Euler at :data:`SAFETY` x its stability bound unless
implicit Euler needs fewer substeps by more than their cost ratio (:func:`implicit_cost_ratio`:
:data:`IMPLICIT_COST_RATIO` per node, times :data:`IMPLICIT_AL_COST` per assistant line on a tube,
which implicit Euler solves with the centerline). The reason for the choice is returned with it and
printed in the run summary.
"""

from __future__ import annotations

import logging
import math
from typing import NamedTuple

import numpy as np

from ..scene.spec import SceneError, SimulationSettings

__all__ = ["IntegratorChoice", "choose_integrator", "decide_integrator", "decide_integrators", "explain_integrator", "is_forced", "implicit_cost_ratio",
           "implicit_substeps", "substeps_for", "SAFETY", "IMPLICIT_DT", "IMPLICIT_COST_RATIO", "IMPLICIT_AL_COST",
           "MAX_SUBSTEPS", "RUN_WARNING"]

log = logging.getLogger(__name__)

#: semi-implicit Euler runs at this fraction of its stability bound when it picks the substep.
SAFETY = 0.5
#: implicit Euler's default substep [s] (its numerical damping: 1.5% amplitude per period of a
#: 1 Hz mode at this step).
IMPLICIT_DT = 1.0 / 240.0
#: cost of an implicit substep over a semi-implicit one, per node (benchmarks/bench_integrators.py).
IMPLICIT_COST_RATIO = 16.0
#: with assistant lines (solved with the centerline) the implicit substep costs this much more again
#: per line on a tube, relative to a semi-implicit substep with the same lines (measured on the CPU,
#: 41 points, one line: ~5.0 us against ~0.11 us per node, i.e. ~3 x IMPLICIT_COST_RATIO).
IMPLICIT_AL_COST = 3.0
#: substeps a frame the kernels can count (a 32-bit loop counter); far past any run that ends
#: (2^31 substeps of the default scene take about a day on a CPU core).
MAX_SUBSTEPS = 2**31 - 1
#: ``extra`` of the log records of run warnings (:mod:`warp_tube.sim.simulation` explains them).
RUN_WARNING = {"run_warning": True}


class IntegratorChoice(NamedTuple):
    """An integrator (``"semiImplicitEuler"`` or ``"implicitEuler"``), why, and its substep [s]."""

    integrator: str
    reason: str
    dt: float


def implicit_cost_ratio(model) -> float:
    """Cost of an implicit substep over a semi-implicit one for ``model`` (a
    :class:`~warp_tube.model.tube.TubeModel`; see the constants)."""
    lines = model.al_lines if model.features.assistant_line else 0
    return IMPLICIT_COST_RATIO * IMPLICIT_AL_COST**lines


def substeps_for(frame_dt: float, dt: float, settings: SimulationSettings, where: str = "") -> int:
    """Substeps a frame of ``frame_dt`` [s] takes at a substep of at most ``dt`` [s]; more than
    :data:`MAX_SUBSTEPS` is refused (a timeStep or stability bound so small that the kernels'
    count would wrap, and nothing move). ``where``: the scene's file, which the message names first."""
    ratio = frame_dt / dt - 1e-9  # (inf where dt is too small for the ratio to be a float)
    if ratio > MAX_SUBSTEPS:
        given = f"warptube:timeStep {settings.time_step:.3g} s" if settings.time_step is not None else "the stability bound"
        count = f"{math.ceil(ratio):,}" if ratio < 1e15 else f"{ratio:.3g}" if math.isfinite(ratio) else "more than 1e308"
        raise SceneError(f"{where + ': ' if where else ''}{given} makes {count} substeps a frame of {frame_dt:.3g} s: expected at most {MAX_SUBSTEPS:,} "
                         f"(a substep of at least {frame_dt / MAX_SUBSTEPS:.3g} s)")  # fmt: skip
    return max(1, math.ceil(ratio))


def implicit_substeps(frame_dt: float, time_step: float | None = None) -> int:
    """Implicit Euler's substeps per frame of ``frame_dt`` [s] (substep ``time_step`` [s] or
    :data:`IMPLICIT_DT`, at most a frame)."""
    return max(1, math.ceil(frame_dt / min(time_step or IMPLICIT_DT, frame_dt) - 1e-9))


def decide_integrator(settings: SimulationSettings, critical_dt: float, frame_dt: float,
                      implicit_cost: float = IMPLICIT_COST_RATIO) -> tuple[str, float]:  # fmt: skip
    """:func:`choose_integrator`'s integrator and substep [s] alone (no reason, no warning): the
    policy itself, for callers that choose for many scenes at once."""
    s, hc = settings, critical_dt
    if s.integrator == "implicitEuler":
        return "implicitEuler", min(s.time_step or IMPLICIT_DT, frame_dt)
    if s.integrator == "semiImplicitEuler":
        if s.time_step is not None:
            return "semiImplicitEuler", min(s.time_step, frame_dt)
        return "semiImplicitEuler", (SAFETY * hc if math.isfinite(hc) else frame_dt)
    # auto: the cheaper of the two, by the cost per substep and node measured for each.
    if not math.isfinite(hc):
        return "semiImplicitEuler", frame_dt
    if s.time_step is not None and s.time_step <= hc:
        return "semiImplicitEuler", s.time_step
    impl_dt = min(s.time_step or IMPLICIT_DT, frame_dt)
    if math.ceil(frame_dt / impl_dt - 1e-9) * implicit_cost < math.ceil(frame_dt / (SAFETY * hc) - 1e-9):
        return "implicitEuler", impl_dt
    return "semiImplicitEuler", SAFETY * hc


def decide_integrators(settings: SimulationSettings, critical_dts: np.ndarray, frame_dt: float,
                       implicit_cost: float = IMPLICIT_COST_RATIO) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:  # fmt: skip
    """:func:`decide_integrator` and :func:`substeps_for` of scenes that share ``settings`` and
    ``frame_dt`` [s], one per stability bound of ``critical_dts`` [s] (shape (n,)), at once: per
    scene whether implicit Euler is chosen (bool), its substeps a frame (int64) and the substep
    [s] (``frame_dt / substeps``), the same numbers as the functions give scene by scene (the same
    float64 operations). None where one of them would raise (a substep the kernels cannot count,
    or a bound so small that its ratio to the frame is no number): call them one by one."""
    s, hc = settings, np.asarray(critical_dts, dtype=np.float64)
    finite = np.isfinite(hc)
    with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
        if s.integrator == "implicitEuler":
            implicit, dt = np.ones(len(hc), dtype=bool), np.full(len(hc), min(s.time_step or IMPLICIT_DT, frame_dt))
        elif s.integrator == "semiImplicitEuler":
            implicit = np.zeros(len(hc), dtype=bool)
            dt = np.full(len(hc), min(s.time_step, frame_dt)) if s.time_step is not None else np.where(finite, SAFETY * hc, frame_dt)
        else:  # auto
            impl_dt = min(s.time_step or IMPLICIT_DT, frame_dt)
            semi_steps = np.ceil(frame_dt / (SAFETY * hc) - 1e-9)
            within = finite & (s.time_step <= hc) if s.time_step is not None else np.zeros(len(hc), dtype=bool)
            if not np.isfinite(semi_steps[finite & ~within]).all():
                return None
            implicit = finite & ~within & (math.ceil(frame_dt / impl_dt - 1e-9) * implicit_cost < semi_steps)
            dt = np.where(finite, np.where(within, s.time_step, np.where(implicit, impl_dt, SAFETY * hc)), frame_dt)
        ratio = frame_dt / dt - 1e-9
    if not (ratio <= MAX_SUBSTEPS).all():
        return None
    substeps = np.maximum(1.0, np.ceil(ratio)).astype(np.int64)
    return implicit, substeps, frame_dt / substeps


def is_forced(settings: SimulationSettings, critical_dt: float, frame_dt: float) -> bool:
    """Whether the scene forces semi-implicit Euler at a substep beyond its stability bound
    ``critical_dt`` [s] (:func:`choose_integrator` warns: expect a blow-up)."""
    s = settings
    return s.integrator == "semiImplicitEuler" and s.time_step is not None and min(s.time_step, frame_dt) > critical_dt


def explain_integrator(settings: SimulationSettings, critical_dt: float, frame_dt: float,
                       implicit_cost: float = IMPLICIT_COST_RATIO) -> str:  # fmt: skip
    """Why :func:`decide_integrator` chose what it chose, in words (the run summary's line)."""
    s, hc = settings, critical_dt
    integrator, dt = decide_integrator(settings, critical_dt, frame_dt, implicit_cost)
    # a timeStep longer than a frame runs as one substep a frame: said, with the value asked for
    capped = f" (timeStep {s.time_step:.3g} s is longer than a frame: one substep a frame)" if s.time_step and s.time_step > frame_dt else ""
    if s.integrator == "implicitEuler":
        return f"from the scene, substep {dt:.3g} s{capped}"
    if s.integrator == "semiImplicitEuler":
        if s.time_step is not None:
            if is_forced(settings, critical_dt, frame_dt):
                return f"forced; timeStep {dt:.3g} s exceeds the stability bound {hc:.3g} s{capped}"
            return f"from the scene, timeStep {dt:.3g} s (bound {hc:.3g} s){capped}"
        if not math.isfinite(hc):
            return "from the scene; nothing stiff: one substep per frame"
        return f"from the scene, substep {SAFETY:g} x the stability bound {hc:.3g} s"
    if not math.isfinite(hc):
        return "auto: nothing stiff to bound the step, one substep per frame"
    if s.time_step is not None and s.time_step <= hc:
        return f"auto: timeStep {s.time_step:.3g} s is within the stability bound {hc:.3g} s"
    impl_dt = min(s.time_step or IMPLICIT_DT, frame_dt)
    semi_steps = math.ceil(frame_dt / (SAFETY * hc) - 1e-9)
    impl_steps = math.ceil(frame_dt / impl_dt - 1e-9)
    # a timeStep beyond the bound is taken by implicit Euler only (force it with semiImplicitEuler)
    over = f"timeStep {s.time_step:.3g} s exceeds the stability bound; " if s.time_step is not None else ""
    if integrator == "implicitEuler":
        impl = f"{impl_steps} implicit one" + ("s" if impl_steps != 1 else "")
        return (f"auto: {over}stiff ({semi_steps} stable semi-implicit substeps a frame against {impl} at "
                f"~{implicit_cost:g}x the cost each){capped}")  # fmt: skip
    why = f"cheaper than implicit ({impl_steps} substeps at ~{implicit_cost:g}x the cost)"
    if semi_steps == 1:  # (a frame is shorter than the step the bound allows)
        return f"auto: {over}one substep a frame, within {SAFETY:g} x the stability bound {hc:.3g} s; {why}"
    return f"auto: {over}{semi_steps} substeps a frame at {SAFETY:g} x the stability bound {hc:.3g} s; {why}"


def choose_integrator(settings: SimulationSettings, critical_dt: float, frame_dt: float,
                      implicit_cost: float = IMPLICIT_COST_RATIO, where: str = "") -> IntegratorChoice:  # fmt: skip
    """The integrator and substep for a scene, and why (a warning where a forced substep exceeds
    the stability bound).

    Args:
        settings: the scene's simulation settings (integrator, forced substep).
        critical_dt: semi-implicit Euler's stability bound [s] (``inf`` when nothing is stiff).
        frame_dt: the output frame's duration [s].
        implicit_cost: an implicit substep's cost over a semi-implicit one
            (:func:`implicit_cost_ratio` of the model).
        where: the scene's file, named in the warning.
    """
    integrator, dt = decide_integrator(settings, critical_dt, frame_dt, implicit_cost)
    if is_forced(settings, critical_dt, frame_dt):
        log.warning("%swarptube:timeStep %.3g s exceeds the semi-implicit Euler stability bound %.3g s: expect a blow-up",
                    f"{where}: " if where else "", dt, critical_dt, extra=RUN_WARNING)  # fmt: skip
    return IntegratorChoice(integrator, explain_integrator(settings, critical_dt, frame_dt, implicit_cost), dt)
