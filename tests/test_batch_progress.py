"""warp-tube batch's progress where stderr is not a terminal (a log file): a plain line every 30 s
with the variant-frames and variants done and the time left, as ``warp-tube run`` writes; nothing
with --quiet. A fake clock or an interval of 0 s, not a timed test."""

from __future__ import annotations

import io

from tests.conftest import SCENES
from warp_tube.batch.progress import LINES, Progress
from warp_tube.cli import main as cli

DEFAULT = SCENES / "default.usda"
E = "/World/Tube.warptube:youngsModulus"


class Clock:
    def __init__(self):
        self.now = 100.0

    def __call__(self):
        return self.now


def test_a_line_every_interval_with_variants_frames_elapsed_and_time_left():
    clock, out = Clock(), io.StringIO()
    bar = Progress(LINES, interval=30.0, stream=out, clock=clock)
    bar.start(600, 4, 0)
    clock.now += 10
    bar.frames(60)
    assert out.getvalue() == ""  # (not before the interval)
    clock.now += 20
    bar.frames(60)
    assert out.getvalue() == ("warp-tube: batch: 120 of 600 variant-frames (20%), 0 of 4 variants written, "
                              "30 s so far, about 2.0 min left\n")  # fmt: skip
    clock.now += 10
    bar.variants_done(2)
    assert out.getvalue().count("\n") == 1
    clock.now += 30
    bar.frames(180)
    last = out.getvalue().splitlines()[-1]
    assert last == "warp-tube: batch: 300 of 600 variant-frames (50%), 2 of 4 variants written, 70 s so far, about 70 s left"
    bar.close()


def test_bars_and_nothing_write_no_lines(capsys):
    for on in (False, True):
        out = io.StringIO()
        bar = Progress(on, interval=0.0, stream=out)
        bar.start(10, 1, 0)
        bar.frames(5)
        bar.close()
        assert out.getvalue() == ""


def test_the_command_writes_lines_into_a_log_and_none_with_quiet(tmp_path, capsys, monkeypatch):
    """stderr captured (not a terminal): lines, here every frame (an interval of 0 s)."""
    import warp_tube.runtime.progress as progress

    monkeypatch.setattr(progress, "PLAIN_INTERVAL", 0.0)
    table = tmp_path / "t.csv"
    table.write_text(f"{E}\n1e5\n2e5\n3e5\n")
    args = ["batch", str(DEFAULT), "--variants", str(table), "--frames", "5", "--chunk", "1", "--writers", "0", "--no-surface"]
    assert cli([*args, "-o", str(tmp_path / "log")]) == 0
    err = capsys.readouterr().err
    lines = [x for x in err.splitlines() if x.startswith("warp-tube: batch: ")]
    assert lines, err
    assert all(" of 12 variant-frames (" in x and " of 3 variants written, " in x and " so far" in x for x in lines), lines
    assert any("left" in x for x in lines) and "\r" not in err
    assert cli([*args, "-o", str(tmp_path / "quiet"), "--quiet"]) == 0
    assert "warp-tube: batch: " not in capsys.readouterr().err
