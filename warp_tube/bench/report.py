"""``report.md`` of ``warp-tube bench``: tables of the aggregated rows of ``results.json``."""

from __future__ import annotations

from .problems import ANSWER_TOLERANCE, cantilever

HEADLINE = cantilever(2.0).name


def label(row: dict) -> str:
    """A configuration in words, e.g. "warp_tube Simulation" or "newton behind 10x20"."""
    c = row["config"]
    if row["code"] == "warp_tube":
        return "warp_tube " + ("solver API" if c.get("api") == "solver" else "Simulation")
    s = f"{row['code']} {c.get('clamp', '')} clamp".replace("behind clamp", "clamp behind (tuned)")
    if row["code"] == "newton":
        s += f", {c['substeps']} substeps x {c['iterations']} it."
    return s


def _fmt(x, spec="{:.3g}"):
    return "-" if x is None else spec.format(x)


def _ratio(x):
    return "-" if x is None else f"{x:.2f}x" if x < 1 else f"{x:.1f}x"


def _pct(x):
    return "-" if x is None else f"{100 * x:.3f}%"


def best_answers(rows: list, problem: str = HEADLINE) -> dict:
    """The fastest answer per configuration family (``label``) for ``problem``: label -> row."""
    best = {}
    for r in rows:
        if r["kind"] != "static" or r["problem"] != problem or r.get("answer_time") is None:
            continue
        k = label(r)
        if k not in best or r["answer_time"] < best[k]["answer_time"]:
            best[k] = r
    return best


def answer_ratios(rows: list, problem: str = HEADLINE) -> dict:
    """Each family's fastest answer time (peers' and warp_tube's solver API) over warp_tube's
    through ``Simulation``: label -> ratio."""
    best = best_answers(rows, problem)
    base = best.get("warp_tube Simulation")
    if base is None:
        return {}
    return {k: r["answer_time"] / base["answer_time"] for k, r in best.items() if k != "warp_tube Simulation"}


def throughput_ratios(rows: list) -> list[str]:
    """Markdown lines: warp_tube's simulated tube-seconds per wall second over each peer's, per batch."""
    tp = {}
    for r in rows:
        if r["kind"] == "throughput" and "failed" not in r:
            tp.setdefault(label(r), {})[r["config"]["batch"]] = r["rod_seconds_per_s"]
    ours = {k: v for k, v in tp.items() if k.startswith("warp_tube")}
    peers = {k: v for k, v in tp.items() if not k.startswith("warp_tube")}
    if not ours or not peers:
        return []
    out = ["", "Throughput ratio at equal error (each code's 0.2%-of-L configuration at 20 segments): "
           "warp_tube's simulated tube-seconds per second over the peer's, same batch size.", "",
           "| warp_tube | peer | " + " | ".join(str(b) for b in sorted({b for v in tp.values() for b in v})) + " |"]  # fmt: skip
    batches = sorted({b for v in tp.values() for b in v})
    out.append("|---|---|" + "---|" * len(batches))
    for a, va in sorted(ours.items()):
        for b, vb in sorted(peers.items()):
            cells = [f"{va[n] / vb[n]:.0f}x" if n in va and n in vb else "-" for n in batches]
            out.append(f"| {a} | {b} | " + " | ".join(cells) + " |")
    return out


