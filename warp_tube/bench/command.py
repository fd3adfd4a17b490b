"""``warp-tube bench``: every code in a process of its own per repetition, repetitions
interleaved (warp_tube, then each peer, then again), medians; results, report and plots in DIR.

Output: ``DIR/logs/CODE-REP.log`` (each worker's progress: one JSON line per measurement),
``DIR/results.json`` (every figure, each repetition's and the medians, with device,
versions, command and date), ``DIR/report.md`` (tables, :mod:`.report`) and, with matplotlib
installed (``pip install "warp-tube[plots]"``), ``DIR/*.png`` (:mod:`.plots`). An interrupted bench leaves
DIR as it was (:class:`_Made`).
"""

from __future__ import annotations

import datetime
import json
import os
import platform
import subprocess
import sys
import tempfile
import time

import numpy as np

from ..scene.spec import SceneError
from . import plan
from .worker import RUNNERS, runner

#: figures whose median over the repetitions is reported (the others come from the first).
TIMED = ("answer_time", "wall_per_simulated_s", "setup_time", "run_wall", "rod_steps_per_s", "rod_seconds_per_s", "error")


def parse_peers(text: str | None) -> list[str]:
    """The peers named by ``--peers`` ("pyelastica,newton", "none"; default: both)."""
    if text is None:
        return ["pyelastica", "newton"]
    names = [t.strip() for t in text.split(",") if t.strip() and t.strip() != "none"]
    for n in names:
        if n not in ("pyelastica", "newton"):
            raise SceneError(f"--peers {text}: unknown peer {n!r}: expected pyelastica and/or newton, or none")
    return names


def _key(rec: dict) -> str:
    return json.dumps([rec["kind"], rec["problem"], rec["config"]], sort_keys=True)


def aggregate(runs: list[dict]) -> list[dict]:
    """One row per (code, kind, problem, config): the median of each timed figure over the
    repetitions that measured it, ``reps`` their count and ``spread`` (max / min - 1) of the
    answer time or throughput."""
    groups: dict[tuple, list] = {}
    for run in runs:
        for rec in run["records"]:
            groups.setdefault((run["code"], _key(rec)), []).append(rec)
    rows = []
    for (code, _), recs in groups.items():
        row = dict(recs[0], code=code, reps=len(recs))
        for k in TIMED:
            vals = [r[k] for r in recs if r.get(k) is not None]
            if vals:
                row[k] = float(np.median(vals))
            elif k in row:
                row[k] = None
        if row["kind"] == "static" and any(r.get("answer_time") is None for r in recs):
            row["answer_time"] = None  # no answer in some repetition: none reported
        main = "answer_time" if row["kind"] == "static" else "rod_seconds_per_s"
        vals = [r[main] for r in recs if r.get(main)]
        if len(vals) > 1:
            row["spread"] = float(max(vals) / min(vals) - 1.0)
        rows.append(row)
    return rows


class _Made:
    """What a bench puts in its folder, so that an interrupted one leaves the folder as it was: the
    folders and files it made are removed, and the files it wrote over (an earlier bench's, in the
    same folder) are put back. Such a file waits beside itself under a hidden name until the bench
    ends."""

    def __init__(self):
        self._made: list[str] = []  # folders and files made by this bench, in the order made
        self._moved: list[tuple[str, str]] = []  # (a file there before it, where it waits)

    def folder(self, path: str) -> None:
        """Note each missing folder of ``path`` (before it is made)."""
        path, missing = os.path.abspath(path), []
        while path and not os.path.exists(path):
            missing.append(path)
            parent = os.path.dirname(path)
            if parent == path:
                break
            path = parent
        self._made += reversed(missing)

    def file(self, path: str) -> None:
        """Before ``path`` may be written: note it, and move a file there aside."""
        path = os.path.abspath(path)
        if path in self._made or any(path == p for p, _ in self._moved):
            return
        if not os.path.lexists(path):
            self._made.append(path)
            return
        aside = os.path.join(os.path.dirname(path), f".{os.path.basename(path)}.before-bench-{os.getpid()}")
        os.replace(path, aside)
        self._moved.append((path, aside))

    def done(self) -> None:
        """The bench is complete: the files it wrote over are dropped, those it did not write put back."""
        for path, aside in self._moved:
            if os.path.lexists(path):
                os.remove(aside)
            else:
                os.replace(aside, path)

    def undo(self) -> list[str]:
        """Remove what this bench made (a folder only if empty: a file put in it since stays, and the
        folder with it) and put back what it moved aside; returns the paths it could not."""
        failed = []
        for path in reversed(self._made):
            try:
                if os.path.isdir(path) and not os.path.islink(path):
                    if os.listdir(path):
                        continue  # (something of someone else's)
                    os.rmdir(path)
                else:
                    os.remove(path)
            except FileNotFoundError:
                pass
            except OSError:
                failed.append(path)
        for path, aside in self._moved:
            try:
                os.replace(aside, path)
            except OSError:
                failed.append(aside)
        return failed


def _output_dir(out_dir: str, made: _Made | None = None) -> None:
    """Create ``out_dir`` or check it is a writable folder (SceneError otherwise)."""
    if os.path.exists(out_dir) and not os.path.isdir(out_dir):
        raise SceneError(f"{out_dir}: exists and is not a folder: -o takes a folder for results.json, report.md and plots")
    if made is not None:
        made.folder(out_dir)
    try:
        os.makedirs(out_dir, exist_ok=True)
    except OSError as e:
        raise SceneError(f"{out_dir}: cannot create the output folder ({e.strerror})") from None
    if not os.access(out_dir, os.W_OK):
        raise SceneError(f"{out_dir}: not writable")


