"""A variant that fails among the worlds and is run alone: what its run warns of goes into its
summary row (its reason), not onto the terminal unnamed."""

import csv
import subprocess
import sys
from pathlib import Path

DEFAULT = Path(__file__).resolve().parents[1] / "scenes" / "default.usda"


def test_warnings_of_a_variant_run_alone_are_in_its_row(tmp_path):
    table = tmp_path / "t.csv"
    # 3 kN on a soft 2 cm tube: the world blows up among the others; alone, `auto` redoes the
    # frame with more substeps, then switches to implicit Euler, which Simulation warns of (it
    # fails even at 16x the substeps; 0.5-1 kN come through with more substeps alone, or not, as
    # round-off has it).
    table.write_text('/World/Push.warptube:force\n"(0, 0.02, 0)"\n"(0, 3000, 0)"\n')
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-m", "warp_tube", "batch", str(DEFAULT), "--variants", str(table), "-o", str(out),
                        "--frames", "4", "--layout", "arrays"], capture_output=True, text=True)  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert "switched to implicit Euler" not in r.stderr  # (said in the row, which names the variant)
    rows = list(csv.DictReader(open(out / "summary.csv", encoding="utf-8")))
    assert rows[0]["reason"] == ""
    assert rows[1]["status"] == "ok" and "ran alone" in rows[1]["reason"] and "switched to implicit Euler" in rows[1]["reason"]