def report_markdown(results: dict) -> str:
    rows = results["rows"]
    compile_by_code = {}
    for run in results["runs"]:
        compile_by_code.setdefault(run["code"], []).append(run["compile_time"])
    versions = {}
    devices = {}
    for run in results["runs"]:
        versions.update(run["versions"])
        devices[run["code"]] = run["device"]
    out = [
        "# warp-tube bench",
        "",
        f"- date: {results['date']}; command: `{results['command']}`",
        f"- devices: " + ", ".join(f"{c} on {d}" for c, d in devices.items()) + (f" ({results['gpu']})" if results.get("gpu") else ""),
        f"- host: {results['host']['platform']}, {results['host']['cpu_count']} CPUs",
        "- versions: " + ", ".join(f"{k} {v}" for k, v in sorted(versions.items())),
        f"- repetitions: {results['repeat']}" + (
            f" (interleaved, one process per code each; medians; `reps` < {results['repeat']}: slow configurations run once)"
            if results["repeat"] > 1 else " (one process per code)"),
    ]
    for code, why in results.get("skipped", {}).items():
        out.append(f"- skipped {code}: {why}")
    out += ["", f"## Time to the answer: {HEADLINE} (tip within {100 * ANSWER_TOLERANCE:g}% of L for good)", "",
            "| code and configuration | segments | tip error | time to answer [s] | over warp_tube Simulation | setup [s] | wall per simulated s |",
            "|---|---|---|---|---|---|---|"]  # fmt: skip
    best = best_answers(rows)
    ratios = answer_ratios(rows)
    for k, r in sorted(best.items(), key=lambda kv: kv[1]["answer_time"]):
        ratio = "1" if k == "warp_tube Simulation" else _ratio(ratios.get(k))
        out.append(f"| {k} | {r['config']['segments']} | {_pct(r['error'])} | {_fmt(r['answer_time'])} | {ratio} | "
                   f"{_fmt(r['setup_time'])} | {_fmt(r['wall_per_simulated_s'])} |")  # fmt: skip
    missing = sorted({label(r) for r in rows if r["kind"] == "static" and r["problem"] == HEADLINE} - set(best))
    for k in missing:
        out.append(f"| {k} | - | no configuration within {100 * ANSWER_TOLERANCE:g}% | - | - | - | - |")
    out += ["", "## Static problems, every configuration", "",
            "| problem | code and configuration | segments | tip error / L | time to answer [s] | reps | spread | set-up |",
            "|---|---|---|---|---|---|---|---|"]  # fmt: skip
    for r in sorted((r for r in rows if r["kind"] == "static"), key=lambda r: (r["problem"], label(r), r["config"]["segments"])):
        if "failed" in r:
            out.append(f"| {r['problem']} | {label(r)} | {r['config']['segments']} | failed: {r['failed']} | | | | |")
            continue
        out.append(f"| {r['problem']} | {label(r)} | {r['config']['segments']} | {_pct(r['error'])} | {_fmt(r['answer_time'])} | "
                   f"{r['reps']} | {_pct(r.get('spread'))} | {r.get('setup', '')} |")  # fmt: skip
    out += ["", "## First natural frequency (undamped, released in the first mode), against Euler-Bernoulli", "",
            "| code and configuration | segments | frequency error |", "|---|---|---|"]  # fmt: skip
    for r in (r for r in rows if r["kind"] == "frequency"):
        out.append(f"| {label(r)} | {r['config']['segments']} | " + (f"failed: {r['failed']}" if "failed" in r else f"{100 * r['frequency_error']:+.2f}%") + " |")
    throughput = sorted((r for r in rows if r["kind"] == "throughput"), key=lambda r: (label(r), r["config"]["batch"]))
    if throughput:  # (none in an accuracy run)
        out += ["", "## Throughput: 20-segment tubes (rod-steps per second; tube-seconds simulated per wall second)", "",
                "| code and configuration | tubes | rod-steps/s | simulated tube-s per s | time step [s] | reps | spread |",
                "|---|---|---|---|---|---|---|"]  # fmt: skip
    for r in throughput:
        if "failed" in r:
            out.append(f"| {label(r)} | {r['config']['batch']} | failed: {r['failed']} | | | | |")
            continue
        out.append(f"| {label(r)} | {r['config']['batch']} | {_fmt(r['rod_steps_per_s'])} | {_fmt(r['rod_seconds_per_s'])} | "
                   f"{_fmt(r['dt'])} | {r['reps']} | {_pct(r.get('spread'))} |")  # fmt: skip
    out += throughput_ratios(rows)
    out += ["", "## Compilation / JIT (warm-up run of each process, apart from every figure above)", "", "| code | median [s] | each repetition [s] |", "|---|---|---|"]
    import numpy as np

    for code, ts in compile_by_code.items():
        out.append(f"| {code} | {np.median(ts):.2f} | {', '.join(f'{t:.2f}' for t in ts)} |")
    return "\n".join(out) + "\n"
