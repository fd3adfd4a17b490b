"""Variants made from the base scene (warp_tube.batch.fastread) against the same rows authored in
the stage and read through usd-core: the same scenes, field for field, bit for bit."""

import dataclasses
from pathlib import Path

import numpy as np
import pytest

import warp_tube.batch.variants as variants_mod
from warp_tube.batch.table import read_table
from warp_tube.batch.variants import collect_variants

SCENE = Path(__file__).resolve().parents[1] / "scenes" / "intestine.usda"
HEADER = ["/World/Bowel.warptube:youngsModulus", "/World/Bowel.warptube:density", "/World/Bowel.warptube:damping",
          "/World/Bowel.warptube:anchorStiffness", "/World/Push.warptube:force"]  # fmt: skip
ROWS = [
    ("20000", "1050", "8", "60", "(0, 0.02, 0)"),
    ("31234.5678", "999.25", "0", "0.1", "(0.0123456789, -0.02, 1e-9)"),  # float3: float32-rounded
    ("20000", "1050", "8", "0", "(0, 0.02, 0)"),  # anchorStiffness 0 with anchors: the reader warns
    ("-5", "1050", "8", "60", "(0, 0.02, 0)"),  # refused: a bad row, named by the reader
    ("1e14", "1050", "8", "60", "(0, 0.02, 0)"),  # beyond the physical range: refused
    ("20000", "1050", "8", "60", "(0, 1e39, 0)"),  # not a float32: refused
    ("5e4", "1100", "2.5", "30", "(0.01, 0, 0.03)"),
]


def same(a, b, where="scene"):
    """Recursive equality of scene dataclasses, arrays bit for bit."""
    if dataclasses.is_dataclass(a):
        assert type(a) is type(b), where
        for f in dataclasses.fields(a):
            same(getattr(a, f.name), getattr(b, f.name), f"{where}.{f.name}")
    elif isinstance(a, (tuple, list)):
        assert len(a) == len(b), where
        for k, (x, y) in enumerate(zip(a, b)):
            same(x, y, f"{where}[{k}]")
    elif isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        assert np.asarray(a).dtype == np.asarray(b).dtype and np.array_equal(a, b), where
    else:
        assert a == b and type(a) is type(b), f"{where}: {a!r} != {b!r}"


def collect(tmp_path, monkeypatch, plain: bool):
    table = tmp_path / "t.csv"
    table.write_text(",".join(HEADER) + "\n" + "\n".join(",".join(f'"{c}"' if "," in c else c for c in r) for r in ROWS) + "\n")
    if not plain:
        monkeypatch.setattr(variants_mod.PlainColumns, "of", classmethod(lambda cls, base, targets: None))
    return collect_variants(str(SCENE), read_table(str(table)))


def test_plain_columns_give_the_scenes_the_stage_gives(tmp_path, monkeypatch, caplog):
    calls = []
    rows_of = variants_mod.PlainColumns.rows
    monkeypatch.setattr(variants_mod.PlainColumns, "rows", lambda self, columns: calls.append(rows_of(self, columns)) or calls[-1])
    fast, fast_problems = collect(tmp_path, monkeypatch, plain=True)
    # rows 0, 1 and 6 made from the base scene (the rows whose cells all read plainly, at once: the
    # first call, without row 5, whose force is no float32); the others read through the stage
    # (each tried alone again first, and refused again)
    assert [m is not None for m in calls[0]] == [True, True, False, False, False, True]
    assert all(c == [None] for c in calls[1:])
    fast_log = [r.getMessage() for r in caplog.records]
    caplog.clear()
    with monkeypatch.context() as m:
        slow, slow_problems = collect(tmp_path, m, plain=False)
    slow_log = [r.getMessage() for r in caplog.records]
    assert fast_problems == slow_problems and [p[0] for p in slow_problems] == [3, 4, 5]
    assert fast_log == slow_log and any("anchorStiffness 0" in msg for msg in slow_log)
    for k, (a, b) in enumerate(zip(fast.variants, slow.variants)):
        assert (a is None) == (b is None), k
        if a is not None:  # (each with its scene made: a plain one's is made when asked for)
            same(a._replace(source=a.scene), b._replace(source=b.scene), f"row {k}")
    # the float3 force was stored as float32 and read back as such
    assert fast.variants[1].scene.forces[0].values[0, 0] == float(np.float32(0.0123456789))


