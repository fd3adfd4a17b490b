"""warp-tube batch with tables as spreadsheets save them and careless output folders: what is
read, what is refused (exit status 2, a message naming the row, its line and the column, nothing
written) and what is kept."""

from __future__ import annotations

import csv
import os
import zipfile

import numpy as np
import pytest

from tests.conftest import SCENES
from warp_tube.cli import main as cli

DEFAULT = SCENES / "default.usda"
E = "/World/Tube.warptube:youngsModulus"
DENSITY = "/World/Tube.warptube:density"
SPOKES = "/World/Tube.warptube:spokes"
FORCE = "/World/Push.warptube:force"


def batch(table, out, *args):
    return cli(["batch", str(DEFAULT), "--variants", str(table), "-o", str(out), "--frames", "2", "--no-surface",
                "--quiet", *args])  # fmt: skip


def summary(out):
    with open(out / "summary.csv", newline="", encoding="utf-8") as f:
        return list(csv.DictReader(f))


def refused(tmp_path, capsys, data: bytes, name="t.csv") -> str:
    """Run a batch of table ``data``: exit status 2, nothing written, no traceback; the message."""
    table = tmp_path / name
    table.write_bytes(data)
    out = tmp_path / "out"
    assert batch(table, out) == 2
    err = capsys.readouterr().err
    assert not out.exists() and "Traceback" not in err and "internal error" not in err, err
    return err


# -- tables as spreadsheets save them --------------------------------------------------------------


def test_excel_table_with_bom_crlf_quoted_headers_and_empty_columns_and_rows(tmp_path):
    table = tmp_path / "excel.csv"
    text = f'"{E}", " {DENSITY} ",,\r\n 1e5 ,1050,,\r\n2e5,1100,,\r\n,,,\r\n\r\n'
    table.write_bytes(b"\xef\xbb\xbf" + text.encode())
    out = tmp_path / "out"
    assert batch(table, out) == 0
    rows = summary(out)
    assert [(r[E], r[DENSITY], r["status"]) for r in rows] == [("1e5", "1050", "ok"), ("2e5", "1100", "ok")]
    assert sorted(p.name for p in out.glob("variant_*")) == ["variant_00000.usdc", "variant_00001.usdc"]


@pytest.mark.parametrize("sep, encoding", [(";", "utf-8"), ("\t", "utf-16")], ids=["semicolons", "utf16-tabs"])
def test_semicolon_and_tab_separated_tables_are_read(tmp_path, sep, encoding):
    table = tmp_path / "t.csv"
    table.write_bytes(f"{E}{sep}{DENSITY}\r\n1e5{sep}1050\r\n2e5{sep}1100\r\n".encode(encoding))
    out = tmp_path / "out"
    assert batch(table, out) == 0
    assert [(r[E], r[DENSITY]) for r in summary(out)] == [("1e5", "1050"), ("2e5", "1100")]


def test_decimal_commas_are_named_with_row_line_and_column(tmp_path, capsys):
    err = refused(tmp_path, capsys, f"{E};{DENSITY}\n1e5;1050\n1,5e5;1100\n100,000;1100\n".encode())
    assert f"row 1 (line 3), column {E}: found '1,5e5'" in err and "decimal comma? write 1.5e5" in err
    assert f"row 2 (line 4), column {E}: found '100,000'" in err and "no thousands separators" in err
    err = refused(tmp_path, capsys, f"{E}\n1e5\n2,5e5\n".encode())  # commas split it: two cells
    assert "row 1 (line 3): 2 cells for 1 columns: a decimal comma (1,5) or a thousands separator (1,000) splits a number" in err


def test_an_unquoted_vector_or_array_cell_is_named_as_such_not_as_a_decimal_comma(tmp_path, capsys):
    """Its pieces (``2,2`` inside ``[2,2,2,2]``) look like a number split by a decimal comma: the
    message says to quote the cell, and gives it quoted."""
    err = refused(tmp_path, capsys, b"/World/Tube.widths\n[2,2,2,2]\n")
    assert 'row 0 (line 2): 4 cells for 1 columns: a vector or array cell must be quoted (its commas split it into cells): write "[2, 2, 2, 2]" in double quotes' in err
    assert "decimal comma" not in err
    err = refused(tmp_path, capsys, f"{E},{FORCE}\n1e5,(0, 2, 0)\n".encode())
    assert 'write "(0, 2, 0)" in double quotes' in err and "decimal comma" not in err


