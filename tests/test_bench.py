"""``warp-tube bench``: the quick accuracy suite's report and figures, and the benchmark's
references and bookkeeping (CPU; peers not needed)."""

import json
import re

import numpy as np
import pytest

from warp_tube.bench.command import aggregate
from warp_tube.bench.problems import CURVED, Trace, cantilever
from warp_tube.bench.references import elastica_tip, planar_rod_tip
from warp_tube.cli import main

from .conftest import ROOT


def readme_figures():
    """(tip errors at PL^2/EI = 1, 2, 5 [fraction of L], first frequency error) from README's table."""
    text = (ROOT / "README.md").read_text()
    row = re.search(r"^\| cantilever tip error, 20 segments.*$", text, re.M).group(0)
    tips = [float(v) / 100 for v in re.findall(r"([\d.]+)%", row)]
    freq = re.search(r"^\| first natural frequency, 20 segments \| ([-+\d.]+)% \|$", text, re.M).group(1)
    return tips, float(freq) / 100


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("bench")
    (out / "logs").mkdir()
    (out / "logs" / "warp_tube-0.log").write_text("an earlier bench's log")
    (out / "mine.txt").write_text("a user's file")
    assert main(["bench", "--suite", "accuracy", "--quick", "--peers", "none", "--device", "cpu", "-o", str(out)]) == 0
    return out, json.loads((out / "results.json").read_text())


def test_a_bench_over_an_earlier_one_replaces_its_files_and_leaves_the_others(quick_run):
    out, _ = quick_run
    assert (out / "mine.txt").read_text() == "a user's file"
    assert "an earlier bench's log" not in (out / "logs" / "warp_tube-0.log").read_text()
    assert not [p for p in out.rglob("*") if p.name.startswith(".") or p.name.endswith(".partial")]


@pytest.fixture
def interrupted_worker(monkeypatch):
    """The bench's worker process stopped by the Ctrl-C that stops the bench: its log holds the
    traceback, and the bench gets the interrupt while it waits for it."""
    import subprocess

    def run(cmd, stdout=None, stderr=None, **kwargs):
        stderr.write("Traceback (most recent call last):\nKeyboardInterrupt\n")
        stderr.flush()
        raise KeyboardInterrupt

    monkeypatch.setattr(subprocess, "run", run)


def test_an_interrupted_bench_removes_the_folder_it_made(tmp_path, capsys, interrupted_worker):
    out = tmp_path / "new" / "bench"
    assert main(["bench", "--suite", "accuracy", "--quick", "--peers", "none", "--device", "cpu", "-o", str(out)]) == 130
    assert "warp-tube: interrupted; nothing was written\n" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_an_interrupted_bench_leaves_a_folder_that_was_there_as_it_was(tmp_path, capsys, interrupted_worker):
    (tmp_path / "logs").mkdir()
    before = {"mine.txt": "a user's file", "logs/warp_tube-0.log": "an earlier bench's log", "logs/other.log": "x",
              "results.json": "{}"}  # fmt: skip
    for name, text in before.items():
        (tmp_path / name).write_text(text)
    assert main(["bench", "--suite", "accuracy", "--quick", "--peers", "none", "--device", "cpu", "-o", str(tmp_path)]) == 130
    assert "warp-tube: interrupted; nothing was written\n" in capsys.readouterr().err
    after = {str(p.relative_to(tmp_path)): p.read_text() for p in tmp_path.rglob("*") if p.is_file()}
    assert after == before


def _row(results, problem, segments, api="simulation", kind="static"):
    (row,) = [r for r in results["rows"] if r["kind"] == kind and r["problem"] == problem and r["code"] == "warp_tube"
              and r["config"]["segments"] == segments and r["config"].get("api") == api]  # fmt: skip
    return row


def test_quick_accuracy_report_structure(quick_run):
    out, res = quick_run
    for key in ("date", "command", "requested_device", "host", "runs", "rows", "skipped"):
        assert key in res
    (run,) = res["runs"]
    assert run["code"] == "warp_tube" and run["device"] == "cpu" and run["compile_time"] > 0
    assert {"warp_tube", "warp-lang"} <= set(run["versions"])
    kinds = {r["kind"] for r in res["rows"]}
    assert kinds == {"static", "frequency"}  # the accuracy suite has no throughput rows
    report = (out / "report.md").read_text()
    for heading in ("## Time to the answer", "## Static problems, every configuration", "## First natural frequency",
                    "## Compilation / JIT"):  # fmt: skip
        assert heading in report
    assert re.search(r"^\| warp_tube Simulation \| \d+ \| [\d.]+% \| [\d.e-]+ \| 1 \|", report, re.M)


