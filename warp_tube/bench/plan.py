"""Which configurations of each code ``warp-tube bench`` runs (the fixed, documented problem set).

Static problems (:func:`static_plan`): each entry is ``(problem, config, once)``; ``once`` entries
(the slow ones) run in the first repetition only. Configurations:

- warp_tube: ``segments`` free segments, ``api`` "simulation" (``warp_tube.Simulation``, the
  integrator ``auto`` picks, frames of 1/24 s) or "solver" (the centerline solver's ``integrate``).
- pyelastica: ``segments`` elements over the free length, ``clamp`` "documented" or "behind"
  (tuned by hand; see :mod:`.peers.pyelastica_runner`), time step 0.5 dl / sqrt(E / rho).
- newton: ``segments``, ``clamp`` as above (see :mod:`.peers.newton_runner`), ``substeps`` per
  1/60 s frame and VBD ``iterations``; 10 x 20 is the cantilever example's setting.
"""

from __future__ import annotations

from .problems import BATCH_SIZES, CANTILEVER_LOADS, CURVED, QUICK_BATCH_SIZES, cantilever  # noqa: F401 (cantilever: used by the worker)

CODES = ("warp_tube", "pyelastica", "newton")


def _wt(n, api="simulation"):
    return {"segments": n, "api": api}


def _pe(n, clamp="behind"):
    return {"segments": n, "clamp": clamp}


def _nt(n, substeps, iterations, clamp="behind"):
    return {"segments": n, "clamp": clamp, "substeps": substeps, "iterations": iterations}


def static_plan(code: str, quick: bool) -> list:
    """[(problem, config, once)] of the accuracy suite's static problems for ``code``."""
    loads = CANTILEVER_LOADS
    out = []
    if code == "warp_tube":
        ns = (10, 20) if quick else (5, 10, 20, 40, 80)
        out += [(cantilever(p), _wt(n), n >= 80) for p in loads for n in ns]
        out += [(cantilever(2.0), _wt(n, "solver"), False) for n in ((20,) if quick else (10, 20))]
        out += [(CURVED, _wt(n), False) for n in ((20,) if quick else (10, 20, 40))]
    elif code == "pyelastica":
        if quick:
            return [(cantilever(2.0), _pe(20), False)]
        out += [(cantilever(2.0), _pe(n, "documented"), n >= 160) for n in (20, 40, 80, 160, 320)]
        out += [(cantilever(2.0), _pe(n), n >= 80) for n in (10, 20, 40, 80)]
        out += [(cantilever(p), _pe(20), False) for p in loads if p != 2.0]
        out += [(CURVED, _pe(n), False) for n in (20, 40)]
    elif code == "newton":
        if quick:
            return [(cantilever(2.0), _nt(10, 2, 10), False)]
        out += [(cantilever(2.0), _nt(n, 2, 10), False) for n in (5, 10)]
        out += [(cantilever(2.0), _nt(20, 10, 20), True), (cantilever(2.0), _nt(10, 2, 10, "documented"), True)]
        out += [(cantilever(p), _nt(10, 2, 10), True) for p in loads if p != 2.0]
        out += [(CURVED, _nt(10, 10, 20), True)]
    return out


def frequency_plan(code: str, quick: bool) -> list:
    """Configurations of the first-frequency measurement for ``code``."""
    if code == "warp_tube":
        return [_wt(n) for n in ((20,) if quick else (10, 20, 40))]
    if code == "pyelastica":
        return [_pe(20)] if quick else [_pe(20), _pe(20, "documented")]
    return [_nt(10, 2, 10)]


def speed_plan(code: str, quick: bool) -> tuple:
    """(configs, batch sizes) of the throughput sweep: 20 free segments, the configuration of each
    code that reaches 0.2% of L at 20 segments (Newton: 10 substeps x 20 iterations)."""
    sizes = QUICK_BATCH_SIZES if quick else BATCH_SIZES
    if code == "warp_tube":
        return [_wt(20, "solver"), _wt(20)], sizes
    if code == "pyelastica":
        # one simulator holding every rod: setting up 65,536 of them took 386 s here, so 4,096 is its largest
        return [_pe(20)], tuple(b for b in sizes if b <= 4096)
    return [_nt(20, 10, 20)], sizes