@pytest.mark.parametrize("first", ["", "Unnamed: 0"], ids=["empty", "unnamed"])
def test_a_pandas_index_column_is_named_with_what_to_do(tmp_path, capsys, first):
    """``df.to_csv(path)`` writes the index as a first column with an empty header (read back and
    written again: ``Unnamed: 0``)."""
    err = refused(tmp_path, capsys, f"{first},{E}\n0,1e5\n1,2e5\n".encode())
    assert f"line 1, column 1 {first!r}: expected PRIM_PATH.ATTRIBUTE" in err
    assert "a pandas index column? write the table with index=False" in err
    err = refused(tmp_path, capsys, f"{E},Tube.density\n1e5,1050\n".encode())  # (not said of any other header)
    assert "index=False" not in err


def test_a_workbook_or_other_text_encoding_is_refused_with_what_to_do(tmp_path, capsys):
    book = tmp_path / "book.xlsx"
    with zipfile.ZipFile(book, "w") as z:
        z.writestr("[Content_Types].xml", "<Types/>")
    err = refused(tmp_path, capsys, book.read_bytes(), name="book.csv")
    assert "a spreadsheet workbook, not CSV text: save it as CSV" in err
    err = refused(tmp_path, capsys, f"{E}\n1e5\n2e5 \xe9\n".encode("latin-1"))
    assert "line 3: not UTF-8 text (byte 0xe9)" in err


def test_an_unclosed_quote_is_named_not_read_as_one_long_cell(tmp_path, capsys):
    err = refused(tmp_path, capsys, f'{E},{DENSITY}\n1e5,1050\n"2e5,1100\n3e5,1100\n4e5,1100\n'.encode())
    assert 't.csv: line 3: a quote (") opens a cell there and is never closed' in err
    # at the end of the file, with or without a line end (before: read as the cell "2e5" or "(0, 0.02, 0)\n")
    for data, line in ((f'{E}\n1e5\n"2e5', 3), (f'{FORCE}\n"(0, 0.01, 0)"\n"(0,\n 0.02, 0)"\n"(0, 0.02, 0)\n', 5)):
        assert f"t.csv: line {line}: a quote" in refused(tmp_path, capsys, data.encode())
    err = refused(tmp_path, capsys, f'{FORCE},{E}\n"(0,\n 0.01, 0)","1e5"\n"(0, 0.02, 0)", "2e5\n'.encode())
    assert 't.csv: line 4: a quote (") opens a cell there and is never closed' in err  # (its own line, not its row's)


def test_a_quoted_cell_over_lines_is_read_and_later_rows_keep_their_lines(tmp_path, capsys):
    """As pandas writes a long NumPy array: "(0,\n 0.02, 0)" (before: refused as an unclosed quote)."""
    data = f'{FORCE},{E}\r\n"(0,\r\n 0.02, 0)",1e5\r\n"(0, 0.01, 0)",2e5\r\n"(0,\n 0.03,\n 0)",soft\r\n'
    err = refused(tmp_path, capsys, data.encode())
    assert f"row 2 (line 5), column {E}: found 'soft'" in err and "1 problem(s)" in err, err
    table = tmp_path / "ok.csv"
    table.write_bytes(data.replace("soft", "3e5").encode())
    out = tmp_path / "ok"
    assert batch(table, out) == 0
    assert [(r[FORCE].split(), r["status"]) for r in summary(out)] == [
        (["(0,", "0.02,", "0)"], "ok"), (["(0,", "0.01,", "0)"], "ok"), (["(0,", "0.03,", "0)"], "ok")]