def test_columns_not_taken_fall_back_to_the_stage():
    from warp_tube import load_scene
    from warp_tube.batch.fastread import PlainColumns

    base = load_scene(str(SCENE))
    assert PlainColumns.of(base, [("/World/Bowel", "warptube:youngsModulus", "double")]) is not None
    for target in [("/World/Bowel", "warptube:spokes", "int"), ("/World/Bowel", "widths", "float[]"),
                   ("/World/Bowel", "warptube:damping", "half"), (None, "warptube:damping", "double"),
                   ("/World/Push", "warptube:point", "int"), ("/World", "warptube:density", "double")]:  # fmt: skip
        assert PlainColumns.of(base, [target]) is None, target


def test_a_plain_table_is_read_in_this_process(tmp_path, monkeypatch):
    """Rows made from the base scene cost too little to start processes for a table of this size;
    a table that needs the stage read row by row gets them (both at 2 rows a process here)."""
    import types

    import warp_tube.batch.prepare as prepare

    monkeypatch.setattr(prepare, "PREPARE_ROWS_PER_PROCESS", 2)
    monkeypatch.setattr(prepare.os, "cpu_count", lambda: 2)
    started = []

    class NoPool:
        def __init__(self, *a, **k):
            started.append(a)
            raise RuntimeError("processes started")

    monkeypatch.setattr(prepare.cf, "ProcessPoolExecutor", NoPool)
    bar = types.SimpleNamespace(reading=lambda n: None)
    good = [r for r in ROWS if not r[0].startswith("-") and r[0] != "1e14" and "1e39" not in r[4] and r[3] != "0"]
    table = tmp_path / "plain.csv"
    table.write_text(",".join(HEADER) + "\n" + "\n".join(",".join(f'"{c}"' if "," in c else c for c in r) for r in good) + "\n")
    variants, choices, _ = prepare.prepare_batch(str(SCENE), read_table(str(table)), None, bar)
    assert len(variants.variants) == len(good) == len(choices) and not started
    other = tmp_path / "other.csv"
    other.write_text("/World/Bowel.warptube:spokes\n" + "\n".join(["8", "12", "16", "10"]) + "\n")
    with pytest.raises(RuntimeError, match="processes started"):
        prepare.prepare_batch(str(SCENE), read_table(str(other)), None, bar)


def test_one_row_at_a_time_gives_the_same_scenes():
    """PlainColumns.scenes of every row at once against one row at a time (PlainColumns.scene):
    which rows are taken, and their scenes, do not depend on the other rows."""
    from warp_tube import load_scene
    from warp_tube.batch.fastread import PlainColumns

    base = load_scene(str(SCENE))
    targets = [("/World/Bowel", "warptube:youngsModulus", "double"), ("/World/Bowel", "warptube:damping", "float"),
               ("/World/Bowel", "warptube:anchorStiffness", "double"), ("/World/Push", "warptube:force", "float3")]  # fmt: skip
    plain = PlainColumns.of(base, targets)
    rows = [(2e4, 8.0, 60.0, (0.0, 0.02, 0.0)), (3.1e4, 0.1, 0.0, (0.0, 0.02, 0.0)), (-1.0, 8.0, 60.0, (0.0, 0.0, 0.0)),
            (2e4, float("nan"), 60.0, (0.0, 0.0, 0.0)), (1e14, 1.0, 1.0, (0.0, 0.0, 0.0)),
            (2e4, 1e39, 60.0, (0.0, 0.0, 0.0)), (2e4, 1.0, 60.0, (0.0, 1e39, 0.0)), (5e4, 2.5, 30.0, (0.01, 0.0, 0.03)),
            (5e4, 0.0, 30.0, (0.0, 2e9, 0.0))]  # fmt: skip
    together = plain.scenes([list(col) for col in zip(*rows)])
    assert [s is not None for s in together] == [True, False, False, False, False, False, False, True, False]
    for k, row in enumerate(rows):
        alone = plain.scene(list(row))
        assert (alone is None) == (together[k] is None), k
        if alone is not None:
            same(together[k], alone, f"row {k}")