def test_quick_accuracy_errors_match_readme(quick_run):
    _, res = quick_run
    tips, freq = readme_figures()
    for load, expected in zip((1.0, 2.0, 5.0), tips):
        row = _row(res, cantilever(load).name, 20)
        # README gives 2 significant digits (rounded to 1e-5 L: +-0.5e-5); the run ends 15 s after the
        # load with the transient decayed to ~4e-6 of the deflection (<3e-6 L) and float32 jitter ~1e-6 L.
        assert abs(row["error"] - expected) <= 1.5e-5, (load, row["error"], expected)
        # every code must see the answer (tip within 0.2% of L for good) in its run
        assert row["answer_time"] is not None and 0 < row["answer_time"] < row["run_wall"]
    f = _row(res, cantilever(0.0).name, 20, kind="frequency")
    # README's figure comes from 11 periods (tests/test_dynamics.py), the bench measures 2.2; the
    # mean crossing spacing of the two windows differs by up to ~1e-4 (higher modes in the release).
    assert abs(f["frequency_error"] - freq) <= 2e-4, (f["frequency_error"], freq)
    curved = _row(res, CURVED.name, 20)
    # the curved tube under gravity and a push against the scipy reference: within the 0.2% answer
    assert curved["error"] <= 2e-3 and curved["answer_time"] is not None


def test_replot_rewrites_report(quick_run, tmp_path):
    out, _ = quick_run
    assert main(["bench", "--replot", str(out / "results.json"), "-o", str(tmp_path)]) == 0
    assert (tmp_path / "report.md").read_text() == (out / "report.md").read_text()


def test_plots_written(quick_run, tmp_path):
    pytest.importorskip("matplotlib")
    out, _ = quick_run
    assert main(["bench", "--replot", str(out / "results.json"), "-o", str(tmp_path)]) == 0
    for name in ("error_vs_time.png", "convergence.png"):
        assert (tmp_path / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize(
    "args, message",
    [(["--peers", "abaqus"], "unknown peer 'abaqus'"), (["--repeat", "0"], "--repeat 0"), (["--replot", "nowhere.json"], "nowhere.json"),
     (["-o", "file.txt"], "is not a folder")],
)
def test_bad_requests_exit_2(args, message, tmp_path, capsys):
    (tmp_path / "file.txt").write_text("a user's file")
    assert main(["bench", "-o", str(tmp_path / "o"), "--quick", *[str(tmp_path / a) if a == "file.txt" else a for a in args]]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
    assert (tmp_path / "file.txt").read_text() == "a user's file"


def test_planar_reference_against_independent_solutions():
    p = cantilever(2.0)
    # straight, no weight: the same problem as the elastica oracle (checked against Bisshopp & Drucker)
    ref = planar_rod_tip(p.length, p.EI, p.EA, tip_force=p.force[:2])
    assert np.allclose(ref, elastica_tip(2.0, 2.0 * p.EI / p.EA) * p.length, atol=1e-7)
    # a small uniform weight: Euler-Bernoulli tip deflection w L^4 / (8 EI); at w L^3 / EI = 1e-3 the
    # large-deflection correction is ~1e-7 of it, the axial strain below 1e-9
    w = 1e-3 * p.EI / p.length**3
    tip = planar_rod_tip(p.length, p.EI, p.EA, weight_per_length=w)
    assert tip[1] == pytest.approx(-w * p.length**4 / (8 * p.EI), rel=1e-5)
    # a curved rod with no load stays on its rest arc
    tip = planar_rod_tip(CURVED.length, CURVED.EI, CURVED.EA, CURVED.rest_curvature)
    assert np.allclose(tip, CURVED.rest_centerline(8)[-1, :2], atol=1e-9)


def test_answer_time_is_the_start_of_the_last_stay_within_tolerance():
    t = Trace(wall=[1.0, 2.0, 3.0, 4.0, 5.0], error=[1e-2, 1e-3, 5e-3, 1e-3, 5e-4])
    assert t.answer_time(2e-3) == 4.0  # frame 2 is inside, frame 3 leaves again
    assert Trace([1.0, 2.0], [1e-3, 3e-3]).answer_time(2e-3) is None  # ends outside: no answer


def test_aggregate_takes_medians_over_repetitions():
    rec = lambda t, e: dict(kind="static", problem="p", config={"segments": 4}, answer_time=t, error=e, setup_time=0.1)  # noqa: E731
    runs = [dict(code="c", records=[rec(t, e)]) for t, e in ((1.0, 3e-3), (3.0, 1e-3), (2.0, 2e-3))]
    (row,) = aggregate(runs)
    assert row["answer_time"] == 2.0 and row["error"] == 2e-3 and row["reps"] == 3 and row["spread"] == pytest.approx(2.0)
    runs[1]["records"][0]["answer_time"] = None
    assert aggregate(runs)[0]["answer_time"] is None  # one repetition without an answer: none reported


@pytest.mark.gpu
def test_quick_accuracy_on_cuda_with_newton(tmp_path):
    wp = pytest.importorskip("warp")
    wp.init()
    if wp.get_cuda_device_count() == 0:
        pytest.skip("no CUDA device")
    peers = "newton" if _importable("newton") else "none"
    assert main(["bench", "--suite", "all", "--quick", "--peers", peers, "--device", "cuda:0", "-o", str(tmp_path)]) == 0
    res = json.loads((tmp_path / "results.json").read_text())
    assert {r["device"] for r in res["runs"]} == {"cuda:0"}
    assert not [r for r in res["rows"] if "failed" in r]
    assert _row(res, cantilever(2.0).name, 20)["error"] <= 2e-3


def _importable(name):
    import importlib.util

    return importlib.util.find_spec(name) is not None