def test_a_quoted_empty_cell_or_a_row_of_empty_cells_is_a_row_not_a_blank_line(tmp_path, capsys):
    """A quoted empty cell (pandas' NaN in a table of one column) and a row of empty cells before a
    later row are rows, refused for their empty cells (before: skipped, so that the later rows'
    values went to other variants); lines with nothing on them are skipped."""
    err = refused(tmp_path, capsys, f'{DENSITY}\n1000\n""\n\n1100\n'.encode())
    assert f"row 1 (line 3), column {DENSITY}: empty cell: expected a number" in err and "1 problem(s)" in err
    err = refused(tmp_path, capsys, f"{DENSITY},{E}\n1000,1e5\n,\n1100,2e5\n".encode())
    assert f"row 1 (line 3), column {DENSITY}: empty cell: expected a number" in err
    assert f"row 1 (line 3), column {E}: empty cell: expected a number" in err
    err = refused(tmp_path, capsys, f'{DENSITY}\n1000\n1100\n""\n'.encode())  # last, but quoted: a value
    assert f"row 2 (line 4), column {DENSITY}: empty cell" in err


def test_a_header_after_blank_lines_and_a_value_under_an_empty_header(tmp_path, capsys):
    err = refused(tmp_path, capsys, f"\n\n{E},Tube.density\n1e5,1050\n".encode())
    assert "line 3, column 2 'Tube.density': expected PRIM_PATH.ATTRIBUTE" in err
    err = refused(tmp_path, capsys, f"{E},,\n1e5,,\n2e5,,7\n".encode())
    assert "row 1 (line 3), column 3: a value under an empty header cell" in err


# -- values ---------------------------------------------------------------------------------------


def test_units_overflow_and_fractions_name_row_line_and_column(tmp_path, capsys):
    err = refused(tmp_path, capsys, f"{E},{SPOKES}\n30kPa,8\n1e400,8\n1e5,8.5\n1e5,1e10\n".encode())
    assert f"row 0 (line 2), column {E}: found '30kPa': expected a number (a double) (no units" in err
    assert f"row 1 (line 3), column {E}: found '1e400': beyond the largest double" in err
    assert f"row 2 (line 4), column {SPOKES}: found '8.5': expected an integer" in err
    assert f"row 3 (line 5), column {SPOKES}: found '1e10': 10000000000 is beyond what int holds" in err
    assert "4 problem(s)" in err


def test_integers_written_as_whole_floats_are_read(tmp_path):
    table = tmp_path / "t.csv"
    table.write_text(f"{SPOKES}\n8.0\n1.2e1\n")  # as a spreadsheet or pandas writes whole numbers
    out = tmp_path / "out"
    assert batch(table, out) == 0
    assert [r["status"] for r in summary(out)] == ["ok", "ok"]


def test_point_files_bad_ones_named_and_a_line_of_column_names_skipped(tmp_path, capsys):
    points = np.zeros((21, 3))
    points[:, 0] = np.arange(21)
    np.savetxt(tmp_path / "named.csv", points, delimiter=",", header="x,y,z", comments="")
    (tmp_path / "garbage.npy").write_bytes(b"not numpy at all")
    err = refused(tmp_path, capsys, b"@/World/Tube.points\nnamed.csv\ngarbage.npy\n")
    assert "row 0" not in err  # the line x,y,z is column names, skipped
    assert "row 1 (line 3), column @/World/Tube.points:" in err and "garbage.npy: not a readable .npy array" in err
    assert "pickled" not in err