def test_plain_cells_parse_as_the_general_parser_does():
    """parse_plain takes a subset of the cells parse_value takes, and gives the same values."""
    from warp_tube.batch.values import parse_plain, parse_value

    cells = ["1", " 2.5 ", "-3e-4", "1_000", "nan", "inf", "1e400", "(1.5)", "1,5", "", "@x.npy", "abc", "0x10",
             "(1, 2, 3)", "[1,2,3]", " ( 1 , -2.5e3 , 3 ) ", "1, 2, 3", "(1, 2)", "(1, 2, 3, 4)", "(1,,3)", "(1 2 3)",
             "((1, 2, 3))", "(1, (2), 3)", "(1;2;3)", "(a, b, c)"]  # fmt: skip
    taken = 0
    for type_name in ("double", "float", "double3", "float3"):
        for text in cells:
            fast = parse_plain(text, type_name)
            if fast is None:
                continue
            taken += 1
            general = parse_value(text, type_name)
            assert type(fast) is type(general), (text, type_name)
            assert np.array_equal(np.asarray(fast), np.asarray(general), equal_nan=True), (text, type_name)
    assert taken >= 16  # the plain spellings are taken: numbers, and triples with or without brackets
    assert parse_plain("(1 2 3)", "double3") is None and parse_value("(1 2 3)", "double3") == (1.0, 2.0, 3.0)
    assert parse_plain("1", "int") is None and parse_plain("x", "double") is None


@pytest.mark.parametrize("type_name", ["double", "float", "double3", "float3"])
def test_a_column_parses_as_its_cells_do(type_name):
    """parse_plain_column gives parse_plain's values for a column of plain cells, and None (so
    that the cells are parsed one by one) where any cell is not plain."""
    from warp_tube.batch.values import parse_plain, parse_plain_column

    rng = np.random.default_rng(2)
    if type_name.endswith("3"):
        cells = [f"({a:.6g}, {b!r}, {c:.3e})" for a, b, c in rng.normal(size=(50, 3)).tolist()] + ["[1,2,3]", " ( 1 , -2.5e3 , 3 ) ", "1, 2, 3"]
        bad = ["(1, 2)", "(1, 2, 3, 4)", "(1,,3)", "(a, b, c)", "(1, 2, 1e400)", "@x.npy"]
    else:
        cells = [f"{x!r}" for x in (rng.normal(size=50) * 1e4).tolist()] + [" 2.5 ", "-3e-4", "1_000", "7"]
        bad = ["nan", "1e400", "abc", "", "1,5", "@x.npy"]
    got = parse_plain_column(cells, type_name)
    assert got == [parse_plain(c, type_name) for c in cells]
    assert all(type(g) is type(parse_plain(c, type_name)) for g, c in zip(got, cells))
    for b in bad:
        assert parse_plain_column(cells + [b], type_name) is None, b


def test_plain_variants_take_the_shortcuts_to_the_same_choices_and_keys(tmp_path):
    """A table of plain values: its variants are marked plain, and their run choices and group
    keys, worked out by the shortcuts (one layout, the key from the choice), are those of the
    general path, variant by variant."""
    from warp_tube.batch.plan import group_key, plain_group_keys, run_choices

    good = [r for r in ROWS if not r[0].startswith("-") and r[0] != "1e14" and "1e39" not in r[4] and r[3] != "0"]
    table = tmp_path / "plain.csv"
    table.write_text(",".join(HEADER) + "\n" + "\n".join(",".join(f'"{c}"' if "," in c else c for c in r) for r in good) + "\n")
    variants, problems = collect_variants(str(SCENE), read_table(str(table)))
    assert not problems and variants.plain
    scenes = [v.scene for v in variants.variants]
    choices = run_choices(scenes, plain=True)
    assert choices == run_choices(scenes)
    general = [group_key(s, c) for s, c in zip(scenes, choices)]
    assert plain_group_keys(scenes[0], choices) == general
    # a table that sets anything else is not plain
    other = tmp_path / "other.csv"
    other.write_text("/World/Bowel.warptube:spokes\n8\n12\n")
    assert not collect_variants(str(SCENE), read_table(str(other)))[0].plain