def run_bench(suite: str, peers: list[str], device: str, out_dir: str, repeat: int, quick: bool, log=print, command: str = "warp-tube bench") -> dict:
    """Run the benchmark and write ``results.json``, ``report.md`` and the plots into ``out_dir``;
    ``command`` is recorded with the results.

    Raises:
        KeyboardInterrupt: after leaving ``out_dir`` as it was: the files and folders this bench
            made are removed, the files it wrote over (an earlier bench's there) put back; the
            exception's ``left`` lists what could not be (normally nothing).
    """
    from ..sim.simulation import resolve_device

    device = resolve_device(device)
    made = _Made()
    try:
        results = _run_bench(suite, peers, device, out_dir, repeat, quick, log, command, made)
    except KeyboardInterrupt as e:
        e.left = made.undo()
        raise
    except BaseException:
        made.done()  # (what it wrote is kept for a look at what failed)
        raise
    made.done()
    return results


def _run_bench(suite, peers, device, out_dir, repeat, quick, log, command, made: _Made) -> dict:
    """:func:`run_bench` on a resolved device, noting in ``made`` what it puts in ``out_dir``."""
    _output_dir(out_dir, made)
    codes, skipped = ["warp_tube"], {}
    for p in peers:
        ok, why = runner(p).available()
        if ok:
            codes.append(p)
        else:
            skipped[p] = why
            log(f"skipped {p}: {why}")
    runs = []
    started = datetime.datetime.now(datetime.timezone.utc)
    with tempfile.TemporaryDirectory() as tmp:
        for rep in range(repeat):
            for code in codes:
                path = os.path.join(tmp, f"{code}-{rep}.json")
                cmd = [sys.executable, "-m", "warp_tube.bench.worker", code, "--suite", suite, "--device", device,
                       "--rep", str(rep), "--out", path] + (["--quick"] if quick else [])  # fmt: skip
                t0 = time.perf_counter()
                log(f"repetition {rep + 1}/{repeat}: {code} ...")
                logpath = os.path.join(out_dir, "logs", f"{code}-{rep}.log")
                made.folder(os.path.dirname(logpath))
                os.makedirs(os.path.dirname(logpath), exist_ok=True)
                made.file(logpath)
                with open(logpath, "w") as logf:
                    proc = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=logf)
                if proc.returncode != 0 or not os.path.exists(path):
                    with open(logpath) as logf:
                        tail = "\n".join(logf.read().strip().splitlines()[-5:])
                    log(f"  {code} failed (exit status {proc.returncode}): {tail}")
                    skipped.setdefault(code, f"its worker failed: {tail}")
                    continue
                with open(path) as f:
                    runs.append(json.load(f))
                log(f"  {code}: {time.perf_counter() - t0:.1f} s")
    results = dict(
        command=command,
        date=started.isoformat(timespec="seconds"), suite=suite, quick=quick, repeat=repeat, requested_device=device,
        host=dict(platform=platform.platform(), processor=platform.processor() or platform.machine(), cpu_count=os.cpu_count()),
        gpu=_gpu_name(device), skipped=skipped, runs=runs, rows=aggregate(runs),
    )  # fmt: skip
    write_outputs(results, out_dir, log, made)
    return results


def _gpu_name(device: str) -> str | None:
    if not device.startswith("cuda"):
        return None
    import warp as wp

    return wp.get_device(device).name


def write_outputs(results: dict, out_dir: str, log=print, made: _Made | None = None) -> None:
    """``results.json``, ``report.md`` and the plots (each written to a temporary name, then
    renamed); ``made`` notes the first two."""
    from .report import report_markdown

    for name, text in (("results.json", json.dumps(results, indent=1, default=float)), ("report.md", report_markdown(results))):
        if made is not None:
            made.file(os.path.join(out_dir, name))
        _write(os.path.join(out_dir, name), text)
    try:
        from .plots import PLOTS, write_plots
    except ImportError as e:
        log(f"plots skipped: matplotlib is not installed ({e}); install it with "
            'pip install "warp-tube[plots]" (from a checkout: pip install -e ".[plots]")')
        return
    if made is not None:
        for name in PLOTS:
            made.file(os.path.join(out_dir, name))
    for path in write_plots(results, out_dir):
        log(path)


def _write(path: str, text: str) -> None:
    """``text`` into ``path``, whole or not at all (an interrupt included: no half-written file)."""
    from ..scene.files import write_atomically

    def put(tmp: str) -> None:
        with open(tmp, "w") as f:
            f.write(text)

    write_atomically(path, put)


def replot(results_path: str, out_dir: str, log=print) -> None:
    """Rewrite the report and plots of an earlier run from its ``results.json``."""
    try:
        with open(results_path) as f:
            results = json.load(f)
    except (OSError, json.JSONDecodeError) as e:
        raise SceneError(f"{results_path}: cannot read benchmark results ({e})") from None
    if "rows" not in results:
        raise SceneError(f"{results_path}: no 'rows': not the results.json of warp-tube bench")
    _output_dir(out_dir)
    write_outputs(results, out_dir, log)


__all__ = ["run_bench", "replot", "parse_peers", "aggregate", "RUNNERS"]