def test_an_empty_array_written_inline_or_as_an_empty_file_is_no_elements(tmp_path, capsys):
    """A tube with no pins (the scene takes int[] pinnedPoints = []): [] and () in a cell, and a
    file of no numbers (before: [] was refused, and an empty .csv printed NumPy's warning)."""
    from pxr import Usd

    (tmp_path / "none.csv").write_text("index\n")
    table = tmp_path / "t.csv"
    table.write_text("/World/Tube.warptube:pinnedPoints,/World/Tube.warptube:anchorPoints\n[],[ ]\n(),@none.csv\n[0],[]\n")
    out = tmp_path / "out"
    assert batch(table, out) == 0
    err = capsys.readouterr().err
    assert "UserWarning" not in err and "loadtxt" not in err, err
    assert [r["status"] for r in summary(out)] == ["ok"] * 3
    moved = [float(r["max_displacement_m"]) for r in summary(out)]
    # rows 0 and 1 are the same tube (no pins, no anchors), row 2 is held at its first point
    assert moved[0] == moved[1] and moved[2] != moved[0] and min(moved) > 0
    stages = [Usd.Stage.Open(str(out / f"variant_{k:05d}.usdc")) for k in range(3)]
    first = [tuple(st.GetAttributeAtPath("/World/Tube/Centerline.points").Get(1)[0]) for st in stages]
    assert first[2] == (0.0, 0.0, 0.0) and first[0] != (0.0, 0.0, 0.0)  # the pin holds; no pin, the push moves it


# -- output folders and --resume ------------------------------------------------------------------


def files_of(folder):
    return {p.name: p.read_bytes() for p in folder.iterdir() if p.is_file()}


def _interrupted_after_one_variant(scene, out, table):
    from warp_tube.batch import BatchInterrupted, run_batch

    with pytest.raises(BatchInterrupted):
        run_batch(str(scene), str(out), str(table), frames=2, chunk=1, writers=0, surface=False,
                  on_chunk=lambda c: (_ for _ in ()).throw(KeyboardInterrupt()))  # fmt: skip
    kept = files_of(out)
    assert "variant_00000.usdc" in kept and "variant_00001.usdc" not in kept
    return kept


def test_resume_takes_the_same_table_under_another_name(tmp_path, capsys):
    """The record compared the table's path as well as its contents: a byte-identical copy of
    the table (moved, renamed) was refused as "another table". Its contents and the files it names
    are what the variants are made of: the copy resumes, and ends as one batch would."""
    import shutil

    table = tmp_path / "t.csv"
    table.write_text(f"{E}\n1e5\n2e5\n")
    out, whole = tmp_path / "out", tmp_path / "whole"
    _interrupted_after_one_variant(DEFAULT, out, table)
    (tmp_path / "elsewhere").mkdir()
    copy = tmp_path / "elsewhere" / "renamed.csv"
    shutil.copy(table, copy)
    assert batch(copy, out, "--resume") == 0, capsys.readouterr().err
    assert batch(table, whole) == 0
    assert {k: v for k, v in files_of(out).items() if k.endswith(".usdc")} == {
        k: v for k, v in files_of(whole).items() if k.endswith(".usdc")}
    table.write_text(f"{E}\n1e5\n3e5\n")  # other contents: still refused
    assert batch(table, out, "--resume") == 2
    assert "other table" in capsys.readouterr().err


def test_resume_refuses_a_points_file_changed_since_the_batch_began(tmp_path, capsys):
    points = np.zeros((21, 3))
    points[:, 0] = np.arange(21)
    np.save(tmp_path / "a.npy", points)
    np.save(tmp_path / "b.npy", points)
    table = tmp_path / "t.csv"
    table.write_text(f"@/World/Tube.points,{E}\na.npy,1e5\nb.npy,2e5\n")
    out = tmp_path / "out"
    before = _interrupted_after_one_variant(DEFAULT, out, table)
    points[:, 1] = 0.1 * np.arange(21)
    np.save(tmp_path / "b.npy", points)  # edited before the resume
    assert batch(table, out, "--resume") == 2
    err = capsys.readouterr().err
    assert "--resume: the batch there was made with other files the table names: b.npy changed" in err, err
    assert files_of(out) == before


def test_resume_refuses_a_scene_whose_sublayer_changed(tmp_path, capsys):
    scene = tmp_path / "top.usda"
    scene.write_text(f'#usda 1.0\n(\n    subLayers = [@./params.usda@, @{DEFAULT}@]\n)\n')
    params = tmp_path / "params.usda"
    params.write_text('#usda 1.0\nover "World"\n{\n    over "Tube"\n    {\n        double warptube:density = 1200\n    }\n}\n')
    table = tmp_path / "t.csv"
    table.write_text(f"{E}\n1e5\n2e5\n")
    out = tmp_path / "out"
    before = _interrupted_after_one_variant(scene, out, table)
    params.write_text(params.read_text().replace("1200", "900"))
    args = ["batch", str(scene), "--variants", str(table), "-o", str(out), "--frames", "2", "--no-surface", "--resume"]
    assert cli(args) == 2
    err = capsys.readouterr().err
    assert "made with other layers and assets the scene uses:" in err and "params.usda changed" in err, err
    assert files_of(out) == before


