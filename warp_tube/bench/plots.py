"""Plots of ``warp-tube bench`` (matplotlib, ``pip install "warp-tube[plots]"``).

- ``error_vs_time.png``: tip error against wall time to the answer, log-log, every code and
  resolution of the headline cantilever (configurations that never get within the tolerance are
  drawn hollow at their whole run's wall time);
- ``throughput.png``: simulated tube-seconds per wall second against the number of tubes;
- ``convergence.png``: tip error against segment count, with slopes 1 and 2 for reference.
"""

from __future__ import annotations

import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.ticker import FuncFormatter, NullFormatter  # noqa: E402

from .problems import ANSWER_TOLERANCE  # noqa: E402
from .report import HEADLINE, label  # noqa: E402

COLORS = {"warp_tube": "tab:green", "pyelastica": "tab:blue", "newton": "tab:orange"}
#: a tip this far from the reference [fraction of L] has blown up: left out of the plots, named below them.
BLOWN_UP = 0.5
MARKERS = ["o", "s", "^", "D", "v", "P"]


def _families(rows, kind, problem=None):
    fam = {}
    for r in rows:
        if r["kind"] == kind and (problem is None or r["problem"] == problem) and "failed" not in r:
            if kind == "static" and not r["error"] <= BLOWN_UP:
                continue
            fam.setdefault(label(r), []).append(r)
    return fam


def _blown_note(ax, rows):
    """Name the static runs of the headline problem that blew up (left out of the plot)."""
    bad = [f"{label(r)}, {r['config']['segments']} segments" for r in rows
           if r["kind"] == "static" and r["problem"] == HEADLINE and "failed" not in r and not r["error"] <= BLOWN_UP]  # fmt: skip
    if bad:
        ax.figure.text(0.01, 0.005, "blew up (not drawn): " + "; ".join(bad), fontsize=6, color="gray")


