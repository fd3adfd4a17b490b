"""What a new user meets first: the help texts, the example scenes' doc strings against what they
do, the preview of a run, and the bench's report, plots and install hints (CPU)."""

import argparse
import re

import numpy as np
import pytest
from PIL import Image
from pxr import Usd, UsdGeom

from warp_tube.cli import _parser, main

from .conftest import SCENES

#: subcommands whose options are described in ``warp_tube/cli.py`` (batch's live in its own module)
CLI_COMMANDS = ("run", "check", "extract", "preview", "export", "batch", "bench")


def _subparsers():
    (sub,) = [a for a in _parser()._actions if isinstance(a, argparse._SubParsersAction)]
    return sub


def test_every_option_is_explained_with_its_default():
    sub = _subparsers()
    for name in CLI_COMMANDS:
        parser = sub.choices[name]
        assert parser.description, f"{name}: no description under its usage line"
        for action in parser._actions:
            if isinstance(action, argparse._HelpAction):
                continue
            assert action.help, f"{name} {action.option_strings or action.dest}: no help"
            if action.option_strings and action.default not in (None, False, argparse.SUPPRESS):
                assert "default" in action.help, f"{name} {action.option_strings}: default {action.default!r} not said"


def test_command_list_names_every_mesh_format_extract_reads():
    sub = _subparsers()
    (extract,) = [a for a in sub._choices_actions if a.dest == "extract"]
    assert "OFF" in extract.help and "glTF binary" in extract.help


@pytest.fixture(scope="module")
def intestine_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("intestine") / "intestine.usdc"
    assert main(["run", str(SCENES / "intestine.usda"), "-o", str(out), "--device", "cpu", "--quiet"]) == 0
    stage = Usd.Stage.Open(str(out))
    attr = UsdGeom.BasisCurves(stage.GetPrimAtPath("/World/Bowel/Centerline")).GetPointsAttr()
    frames = np.array([np.asarray(attr.Get(t)) for t in attr.GetTimeSamples()], dtype=np.float64)  # cm
    return out, frames


def test_intestine_does_what_its_doc_string_says(intestine_run):
    """The scene's doc string: it sags about 3 cm under gravity within 0.4 s and stays sagged; the
    push moves the middle about 2 cm along +Z, the anchors far less; after the release (frame 37)
    the middle is back within 0.5 s, on the sagged shape rather than the rest shape."""
    _, x = intestine_run
    scene = Usd.Stage.Open(str(SCENES / "intestine.usda"))
    doc = scene.GetRootLayer().documentation
    assert "sagged" in doc and "returns to its meandering rest shape" not in doc
    assert len(x) == 97
    moved = np.linalg.norm(x - x[0], axis=2)  # cm
    assert 2.0 <= moved[10].max() <= 4.0  # sagged by frame 10 (0.42 s)
    assert 2.0 <= moved[96].max() <= 4.0  # ... and still at the end: not back at rest
    push = x[32, 20] - x[96, 20]  # the push held (frame 32) against the settled end
    assert 1.5 <= push[2] <= 2.5 and abs(push[0]) < 0.3
    by_push = np.linalg.norm(x[32] - x[96], axis=1)
    assert by_push[[16, 24]].max() < 0.6  # the anchors beside the middle: about 4 mm
    assert by_push[[0, 1, 8, 32, 39, 40]].max() < 0.2  # the others under 2 mm
    assert np.argmax(by_push) in (19, 20, 21)  # the middle loop moves most
    assert np.linalg.norm(x[49, 20] - x[96, 20]) < 0.3  # back 0.5 s after the release


def test_preview_shows_the_first_frame_behind_later_tiles(intestine_run, tmp_path):
    from warp_tube.io import preview as module

    out, _ = intestine_run
    size = 128
    png = module.preview(out, tmp_path / "sheet.png", frames=2, size=size, device="cpu")
    img = np.asarray(Image.open(png).convert("RGB")).astype(int)
    first, last = img[:, :size], img[:, size:]
    ghost = module.GHOST.astype(int)
    background = module.BACKGROUND.astype(int)
    tube_first = np.any(first != background, axis=2)
    ghost_last = np.all(last == ghost, axis=2)
    assert not np.all(first == ghost, axis=2).any()  # the first tile has nothing behind it
    assert ghost_last.sum() > 50  # where the tube was at frame 0 and is no more (it sagged)
    assert np.all(tube_first[ghost_last])  # ... and only there