def test_resume_names_each_option_that_differs_and_a_damaged_record(tmp_path, capsys):
    table = tmp_path / "t.csv"
    table.write_text(f"{E}\n1e5\n2e5\n")
    out = tmp_path / "out"
    assert batch(table, out) == 0
    before = files_of(out)
    assert cli(["batch", str(DEFAULT), "--variants", str(table), "-o", str(out), "--frames", "3", "--resume"]) == 2
    assert "made with other --frames (2 then, 3 now); Surface (not written then, written now: --no-surface" in capsys.readouterr().err
    (out / ".batch-finished.json").write_text("{")
    assert batch(table, out, "--resume") == 2
    assert ".batch-finished.json is damaged" in capsys.readouterr().err
    before[".batch-finished.json"] = b"{"
    assert files_of(out) == before


@pytest.mark.parametrize("resume", [False, True], ids=["new", "resume"])
def test_a_table_named_as_an_output_of_its_batch_folder_is_refused_and_kept(tmp_path, capsys, resume):
    out = tmp_path / "out"
    out.mkdir()
    table = out / "summary.csv"
    table.write_text(f"{E}\n1e5\n2e5\n")
    assert batch(table, out, *(["--resume"] if resume else [])) == 2
    err = capsys.readouterr().err
    assert "the variants table is in" in err and "under a name the batch writes there (summary.csv)" in err, err
    assert files_of(out) == {"summary.csv": f"{E}\n1e5\n2e5\n".encode()}


def test_resume_where_a_summary_csv_is_not_a_batch_summary(tmp_path, capsys):
    table = tmp_path / "t.csv"
    table.write_text(f"{E}\n1e5\n2e5\n")
    out = tmp_path / "out"
    out.mkdir()
    (out / "summary.csv").write_text("a,b\n1,2\n")
    assert batch(table, out, "--resume") == 2
    err = capsys.readouterr().err
    assert "no batch there to resume" in err and "internal error" not in err, err
    assert files_of(out) == {"summary.csv": b"a,b\n1,2\n"}


def test_an_empty_output_name_is_refused(tmp_path, capsys, monkeypatch):
    table = tmp_path / "t.csv"
    table.write_text(f"{E}\n1e5\n2e5\n")
    monkeypatch.chdir(tmp_path)
    assert batch(table, "") == 2
    assert "-o '': expected a folder name" in capsys.readouterr().err
    assert sorted(os.listdir(tmp_path)) == ["t.csv"]


def test_every_beyond_the_frames_is_warned_of_as_run_does(tmp_path, capsys):
    table = tmp_path / "t.csv"
    table.write_text(f"{E}\n1e5\n2e5\n")
    assert batch(table, tmp_path / "out", "--every", "5") == 0
    assert "--every 5: of frames 0 to 1 only frame 0 is written" in capsys.readouterr().err


def test_frames_after_the_last_written_are_warned_of_as_run_does(tmp_path, capsys):
    """--every 3 --frames 12 writes frames 0, 3, 6, 9: 10 and 11 are simulated, not written."""
    table = tmp_path / "t.csv"
    table.write_text(f"{E}\n1e5\n")
    assert batch(table, tmp_path / "out", "--every", "3", "--frames", "12") == 0
    assert "--every 3: frames 10 to 11 are simulated but not written (the last written is frame 9)" in capsys.readouterr().err