def _short_log_ticks(ax):
    """Plain numbers (0.012, not 1.2 x 10^-2) on log axes. An axis spanning under two decades (one
    or no decade to label) gets labels on minor ticks too: 2 and 5 of each decade where it spans
    more than one, else at most about five of them, so that the labels never run into each other."""
    plain = FuncFormatter(lambda v, _: f"{v:g}")
    for axis, (lo, hi) in ((ax.xaxis, ax.get_xlim()), (ax.yaxis, ax.get_ylim())):
        if axis.get_scale() != "log" or not 0 < lo < hi:
            continue
        axis.set_major_formatter(plain)
        decades = np.log10(hi / lo)
        if decades >= 2.0:
            axis.set_minor_formatter(NullFormatter())
            continue
        minors = [t for t in axis.get_minorticklocs() if lo <= t <= hi]
        if decades >= 1.0:
            shown = {t for t in minors if round(t / 10 ** np.floor(np.log10(t) + 1e-9), 6) in (2.0, 5.0)}
        else:
            shown = set(minors[:: max(1, -(-len(minors) // 5))])
        axis.set_minor_formatter(FuncFormatter(lambda v, _, shown=shown: f"{v:g}" if v in shown else ""))


def _title(results, what):
    dev = results.get("gpu") or results["requested_device"]
    return f"{what}\n{dev}, {results['date'][:10]}"


#: every PNG :func:`write_plots` may write
PLOTS = ("error_vs_time.png", "convergence.png", "throughput.png")


def write_plots(results: dict, out_dir: str) -> list[str]:
    """Write the PNGs the results have data for into ``out_dir``; returns their paths."""
    rows = results["rows"]
    paths = []
    if _families(rows, "static", HEADLINE):
        paths += _static_plots(results, rows, out_dir)
    fam = _families(rows, "throughput")
    if fam:
        paths.append(_throughput_plot(results, fam, out_dir))
    return paths


def _static_plots(results, rows, out_dir):
    paths = []
    # error against time to the answer
    fig, ax = plt.subplots(figsize=(7, 5))
    for i, (name, rs) in enumerate(sorted(_families(rows, "static", HEADLINE).items())):
        rs = sorted(rs, key=lambda r: r["config"]["segments"])
        c = COLORS.get(rs[0]["code"], "k")
        m = MARKERS[i % len(MARKERS)]
        t = [r["answer_time"] if r["answer_time"] is not None else r["run_wall"] for r in rs]
        e = [r["error"] for r in rs]
        ax.plot(t, e, "-", color=c, alpha=0.4)
        for r, ti, ei in zip(rs, t, e):
            ax.plot(ti, ei, m, color=c, mfc=c if r["answer_time"] is not None else "none", label=name if r is rs[0] else None)
            ax.annotate(str(r["config"]["segments"]), (ti, ei), textcoords="offset points", xytext=(4, 3), fontsize=7, color=c)
    ax.axhline(ANSWER_TOLERANCE, color="gray", ls=":", lw=1, label=f"answer: within {100 * ANSWER_TOLERANCE:g}% of L")
    _blown_note(ax, rows)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("wall time to the answer [s] (hollow: no answer; whole run)")
    ax.set_ylabel("static tip error / L")
    ax.set_title(_title(results, f"{HEADLINE}: error against time (labels: segments)"), fontsize=9)
    ax.legend(fontsize=7)
    ax.grid(True, which="both", alpha=0.3)
    _short_log_ticks(ax)
    paths.append(_save(fig, out_dir, "error_vs_time.png"))
    # convergence
    fig, ax = plt.subplots(figsize=(7, 5))
    for i, (name, rs) in enumerate(sorted(_families(rows, "static", HEADLINE).items())):
        rs = sorted(rs, key=lambda r: r["config"]["segments"])
        if len(rs) < 2:
            continue
        n = np.array([r["config"]["segments"] for r in rs], dtype=float)
        e = np.array([r["error"] for r in rs])
        order = -np.polyfit(np.log(n), np.log(e), 1)[0]
        ax.plot(n, e, MARKERS[i % len(MARKERS)] + "-", color=COLORS.get(rs[0]["code"], "k"), label=f"{name} (order {order:.2f})")
    n = np.array([5.0, 320.0])
    for p, ls in ((1, "--"), (2, ":")):
        ax.plot(n, 0.05 * (n / n[0]) ** -p, ls, color="gray", lw=1, label=f"slope {p}")
    ax.axhline(ANSWER_TOLERANCE, color="gray", ls="-.", lw=0.8, label=f"{100 * ANSWER_TOLERANCE:g}% of L")
    _blown_note(ax, rows)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("free segments")
    ax.set_ylabel("static tip error / L")
    ax.set_title(_title(results, f"{HEADLINE}: convergence"), fontsize=9)
    ax.legend(fontsize=7, loc="upper right")
    ax.grid(True, which="both", alpha=0.3)
    _short_log_ticks(ax)
    paths.append(_save(fig, out_dir, "convergence.png"))
    return paths


def _throughput_plot(results, fam, out_dir):
    fig, ax = plt.subplots(figsize=(7, 5))
    for i, (name, rs) in enumerate(sorted(fam.items())):
        rs = sorted(rs, key=lambda r: r["config"]["batch"])
        ax.plot([r["config"]["batch"] for r in rs], [r["rod_seconds_per_s"] for r in rs], MARKERS[i % len(MARKERS)] + "-",
                color=COLORS.get(rs[0]["code"], "k"), label=name)  # fmt: skip
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("tubes in the batch (20 segments each)")
    ax.set_ylabel("simulated tube-seconds per wall second")
    ax.set_title(_title(results, "throughput at each code's 0.2%-of-L configuration"), fontsize=9)
    ax.legend(fontsize=7)
    ax.grid(True, which="both", alpha=0.3)
    _short_log_ticks(ax)
    return _save(fig, out_dir, "throughput.png")


def _save(fig, out_dir, name):
    from ..scene.files import write_atomically

    path = os.path.join(out_dir, name)
    fig.tight_layout(rect=(0, 0.02, 1, 1))
    try:  # (whole or not at all, an interrupt included)
        write_atomically(path, lambda tmp: fig.savefig(tmp, dpi=110, format="png"))
    finally:
        plt.close(fig)
    return path