def _results(repeat):
    row = dict(kind="static", problem="cantilever PL^2/EI=2", error=2e-4, setup_time=0.002, wall_per_simulated_s=0.001,
               reps=repeat, setup="")  # fmt: skip
    rows = [dict(row, code="warp_tube", config={"segments": 10, "api": "simulation"}, answer_time=0.0125),
            dict(row, code="warp_tube", config={"segments": 20, "api": "solver"}, answer_time=0.005),
            dict(row, code="pyelastica", config={"segments": 20, "clamp": "behind"}, answer_time=0.15)]  # fmt: skip
    return dict(command="warp-tube bench", date="2026-11-27T00:00:00+00:00", repeat=repeat, requested_device="cpu",
                host=dict(platform="Linux", cpu_count=2), gpu=None, skipped={}, rows=rows,
                runs=[dict(code="warp_tube", compile_time=0.8, versions={"warp_tube": "0"}, device="cpu")])  # fmt: skip


def test_bench_report_compares_the_solver_api_and_says_repetitions_plainly():
    from warp_tube.bench.report import report_markdown

    text = report_markdown(_results(1))
    assert "`reps` < 1" not in text
    assert re.search(r"^- repetitions: 1 \(one process per code\)$", text, re.M)
    assert re.search(r"^\| warp_tube solver API \| 20 \| .* \| 0\.40x \|", text, re.M)
    assert re.search(r"^\| pyelastica clamp behind \(tuned\) \| 20 \| .* \| 12\.0x \|", text, re.M)
    assert "`reps` < 3: slow configurations run once" in report_markdown(_results(3))


def test_bench_install_hints_can_be_pasted_into_a_shell():
    from warp_tube.bench.peers import newton_runner, pyelastica_runner

    for runner, module in ((newton_runner, "newton"), (pyelastica_runner, "elastica")):
        ok, why = runner.available()
        if ok:
            continue  # installed: no hint to give
        assert 'pip install "warp-tube[peers]"' in why and 'pip install -e ".[peers]"' in why


def test_bench_plots_label_short_log_axes_without_overlap(tmp_path):
    pytest.importorskip("matplotlib")
    import matplotlib.pyplot as plt

    from warp_tube.bench.plots import _short_log_ticks

    fig, ax = plt.subplots(figsize=(7, 5))
    ax.plot([0.0101, 0.0127, 0.0175], [1.9e-4, 8.9e-4, 1.9e-4], "o")
    ax.set_xscale("log")
    ax.set_yscale("log")
    _short_log_ticks(ax)
    fig.canvas.draw()
    lo, hi = ax.get_xlim()
    labels = [t for t in ax.get_xticklabels(which="both") if t.get_text() and lo <= t.get_position()[0] <= hi]
    assert 2 <= len(labels) <= 6
    assert all(re.fullmatch(r"[0-9.]+", t.get_text()) for t in labels)  # 0.012, not 1.2 x 10^-2
    boxes = sorted((t.get_window_extent() for t in labels), key=lambda b: b.x0)
    assert all(a.x1 < b.x0 for a, b in zip(boxes, boxes[1:]))  # no label runs into the next
    plt.close(fig)


def test_verbose_is_taken_after_the_command_and_bench_records_its_own_arguments(tmp_path):
    """``warp-tube run -v`` is ``warp-tube -v run``; the arguments a command records as its command
    line are its own, whether ``-v`` came before it or not."""
    from warp_tube.cli import _parser

    assert _parser().parse_args(["run", "-v"]).verbose and _parser().parse_args(["-v", "run"]).verbose
    assert not _parser().parse_args(["run"]).verbose
    seen = {}
    import warp_tube.cli as cli

    def fake_bench(a):
        seen["argv"] = a.argv
        return 0

    handler = cli._cmd_bench
    cli._cmd_bench = fake_bench
    try:
        assert main(["-v", "bench", "-o", str(tmp_path), "--quick"]) == 0
    finally:
        cli._cmd_bench = handler
        from warp_tube.runtime.warp_setup import set_verbose

        set_verbose(False)  # (main's -v is process-wide: the tests after this one run quiet)
        cli._configure_logging(False)
    assert seen["argv"] == ["-o", str(tmp_path), "--quick"]