def test_a_single_frame_after_the_last_written_is_said_as_one_frame(tmp_path, capsys):
    """--every 3 --frames 11 writes frames 0, 3, 6, 9: frame 10 alone is simulated, not written
    (not "frames 10 to 10 are")."""
    table = tmp_path / "t.csv"
    table.write_text(f"{E}\n1e5\n")
    assert batch(table, tmp_path / "out", "--every", "3", "--frames", "11") == 0
    err = capsys.readouterr().err
    assert "--every 3: frame 10 is simulated but not written (the last written is frame 9)" in err and "10 to 10" not in err
    assert batch(table, tmp_path / "out4", "--every", "4", "--frames", "9") == 0
    assert "not written" not in capsys.readouterr().err  # (frame 8, the last, is written)


def test_an_empty_variant_sets_option_is_refused(tmp_path, capsys):
    table = tmp_path / "t.csv"
    table.write_text(f"{E}\n1e5\n2e5\n")
    assert batch(table, tmp_path / "out", "--variant-sets", "") == 2
    assert "--variant-sets '': expected all, or SET or /PRIM{SET} names" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_a_cell_longer_than_the_csv_modules_default_limit_is_read(tmp_path):
    n = 8000  # an inline array of 8,000 points: ~150,000 characters in one cell
    points = ", ".join(f"({20 * i / (n - 1):.6f}, 0, 0)" for i in range(n))
    table = tmp_path / "t.csv"
    table.write_text(f'/World/Tube.points,/World/Tube.curveVertexCounts,/World/Push.warptube:point\n"[{points}]",[{n}],10\n')
    assert table.stat().st_size > 131072
    out = tmp_path / "out"
    assert batch(table, out) == 0
    assert [r["status"] for r in summary(out)] == ["ok"]


def test_resume_simulates_again_a_finished_variant_whose_file_was_deleted(tmp_path, capsys):
    table = tmp_path / "t.csv"
    table.write_text(f"{E}\n1e5\n2e5\n")
    out = tmp_path / "out"
    _interrupted_after_one_variant(DEFAULT, out, table)
    (out / "variant_00000.usdc").unlink()
    assert batch(table, out, "--resume") == 0
    assert "variant_00000.usdc, written before, is missing: 1 finished chunk(s) are simulated again" in capsys.readouterr().err
    whole = tmp_path / "whole"
    assert batch(table, whole, "--chunk", "1") == 0
    assert files_of(out) == files_of(whole)


def test_a_folder_holding_a_file_named_like_variant_but_no_batch_takes_a_new_batch(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "variant_list.txt").write_text("my notes\n")
    table = tmp_path / "t.csv"
    table.write_text(f"{E}\n1e5\n2e5\n")
    assert batch(table, out) == 0
    assert (out / "variant_list.txt").read_text() == "my notes\n" and (out / "variant_00001.usdc").exists()


def test_an_interrupt_while_reading_says_how_to_go_on(tmp_path, capsys, monkeypatch):
    """Stopped before its folder is made, a batch has nothing for --resume (before: the message
    gave no advice, and README's, --resume, answered "no such folder")."""
    from warp_tube.batch import run as run_module

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(run_module, "prepare_batch", interrupted)
    table = tmp_path / "t.csv"
    table.write_text(f"{E}\n100000\n")
    assert batch(table, tmp_path / "out") == 130
    err = capsys.readouterr().err
    assert "interrupted; nothing was written (nothing to --resume: run the batch again as it was)" in err, err


def test_a_folder_of_files_named_as_outputs_is_told_from_a_batchs(tmp_path, capsys):
    """A user's summary.csv in the folder: refused, untouched, and not said to be a batch's (whose
    --resume would then answer that it is none); a finished batch's folder: --resume offered."""
    table = tmp_path / "t.csv"
    table.write_text(f"{E}\n100000\n")
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "summary.csv").write_text("precious")
    assert batch(table, mine) == 2
    err = capsys.readouterr().err
    assert "holds files named as a batch's outputs (summary.csv)" in err and "write to another folder" in err, err
    assert (mine / "summary.csv").read_text() == "precious"
    done = tmp_path / "done"
    assert batch(table, done) == 0
    assert batch(table, done) == 2
    assert "holds batch outputs already (summary.csv, .batch-finished.json, variant_00000.usdc): --resume continues" in \
        capsys.readouterr().err  # fmt: skip