def test_plain_variants_are_planned_and_built_from_their_columns(tmp_path):
    """A table of plain values keeps its rows as columns: planning (run choices, per-node
    parameters) and a chunk's build (forces per world, surfaces) read them without making the
    variants' scenes, and give what the scenes made one by one give, bit for bit."""
    from warp_tube.batch.control import WorldControl
    from warp_tube.batch.fastread import PlainScenes
    from warp_tube.batch.plan import run_choices
    from warp_tube.batch.worlds import build_worlds, combined_tubes, initial_state, release_builders, scenes_node_parameters
    from warp_tube.model.tube import node_parameters

    good = [r for r in ROWS if not r[0].startswith("-") and r[0] != "1e14" and "1e39" not in r[4] and r[3] != "0"]
    table = tmp_path / "plain.csv"
    table.write_text(",".join(HEADER) + "\n" + "\n".join(",".join(f'"{c}"' if "," in c else c for c in r) for r in good) + "\n")
    variants, problems = collect_variants(str(SCENE), read_table(str(table)))
    assert not problems and variants.plain and len(variants) == len(good) >= 3
    lazy = variants.scenes(range(len(variants)))
    assert isinstance(lazy, PlainScenes)
    rows = lazy.rows
    choices = run_choices(lazy, plain=True)
    per_node = scenes_node_parameters(lazy)
    worlds = build_worlds(lazy, "cpu", True, per_node=None)
    state, _, control = initial_state(worlds)
    forces = WorldControl(worlds, control, 1 / 24).forces_at(0.5)
    assert set(rows._made) == {0}  # (the first scene alone: the layout, settings and stage every one shares)
    eager = [v.scene for v in variants.variants]  # every scene made
    assert choices == run_choices(eager)
    general = node_parameters(combined_tubes(eager))[0]
    assert per_node.keys() == general.keys()
    for name, a in general.items():
        np.testing.assert_array_equal(per_node[name], a, err_msg=name)
    release_builders()  # (a builder of their own: not the one the lazy chunk left)
    worlds_eager = build_worlds(eager, "cpu", True)
    assert worlds_eager.surfaces[0] is not worlds.surfaces[0]
    _, _, control_eager = initial_state(worlds_eager)
    np.testing.assert_array_equal(forces, WorldControl(worlds_eager, control_eager, 1 / 24).forces_at(0.5))
    assert forces[:, 0].tolist() == [list(s.forces[0].values[0]) for s in eager]
    for a, b in zip(worlds.surfaces[0].compute(state.node_q), worlds_eager.surfaces[0].compute(state.node_q)):
        np.testing.assert_array_equal(a.numpy(), b.numpy())


@pytest.mark.parametrize("text, type_name, why", [
    ("1e5)", "double", "do not balance"), ("(((1e5", "double", "do not balance"), ("((1e5))", "double", "nested 2 deep"),
    ("[1e5]", "double", "nested 1 deep"), ("\u0661\u0662\u0663", "double", "other than ASCII"),  # Arabic-Indic 123
    ("[0,", "int[]", "do not balance"), ("[[0]]", "int[]", "nested 2 deep"), ("[(0,0,0)]", "float3", "nested 2 deep"),
    ("((0, 0, 0)", "float3", "do not balance"), ("(0, 0, 0))", "float3", "do not balance"), ("(0, 0, 0]", "float3", "do not balance"),
])  # fmt: skip
def test_a_cell_whose_brackets_do_not_fit_its_type_is_refused(text, type_name, why):
    """Brackets and separators split a cell into numbers; a cell whose brackets do not balance or
    nest deeper than its type (a scalar: none; a vector or an array: one pair; an array of vectors:
    two) was read as its numbers alone (``1e5)`` as 1e5). Both parsers refuse it (the plain one
    leaves it to the general one)."""
    from warp_tube.batch.values import parse_plain, parse_plain_column, parse_value

    with pytest.raises(ValueError, match=why):
        parse_value(text, type_name)
    assert parse_plain(text, type_name) is None
    if type_name in ("double", "float3"):
        assert parse_plain_column(["1" if type_name == "double" else "(1, 2, 3)", text], type_name) is None


def test_a_long_cell_is_shown_cut_in_its_message():
    from warp_tube.batch.values import parse_value

    with pytest.raises(ValueError) as err:
        parse_value("x" * 1_000_000, "double")
    assert len(str(err.value)) < 400 and "(1,000,000 characters)" in str(err.value)
