"""warp-tube batch on the CPU: variant k of a batch against the same variant run alone with
``warp-tube run``, layouts, failures, resume, bad tables, and a local Dask cluster."""

from __future__ import annotations

import filecmp
import os
from dataclasses import replace

import numpy as np
import pytest
import warp as wp

from tests.conftest import SCENES, check_output_problems, needs_shared
from warp_tube.batch import BatchInterrupted, run_batch
from warp_tube.scene.spec import SceneError
from warp_tube.cli import main as cli

DEFAULT = SCENES / "default.usda"
FRAMES = 8
E = "/World/Tube.warptube:youngsModulus"
FORCE = "/World/Push.warptube:force"
WIDTHS = "/World/Tube.widths"


def write_table(path, header, rows):
    lines = [",".join(header)] + [",".join(f'"{c}"' if "," in c else c for c in row) for row in rows]
    path.write_text("\n".join(lines) + "\n")
    return path


def variant_scene(tmp_path, name, overrides: dict, selection: dict | None = None, base=DEFAULT):
    """The scene ``base`` with ``overrides`` ({"/Prim.attr": value}) authored in place of the
    scene's own values and time samples, as a user would edit it by hand; a file ``warp-tube run``
    reads."""
    from pxr import Sdf, Usd

    path = tmp_path / f"{name}.usda"
    Sdf.Layer.FindOrOpen(str(base)).Export(str(path))
    stage = Usd.Stage.Open(str(path))
    for (prim, set_name), choice in (selection or {}).items():
        stage.GetPrimAtPath(prim).GetVariantSet(set_name).SetVariantSelection(choice)
    for target, value in overrides.items():
        prim, attr = target.rsplit(".", 1)
        a = stage.GetPrimAtPath(prim).GetAttribute(attr)
        a.Clear()
        a.Set(value)
    stage.GetRootLayer().Save()
    return path


def stage_samples(path):
    """Every time-sampled point array of an output stage: {attribute path: (times, arrays)}."""
    from pxr import Usd

    stage = Usd.Stage.Open(str(path))
    out = {}
    for prim in stage.Traverse():
        for a in prim.GetAttributes():
            times = a.GetTimeSamples()
            if times:
                out[str(a.GetPath())] = (times, [np.asarray(a.Get(t), dtype=np.float64) for t in times])
    return out


@pytest.fixture(scope="module")
def sweep(tmp_path_factory):
    """A batch of five variants of the default scene (stiffness, push, widths), files layout."""
    from pxr import Gf

    d = tmp_path_factory.mktemp("sweep")
    rows = [("100000", "(0, 0.02, 0)", "[2]"), ("100000", "(0, 0.03, 0.01)", "[2]"), ("250000", "(0, 0.02, 0)", "[2]"),
            ("100000", "(0.01, 0, 0.02)", "[2.5]"), ("60000", "(0, -0.02, 0)", "[2]")]  # fmt: skip
    table = write_table(d / "table.csv", [E, FORCE, WIDTHS], rows)
    out = d / "out"
    result = run_batch(str(DEFAULT), str(out), str(table), frames=FRAMES, writers=0)
    values = [{E: float(e), FORCE: Gf.Vec3f(*eval(f)), WIDTHS: [float(w.strip("[]"))]} for e, f, w in rows]
    return d, out, result, values


def test_batch_variant_equals_the_variant_run_alone(sweep, tmp_path):
    d, out, result, values = sweep
    assert (result.ok, result.failed, result.variants) == (5, 0, 5)
    assert result.groups >= 3  # widths 2.5 and the stiff variant's substeps make groups of their own
    for k in (1, 3, 4):
        scene = variant_scene(tmp_path, f"v{k}", values[k])
        alone = tmp_path / f"alone{k}.usdc"
        assert cli(["run", str(scene), "-o", str(alone), "--frames", str(FRAMES), "--quiet"]) == 0
        a, b = stage_samples(alone), stage_samples(out / f"variant_{k:05d}.usdc")
        assert a.keys() == b.keys() and len(a) == 5  # Centerline points, extent, Surface points, normals, extent
        for name in a:
            assert a[name][0] == b[name][0]
            # Each world runs the same kernels on the same float32 inputs as the run alone (the
            # control's float64 arithmetic included), so the samples agree to float32 round-off:
            # 1e-6 of the tube's 20-unit length is ~16 float32 ulps of its largest coordinate.
            # (On the CPU they are identical, and so are the files.)
            assert max(np.abs(x - y).max() for x, y in zip(a[name][1], b[name][1])) <= 2e-5, name
        assert filecmp.cmp(alone, out / f"variant_{k:05d}.usdc", shallow=False)


def test_variants_of_other_widths_and_rest_shapes_run_as_worlds_of_one_group(tmp_path):
    """Widths and rest points varied by the table, at one substep (a fixed timeStep within every
    variant's stability bound): the surface builders hold each world's rest frames and inner-bend
    guard window, so the variants are one group, and each still gives what it gives alone."""
    from pxr import Vt

    base = tmp_path / "base.usda"
    base.write_text(DEFAULT.read_text().replace('token warptube:integrator = "auto"',
                                                'token warptube:integrator = "semiImplicitEuler"\n'
                                                '        double warptube:timeStep = 0.00005'))  # fmt: skip
    # A U-turn of bend radius 1 (its legs 2 apart, the tubes' radii 1 and 1.3), its points 0.4
    # apart: the inner-bend guard's cells across the U lie within one world's window along the
    # tube (pi radii) and not within another's; turned out of the straight tube's line (other rest
    # frames from the first hub on).
    s = np.arange(21.0)
    x = 0.4 * s
    a = np.clip(x - 2.8, 0.0, np.pi)
    u = np.stack([np.minimum(x, 2.8) + np.sin(a) - np.maximum(x - 2.8 - np.pi, 0.0), 1.0 - np.cos(a), 0 * s], 1)
    c, d = np.cos(0.6), np.sin(0.6)
    bent = (u @ np.array([[c, d, 0.0], [-d * c, c * c, d], [d * d, -d * c, c]])).astype(np.float32)
    straight = np.stack([s, 0 * s, 0 * s], 1).astype(np.float32)
    np.save(tmp_path / "bent.npy", bent)
    np.save(tmp_path / "straight.npy", straight)
    rows = [("[1.6]", "@straight.npy"), ("[2]", "@bent.npy"), ("[2.6]", "@bent.npy")]
    table = write_table(tmp_path / "table.csv", [WIDTHS, "/World/Tube.points"], rows)
    out = tmp_path / "out"
    result = run_batch(str(base), str(out), str(table), frames=FRAMES, writers=0, chunk=3)
    assert (result.ok, result.groups, result.chunks) == (3, 1, 1)
    for k, (width, points) in enumerate([(1.6, straight), (2.0, bent), (2.6, bent)]):
        scene = variant_scene(tmp_path, f"v{k}", {WIDTHS: [width], "/World/Tube.points": Vt.Vec3fArray.FromNumpy(points)}, base=base)
        alone = tmp_path / f"alone{k}.usdc"
        assert cli(["run", str(scene), "-o", str(alone), "--frames", str(FRAMES), "--quiet"]) == 0
        # On the CPU each world runs the run alone's kernels on the same float32 inputs: the same
        # files, byte for byte (a guard window or rest frame of another world would move the
        # surface's points).
        assert filecmp.cmp(alone, out / f"variant_{k:05d}.usdc", shallow=False), k


@needs_shared
def test_batch_files_pass_the_output_checker(sweep):
    _, out, _, _ = sweep
    assert check_output_problems(out / "variant_00002.usdc", DEFAULT, require_surface=True) == []


def test_summary_has_a_row_per_variant_with_its_parameters(sweep):
    import csv

    _, out, _, values = sweep
    rows = list(csv.DictReader(open(out / "summary.csv")))
    assert [r["name"] for r in rows] == [f"variant_{k:05d}" for k in range(5)]
    assert [float(r[E]) for r in rows] == [v[E] for v in values]
    assert all(r["status"] == "ok" and r["output"] == f"{r['name']}.usdc" for r in rows)
    # The pushes do work and the tube moves: displacement and work are positive, the stiffer tube
    # (variant 2, 2.5x the modulus of variant 0 under the same push) moves less.
    disp = [float(r["max_displacement_m"]) for r in rows]
    assert all(x > 0 for x in disp) and disp[2] < disp[0]
    assert all(float(r["work_J"]) > 0 for r in rows)
    assert not os.path.exists(out / ".batch")


def test_arrays_and_grid_layouts_hold_the_same_frames(sweep, tmp_path):
    d, files_out, _, _ = sweep
    table = d / "table.csv"
    arr = tmp_path / "arrays"
    run_batch(str(DEFAULT), str(arr), str(table), frames=FRAMES, layout="arrays", surface=True, writers=0)
    cl = np.load(arr / "centerline.npy", mmap_mode="r")
    surf = np.load(arr / "surface.npy", mmap_mode="r")
    assert cl.shape == (5, FRAMES, 21, 3) and cl.dtype == np.float32
    assert surf.shape[:2] == (5, FRAMES)
    for k in (0, 3):
        s = stage_samples(files_out / f"variant_{k:05d}.usdc")
        # the same float32 values, copied: exact
        assert np.array_equal(cl[k], np.stack(s["/World/Tube/Centerline.points"][1]).astype(np.float32))
        assert np.array_equal(surf[k], np.stack(s["/World/Tube/Surface.points"][1]).astype(np.float32))
    grid = tmp_path / "grid"
    run_batch(str(DEFAULT), str(grid), str(table), frames=FRAMES, layout="grid", every=2, writers=0)
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(grid / "grid.usda"))
    kids = [p.GetName() for p in stage.GetPrimAtPath("/Grid").GetChildren()]
    assert kids == [f"variant_{k:05d}" for k in range(5)]
    pts = stage.GetAttributeAtPath("/Grid/variant_00003/World/Tube/Centerline.points")
    assert list(pts.GetTimeSamples()) == [0.0, 2.0, 4.0, 6.0]
    s = stage_samples(files_out / "variant_00003.usdc")["/World/Tube/Centerline.points"][1]
    assert np.array_equal(np.asarray(pts.Get(4.0)), s[4].astype(np.float32))
    m = UsdGeom.Xformable(stage.GetPrimAtPath("/Grid/variant_00003")).ComputeLocalToWorldTransform(0.0)
    offsets = [UsdGeom.Xformable(stage.GetPrimAtPath(f"/Grid/{n}")).ComputeLocalToWorldTransform(0.0).ExtractTranslation()
               for n in kids]  # fmt: skip
    # side by side: no two variants at the same place, none further than the grid's extent
    assert len({tuple(o) for o in offsets}) == 5
    assert m.ExtractTranslation()[1] == 0.0  # the grid lies across the up axis (Y)


def test_chunks_written_while_the_next_simulates_reuse_no_live_buffer(sweep, tmp_path):
    """One variant per chunk and a pool of writers: each chunk's frames go into buffers an earlier
    chunk used (two in turn) while that chunk may still be written; every variant must still
    come out as in the batch written in one process (the same bytes; arrays: the same values)."""
    d, files_out, _, _ = sweep
    table = d / "table.csv"
    # Writers finish in any order (a later chunk's before an earlier one's): three runs, since a
    # slot handed on too early shows only in some of them.
    for trial in range(3):
        files = tmp_path / f"files{trial}"
        run_batch(str(DEFAULT), str(files), str(table), frames=FRAMES, chunk=1, writers=2)  # writer processes
        for k in range(5):
            assert filecmp.cmp(files / f"variant_{k:05d}.usdc", files_out / f"variant_{k:05d}.usdc", shallow=False), k
    one, pooled = tmp_path / "one", tmp_path / "pooled"
    run_batch(str(DEFAULT), str(one), str(table), frames=FRAMES, layout="arrays", surface=True, writers=0)
    run_batch(str(DEFAULT), str(pooled), str(table), frames=FRAMES, layout="arrays", surface=True, chunk=1, writers=2)  # threads
    for name in ("centerline.npy", "surface.npy"):
        assert np.array_equal(np.load(one / name), np.load(pooled / name), equal_nan=True), name


def test_failed_variant_is_marked_and_the_others_go_on(tmp_path):
    # One forced substep for all: stable for the soft tubes, beyond the stiff one's bound (its
    # bound shrinks as 1/sqrt(E)), so that world blows up while the others run on.
    table = write_table(tmp_path / "t.csv", [E, "/World/Simulation.warptube:integrator", "/World/Simulation.warptube:timeStep"],
                        [("100000", "semiImplicitEuler", "0.0002"), ("50000000", "semiImplicitEuler", "0.0002"),
                         ("80000", "semiImplicitEuler", "0.0002")])  # fmt: skip
    out = tmp_path / "out"
    status = cli(["batch", str(DEFAULT), "--variants", str(table), "-o", str(out), "--frames", "6", "--writers", "0", "--quiet"])
    assert status == 3
    import csv

    rows = list(csv.DictReader(open(out / "summary.csv")))
    assert [r["status"] for r in rows] == ["ok", "failed", "ok"]
    assert "numerical failure at frame" in rows[1]["reason"] and rows[1]["output"] == "variant_00001.partial.usdc"
    assert int(rows[1]["frames"]) < 6 and int(rows[0]["frames"]) == 6
    # no result for the failed one: NaN (not the last finished frame's, the rest state where frame 1 failed)
    import math

    results = ("max_displacement_m", "tip_x", "tip_y", "tip_z", "kinetic_energy_J", "work_J", "max_stretch")
    assert all(math.isnan(float(rows[1][k])) for k in results), rows[1]
    assert all(math.isfinite(float(rows[k][f])) for k in (0, 2) for f in results)
    assert sorted(p.name for p in out.iterdir()) == [".batch-finished.json", "summary.csv", "variant_00000.usdc",
                                                     "variant_00001.partial.usdc", "variant_00002.usdc"]  # fmt: skip
    # the ones that ran on are what they are alone
    scene = variant_scene(tmp_path, "v2", {E: 80000.0, "/World/Simulation.warptube:integrator": "semiImplicitEuler"})
    from pxr import Sdf, Usd

    st = Usd.Stage.Open(str(scene))
    st.GetPrimAtPath("/World/Simulation").CreateAttribute("warptube:timeStep", Sdf.ValueTypeNames.Double).Set(0.0002)
    st.GetRootLayer().Save()
    alone = tmp_path / "alone.usdc"
    assert cli(["run", str(scene), "-o", str(alone), "--frames", "6", "--quiet"]) == 0
    assert filecmp.cmp(alone, out / "variant_00002.usdc", shallow=False)


def test_a_failed_variant_keeps_its_finished_frames_in_its_grid_cell(tmp_path):
    """As the files layout keeps them in ``variant_00001.partial.usdc``: the grid holds the failed
    variant's frames up to its failure in its cell (the same values), its prim marked partial, and
    the summary names grid.usda as its output."""
    import csv

    from pxr import Usd

    table = write_table(tmp_path / "t.csv", [E, "/World/Simulation.warptube:integrator", "/World/Simulation.warptube:timeStep"],
                        [("100000", "semiImplicitEuler", "0.0002"), ("50000000", "semiImplicitEuler", "0.0002"),
                         ("80000", "semiImplicitEuler", "0.0002")])  # fmt: skip
    files, grid = tmp_path / "files", tmp_path / "grid"
    for out, layout in ((files, "files"), (grid, "grid")):
        status = cli(["batch", str(DEFAULT), "--variants", str(table), "-o", str(out), "--frames", "6", "--writers", "0",
                      "--layout", layout, "--quiet"])  # fmt: skip
        assert status == 3
    rows = list(csv.DictReader(open(grid / "summary.csv")))
    assert [r["status"] for r in rows] == ["ok", "failed", "ok"]
    assert [r["output"] for r in rows] == ["grid.usda"] * 3
    n = int(rows[1]["frames"])
    assert 0 < n < 6
    stage = Usd.Stage.Open(str(grid / "grid.usda"))
    assert [p.GetName() for p in stage.GetPrimAtPath("/Grid").GetChildren()] == [f"variant_{k:05d}" for k in range(3)]
    failed = stage.GetPrimAtPath("/Grid/variant_00001")
    assert failed.GetCustomDataByKey("warptube:partial") is True and failed.GetCustomDataByKey("warptube:framesWritten") == n
    assert stage.GetPrimAtPath("/Grid/variant_00000").GetCustomDataByKey("warptube:partial") is None
    times, arrays = stage_samples(files / "variant_00001.partial.usdc")["/World/Tube/Centerline.points"]
    pts = stage.GetAttributeAtPath("/Grid/variant_00001/World/Tube/Centerline.points")
    assert list(pts.GetTimeSamples()) == list(times) and len(times) == n
    assert all(np.array_equal(np.asarray(pts.Get(t)), a) for t, a in zip(times, arrays))
    assert len(stage.GetAttributeAtPath("/Grid/variant_00002/World/Tube/Centerline.points").GetTimeSamples()) == 6


def grid_centerlines(out):
    """Per frame of ``out/grid.usda``, each variant's centerline points in the world and radius."""
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(out / "grid.usda"))
    curves = [p for p in stage.Traverse() if p.GetName() == "Centerline"]
    frames = {}
    for t in curves[0].GetAttribute("points").GetTimeSamples():
        for p in curves:
            m = UsdGeom.Xformable(p).ComputeLocalToWorldTransform(t)
            pts = np.array([m.Transform(q) for q in p.GetAttribute("points").Get(t)])
            frames.setdefault(t, []).append((pts, max(p.GetAttribute("widths").Get(t)) / 2))
    return frames


def test_grid_neighbours_cannot_meet_however_they_move(tmp_path):
    """The grid's cells are spaced from the variants' largest displacement (known at the end):
    pushed tubes, which reach well past their rest shape, never come within the sum of their
    radii of a neighbour; and variants whose rest shapes lie apart are each centred in a cell."""
    import itertools

    table = write_table(tmp_path / "t.csv", [E, FORCE], [("1e5", "(0, 0.1, 0)"), ("2e4", "(-0.3, 0.02, 0)"),
                        ("1e5", "(0, 0, 0)"), ("1e5", "(0, 0, 0)")])  # fmt: skip
    out = tmp_path / "out"
    run_batch(str(DEFAULT), str(out), str(table), frames=20, layout="grid", writers=0)
    for t, tubes in grid_centerlines(out).items():
        for (a, ra), (b, rb) in itertools.combinations(tubes, 2):
            assert np.linalg.norm(a[:, None] - b[None], axis=-1).min() > ra + rb, t
    x = np.arange(21, dtype=np.float32)
    np.save(tmp_path / "origin.npy", np.stack([x, 0 * x, 0 * x], 1))
    np.save(tmp_path / "shifted.npy", np.stack([x - 33, 0 * x, 0 * x], 1))
    table = write_table(tmp_path / "a.csv", [E, "@/World/Tube.points"], [("1e5", "origin.npy"), ("1e5", "shifted.npy")])
    out = tmp_path / "apart"
    run_batch(str(DEFAULT), str(out), str(table), frames=2, layout="grid", writers=0)
    (a, _), (b, _) = grid_centerlines(out)[0.0]
    centre_a, centre_b = (a.min(0) + a.max(0)) / 2, (b.min(0) + b.max(0)) / 2
    assert centre_a[0] == pytest.approx(0.0, abs=1e-4) and centre_b[0] - centre_a[0] > 21


@pytest.mark.parametrize("records", ["here", "process"])
def test_interrupt_and_resume_end_with_the_same_files(tmp_path, monkeypatch, records):
    """Also with the chunks' records (journal, summary lines) made by a process of their own, as
    for a large batch: the same summary as made here, every chunk recorded as finished in the
    journal when the batch is interrupted."""
    import warp_tube.batch.run as batch_run

    table = write_table(tmp_path / "t.csv", [E, FORCE],
                        [(str(80000 + 10000 * k), f"(0, {0.01 + 0.002 * k}, 0)") for k in range(6)])  # fmt: skip
    if records == "process":
        here = tmp_path / "here"
        run_batch(str(DEFAULT), str(here), str(table), frames=5, chunk=2, writers=1)
        monkeypatch.setattr(batch_run, "PROCESS_VARIANTS", 1)
    whole = tmp_path / "whole"
    run_batch(str(DEFAULT), str(whole), str(table), frames=5, chunk=2, writers=1)
    if records == "process":
        assert (whole / "summary.csv").read_bytes() == (here / "summary.csv").read_bytes()

    part = tmp_path / "part"
    seen = []

    def stop_after_first(chunk_id):
        seen.append(chunk_id)
        raise KeyboardInterrupt

    with pytest.raises(BatchInterrupted) as e:
        run_batch(str(DEFAULT), str(part), str(table), frames=5, chunk=2, writers=1, on_chunk=stop_after_first)
    assert e.value.result.pending == 4
    assert (part / ".batch").is_dir() and not (part / "summary.csv").exists()
    # the finished chunk's variants are complete files
    kept = sorted(p.name for p in part.glob("variant_*.usdc"))
    assert {f"variant_{i:05d}.usdc" for i in (0, 1)} <= set(kept)
    # without --resume the folder is refused; with it the batch goes on
    with pytest.raises(Exception, match="--resume continues"):
        run_batch(str(DEFAULT), str(part), str(table), frames=5, chunk=2, writers=1)
    result = run_batch(str(DEFAULT), str(part), str(table), frames=5, writers=1, resume=True)
    assert result.resumed == 2 and result.ok == 6
    names = sorted(p.name for p in whole.iterdir())
    assert names == sorted(p.name for p in part.iterdir())
    for n in names:
        assert filecmp.cmp(whole / n, part / n, shallow=False), n
    # resuming a finished batch does nothing
    again = run_batch(str(DEFAULT), str(part), str(table), frames=5, writers=1, resume=True)
    assert (again.resumed, again.ok) == (6, 6)
    assert sorted(p.name for p in part.iterdir()) == names
    # ... but with other options or another table it is refused, and nothing changes
    other = write_table(tmp_path / "other.csv", [E], [("90000",), ("95000",)])
    for kw, what in ((dict(frames=4), "frames"), (dict(frames=5, layout="arrays"), "layout"), (dict(frames=5, table=str(other)), "table")):
        args = dict(dict(table=str(table)), **kw)
        with pytest.raises(SceneError, match=f"finished and was made with other .*{what}"):
            run_batch(str(DEFAULT), str(part), args.pop("table"), writers=1, resume=True, **args)
    assert sorted(p.name for p in part.iterdir()) == names


def test_a_stopped_batch_leaves_no_temporary_file(tmp_path):
    """A writer process stopped mid-file (a SIGTERM to the batch's process group reaches it, which
    Ctrl-C does not) leaves its hidden temporary file; the batch removes what is left once its
    writers are gone, and keeps its finished variants for --resume. Here a file of that name is
    left in the folder while the batch runs, and the batch is stopped after its first chunk."""
    table = write_table(tmp_path / "t.csv", [E], [(str(80000 + 10000 * k),) for k in range(4)])
    out = tmp_path / "out"

    def stop(chunk_id):
        (out / ".variant_00003.tmp-99999.usdc").write_bytes(b"half a file")  # (as a killed writer leaves it)
        (out / "grid").mkdir(exist_ok=True)
        (out / "grid" / ".chunk_00001.tmp-99999.usdc").write_bytes(b"half a file")
        raise KeyboardInterrupt

    with pytest.raises(BatchInterrupted):
        run_batch(str(DEFAULT), str(out), str(table), frames=3, chunk=2, writers=0, on_chunk=stop)
    left = sorted(p.name for p in out.rglob("*") if ".tmp-" in p.name)
    assert left == [], left
    assert "variant_00000.usdc" in {p.name for p in out.glob("variant_*.usdc")}  # (the finished chunk's, kept)
    assert run_batch(str(DEFAULT), str(out), str(table), frames=3, writers=0, resume=True).ok == 4


def test_resume_refuses_other_options(tmp_path):
    table = write_table(tmp_path / "t.csv", [E], [("100000",), ("90000",)])
    out = tmp_path / "out"
    with pytest.raises(BatchInterrupted):
        run_batch(str(DEFAULT), str(out), str(table), frames=3, chunk=1, writers=0,
                  on_chunk=lambda c: (_ for _ in ()).throw(KeyboardInterrupt()))  # fmt: skip
    status = cli(["batch", str(DEFAULT), "--variants", str(table), "-o", str(out), "--frames", "4", "--resume", "--quiet"])
    assert status == 2


def _bad(tmp_path, capsys, header, rows, *extra, files=None):
    for name, data in (files or {}).items():
        np.save(tmp_path / name, data)
    table = write_table(tmp_path / "bad.csv", header, rows)
    out = tmp_path / "out"
    status = cli(["batch", str(DEFAULT), "--variants", str(table), "-o", str(out), "--frames", "2", *extra])
    err = capsys.readouterr().err
    assert status == 2, err
    assert not out.exists()  # nothing was run, nothing written
    assert "Traceback" not in err
    return err


@pytest.mark.parametrize("layout", ["files", "arrays"])
def test_a_batch_larger_than_the_free_space_is_refused_before_it_starts(tmp_path, capsys, monkeypatch, layout):
    """Before: --frames 100000000 began filling the disk with the chunks' buffers (520 GB files)."""
    from warp_tube.runtime import memory

    # 1,000 variant-frames of the default scene take ~9 MB with the surface, 0.25 MB of centerline
    # points alone (arrays): say 100 kB are free
    monkeypatch.setattr(memory, "available_disk", lambda folder: 100_000)
    err = _bad(tmp_path, capsys, [E], [("100000",)] * 10, "--frames", "100", "--layout", layout)
    assert "the batch would write about" in err and "GB free in" in err and "--every K" in err
    monkeypatch.undo()
    err = _bad(tmp_path, capsys, [E], [("100000",)], "--frames", "100000000")
    assert "--frames 100000000: expected 1 to 1,000,001" in err


def test_a_time_step_too_small_to_count_is_a_bad_row(tmp_path, capsys):
    """Before: 41,666,666,667 substeps a frame wrapped the kernels' 32-bit count, and the variant
    was "ok" with nothing moving."""
    err = _bad(tmp_path, capsys, ["/World/Simulation.warptube:timeStep"], [("0.0004",), ("1e-12",)])
    assert "row 1 (line 3)" in err and "41,666,666,667 substeps a frame" in err and "at most 2,147,483,647" in err


def test_a_relationship_column_and_an_absurd_width_are_named_as_such(tmp_path, capsys):
    err = _bad(tmp_path, capsys, ["/World/Push.warptube:target"], [("/World/Nothing",)])
    assert "/World/Push.warptube:target is a relationship: a table sets attributes only" in err
    err = _bad(tmp_path, capsys, [WIDTHS], [("[1e30]",)])
    assert "row 0 (line 2)" in err and "/World/Tube.widths: found a radius of 5e+27 m" in err


def test_bad_header_and_rows(tmp_path, capsys):
    err = _bad(tmp_path, capsys, ["World/Tube.warptube:youngsModulus"], [("1",)])
    assert "line 1, column 1" in err and "PRIM_PATH.ATTRIBUTE" in err
    err = _bad(tmp_path, capsys, [E, FORCE], [("1e5", "(0, 1, 0)"), ("1e5",)])
    assert "row 1 (line 3): 1 cells for 2 columns" in err
    err = _bad(tmp_path, capsys, [E, E], [("1e5", "2e5")])
    assert "both set /World/Tube.warptube:youngsModulus" in err
    raw = tmp_path / "unquoted.csv"  # a vector cell left unquoted: its commas split it
    raw.write_text(f"{FORCE}\n(0, 0.02, 0)\n")
    assert cli(["batch", str(DEFAULT), "--variants", str(raw), "-o", str(tmp_path / "o2"), "--frames", "2"]) == 2
    err = capsys.readouterr().err
    assert '3 cells for 1 columns: a vector or array cell must be quoted (its commas split it into cells): write "(0, 0.02, 0)" in double quotes' in err


def test_bad_columns(tmp_path, capsys):
    err = _bad(tmp_path, capsys, ["/World/Nope.warptube:density"], [("1000",)])
    assert "column /World/Nope.warptube:density: no prim /World/Nope" in err
    err = _bad(tmp_path, capsys, ["/World/Tube.warptube:colour"], [("1",)])
    assert "has no attribute warptube:colour" in err


def test_bad_values_name_row_and_column(tmp_path, capsys):
    err = _bad(tmp_path, capsys, [E, FORCE], [("1e5", "(0, 1, 0)"), ("soft", "(0, 1, 0)"), ("1e5", "(0, 1)")])
    assert "row 1 (line 3), column /World/Tube.warptube:youngsModulus: found 'soft': expected a number" in err
    assert "row 2 (line 4), column /World/Push.warptube:force: found '(0, 1)': 2 number(s): expected 3 numbers" in err
    assert "2 problem(s)" in err
    # a value of the right type that the scene contract refuses: the reader's message, with row and column
    err = _bad(tmp_path, capsys, ["/World/Tube.warptube:density"], [("1050",), ("-3",)])
    assert "row 1 (line 3), column /World/Tube.warptube:density" in err and "expected a number > 0" in err
    err = _bad(tmp_path, capsys, ["/World/Push.warptube:point"], [("40",)])
    assert "row 0 (line 2), column /World/Push.warptube:point" in err and "0..20" in err


def test_bad_files_and_settings(tmp_path, capsys):
    err = _bad(tmp_path, capsys, ["@/World/Tube.points"], [("missing.npy",)])
    assert "column @/World/Tube.points" in err and "no such file" in err
    err = _bad(tmp_path, capsys, ["@/World/Tube.points"], [("p.npy",)], files={"p.npy": np.zeros((21, 2))})
    assert "shape (21, 2)" in err
    # a points array of another length than curveVertexCounts says: the reader refuses it
    err = _bad(tmp_path, capsys, ["/World/Tube.points"], [("@p.npy",)], files={"p.npy": np.zeros((5, 3))})
    assert "row 0 (line 2)" in err and "curveVertexCounts" in err
    # a timeStep no integrator accepts: a bad row, before anything runs
    err = _bad(tmp_path, capsys, ["/World/Simulation.warptube:timeStep"], [("0.001",), ("-1",)])
    assert "row 1 (line 3)" in err and "timeStep" in err


def test_bad_requests(tmp_path, capsys):
    table = write_table(tmp_path / "t.csv", [E], [("1e5",)])
    for args, expect in ((["--variant-sets", "shape"], "no such variantSet"), (["--every", "0"], "--every 0"),
                         (["--layout", "arrays", "--no-surface"], "--no-surface: only with"),
                         (["--surface-arrays"], "--surface-arrays: only with --layout arrays")):  # fmt: skip
        status = cli(["batch", str(DEFAULT), "--variants", str(table), "-o", str(tmp_path / "o"), *args])
        assert status == 2 and expect in capsys.readouterr().err
    assert cli(["batch", str(DEFAULT), "-o", str(tmp_path / "o")]) == 2
    assert "nothing to vary" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("options, expect", [
    ({"every": 1.5}, "every 1.5: expected a whole number"), ({"chunk": 2.5}, "chunk 2.5: expected a whole number"),
    ({"workers": 1.5}, "workers 1.5: expected a whole number"), ({"writers": 0.5}, "writers 0.5: expected a whole number"),
    ({"frames": "3"}, "frames '3': expected a whole number"), ({"frames": 2.5}, "frames 2.5: expected a whole number"),
    ({"frames": True}, "frames True: expected a whole number"),
])  # fmt: skip
def test_run_batch_takes_whole_numbers_as_simulation_run_does(tmp_path, options, expect):
    """Before: a TypeError deep inside (every, chunk, workers, frames='3'), or 2.5 frames run as 2
    and True as 1. A float of no fraction is that number, as for Simulation.run."""
    table = write_table(tmp_path / "t.csv", [E], [("1e5",)])
    with pytest.raises(SceneError) as e:
        run_batch(str(DEFAULT), str(tmp_path / "o"), str(table), **{"frames": 3, **options})
    assert str(e.value) == expect
    assert not (tmp_path / "o").exists()
    if "every" in options:
        result = run_batch(str(DEFAULT), str(tmp_path / "w"), str(table), layout="arrays", frames=3.0, every=2.0, chunk=1.0)
        assert result.ok == 1 and np.load(tmp_path / "w" / "centerline.npy").shape[1] == 2


def stiffness_sets_scene(tmp_path):
    """The default scene with a variantSet ``stiffness`` on /World/Tube: ``soft`` (youngsModulus
    6e4 Pa, selected) and ``stiff`` (3e5 Pa)."""
    from pxr import Sdf, Usd

    scene = tmp_path / "sets.usda"
    Sdf.Layer.FindOrOpen(str(DEFAULT)).Export(str(scene))
    st = Usd.Stage.Open(str(scene))
    # (the prim's own youngsModulus cleared: a local opinion is stronger than a variant's, and every
    # choice would give the scene's 1e5 Pa)
    st.GetPrimAtPath("/World/Tube").GetAttribute("warptube:youngsModulus").Clear()
    vset = st.GetPrimAtPath("/World/Tube").GetVariantSets().AddVariantSet("stiffness")
    for name, e in (("soft", 6e4), ("stiff", 3e5)):
        vset.AddVariant(name)
        vset.SetVariantSelection(name)
        with vset.GetVariantEditContext():
            st.GetPrimAtPath("/World/Tube").GetAttribute("warptube:youngsModulus").Set(e)
    vset.SetVariantSelection("soft")
    st.GetRootLayer().Save()
    return scene


def test_a_column_that_sets_what_a_crossed_variant_set_sets_is_warned_of(tmp_path, caplog):
    """The table's value wins in every choice of the variantSet (identical variants): said once."""
    scene = stiffness_sets_scene(tmp_path)
    from warp_tube.batch.table import read_table
    from warp_tube.batch.variants import prepare_variants

    for header, warned in (([E], True), (["/World/Tube.warptube:density"], False)):
        caplog.clear()
        table = write_table(tmp_path / "t.csv", header, [("90000",), ("95000",)] if warned else [("1000",), ("1100",)])
        with caplog.at_level("WARNING", logger="warp_tube.batch.variants"):
            assert len(prepare_variants(str(scene), read_table(str(table)), "all")) == 4
        said = [r.getMessage() for r in caplog.records if "set what variantSet" in r.getMessage()]
        assert len(said) == (1 if warned else 0), said
        if warned:
            assert E in said[0] and "/World/Tube{stiffness}" in said[0]


def test_a_variant_set_whose_choices_give_one_scene_is_warned_of(tmp_path, caplog):
    """A variantSet setting an attribute the prim also authors itself changes nothing (a local
    opinion is stronger than a variant's): its choices give the same scene, which is said once,
    naming it; a variantSet whose choices differ is not warned of."""
    from pxr import Sdf, Usd

    from warp_tube.batch.variants import prepare_variants

    working = stiffness_sets_scene(tmp_path)
    inert = tmp_path / "inert.usda"
    Sdf.Layer.FindOrOpen(str(working)).Export(str(inert))
    st = Usd.Stage.Open(str(inert))
    st.GetPrimAtPath("/World/Tube").GetAttribute("warptube:youngsModulus").Set(1e5)  # (a local opinion again)
    st.GetRootLayer().Save()
    for scene, warned in ((working, False), (inert, True)):
        caplog.clear()
        with caplog.at_level("WARNING", logger="warp_tube.batch.warned"):
            variants = prepare_variants(str(scene), None, "all")
        said = [r.getMessage() for r in caplog.records if "choices give the same scene" in r.getMessage()]
        moduli = [v.scene.tubes[0].params.youngs_modulus for v in variants.variants]
        assert moduli == ([1e5, 1e5] if warned else [6e4, 3e5])
        assert said == (["variantSet /World/Tube{stiffness}: its 2 choices give the same scene: what it sets is decided by "
                         "a stronger opinion (the attribute authored on the prim itself, or in a stronger layer), so its "
                         "variants are the same simulation"] if warned else []), said


def test_points_from_files_and_variant_sets(tmp_path):
    """A file column gives each variant its own rest shape; a scene's variantSet crossed with the
    table gives rows x variants, row-major; each equals its variant run alone."""
    from pxr import Sdf, Usd

    scene = stiffness_sets_scene(tmp_path)
    x = np.linspace(0, 20, 21)
    np.save(tmp_path / "bent.npy", np.stack([x, 0.02 * (x - 10) ** 2 - 2, 0 * x], 1))
    table = write_table(tmp_path / "t.csv", ["@/World/Tube.points"], [("bent.npy",), ("straight.csv",)])
    np.savetxt(tmp_path / "straight.csv", np.stack([x, 0 * x, 0 * x], 1), delimiter=",")
    out = tmp_path / "out"
    result = run_batch(str(scene), str(out), str(table), variant_sets="all", frames=5, writers=0)
    assert result.variants == 4 and result.ok == 4
    import csv

    rows = list(csv.DictReader(open(out / "summary.csv")))
    assert [(r["@/World/Tube.points"], r["/World/Tube{stiffness}"]) for r in rows] == [
        ("bent.npy", "soft"), ("bent.npy", "stiff"), ("straight.csv", "soft"), ("straight.csv", "stiff")]
    # variant 1: the bent shape, the stiff selection, alone
    alone_scene = tmp_path / "alone.usda"
    Sdf.Layer.FindOrOpen(str(scene)).Export(str(alone_scene))
    st = Usd.Stage.Open(str(alone_scene))
    st.GetPrimAtPath("/World/Tube").GetVariantSet("stiffness").SetVariantSelection("stiff")
    from pxr import Vt

    st.GetPrimAtPath("/World/Tube").GetAttribute("points").Set(Vt.Vec3fArray.FromNumpy(np.load(tmp_path / "bent.npy").astype(np.float32)))
    st.GetRootLayer().Save()
    alone = tmp_path / "alone.usdc"
    assert cli(["run", str(alone_scene), "-o", str(alone), "--frames", "5", "--quiet"]) == 0
    assert filecmp.cmp(alone, out / "variant_00001.usdc", shallow=False)
    # the sets named as a list, as the Python API takes them: the same variants
    listed = run_batch(str(scene), str(tmp_path / "listed"), str(table), variant_sets=["stiffness"], frames=5, writers=0)
    assert listed.variants == 4 and filecmp.cmp(tmp_path / "listed" / "variant_00001.usdc", out / "variant_00001.usdc", shallow=False)


def test_cpu_worker_processes_match_one_process(sweep, tmp_path):
    d, files_out, _, _ = sweep
    if wp.get_preferred_device().is_cuda:  # the sweep ran on the GPU: the one-process reference must be on the CPU
        files_out = tmp_path / "w1"
        run_batch(str(DEFAULT), str(files_out), str(d / "table.csv"), frames=FRAMES, device="cpu", writers=0)
    # chunk=1: five chunks through four buffer slots, so a slot's files are written again by a
    # later chunk (once the chunk before has been written)
    for chunk in (2, 1):
        out = tmp_path / f"w2_{chunk}"
        result = run_batch(str(DEFAULT), str(out), str(d / "table.csv"), frames=FRAMES, device="cpu", workers=2, chunk=chunk,
                           writers=1)  # fmt: skip
        assert result.devices == ["cpu", "cpu"] and result.ok == 5
        for k in range(5):
            # same kernels, same inputs, another process: the same bytes
            assert filecmp.cmp(files_out / f"variant_{k:05d}.usdc", out / f"variant_{k:05d}.usdc", shallow=False)


def test_cpu_worker_processes_writing_arrays_themselves_match_one_process(tmp_path):
    """With ``arrays`` each simulating process writes its own chunks (two chunks' arrays in turn,
    written while the next simulates): seven one-variant chunks through two processes give the
    bytes one process gives, and a batch interrupted after its first chunk resumes to them too."""
    table = write_table(tmp_path / "t.csv", [E, FORCE], [(str(80000 + 7000 * k), f"(0, {0.01 + 0.002 * k}, 0)") for k in range(7)])
    kw = dict(frames=5, layout="arrays", surface=True, device="cpu")
    one = tmp_path / "one"
    run_batch(str(DEFAULT), str(one), str(table), writers=0, **kw)
    two = tmp_path / "two"
    result = run_batch(str(DEFAULT), str(two), str(table), workers=2, chunk=1, **kw)
    assert result.devices == ["cpu", "cpu"] and result.ok == 7 and result.chunks == 7
    names = ["centerline.npy", "surface.npy", "summary.csv", "arrays.json"]
    for n in names:
        assert filecmp.cmp(one / n, two / n, shallow=False), n  # same kernels, same inputs: the same bytes
    cut = tmp_path / "cut"

    def stop(chunk_id):
        raise KeyboardInterrupt

    with pytest.raises(BatchInterrupted) as e:
        run_batch(str(DEFAULT), str(cut), str(table), workers=2, chunk=1, on_chunk=stop, **kw)
    assert 1 <= 7 - e.value.result.pending < 7 and not (cut / "summary.csv").exists()
    assert run_batch(str(DEFAULT), str(cut), str(table), workers=2, resume=True, **kw).ok == 7
    for n in names:
        assert filecmp.cmp(one / n, cut / n, shallow=False), n


def test_scheduler_without_dask_fails_before_writing(tmp_path, monkeypatch):
    """--scheduler where Dask is not installed: exit status 2 and no batch folder left behind
    (it would block the same command without --scheduler)."""
    import sys

    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed -> ImportError
    table = write_table(tmp_path / "t.csv", [E], [("90000",), ("95000",)])
    out = tmp_path / "out"
    with pytest.raises(SceneError, match="needs Dask distributed"):
        run_batch(str(DEFAULT), str(out), str(table), frames=3, scheduler="tcp://127.0.0.1:1")
    assert not out.exists()


@pytest.mark.parametrize("address", ["localhost", "tcp://127.0.0.1:abc", "http://127.0.0.1:8786", "", "tcp://h:99999"])
def test_a_malformed_scheduler_address_is_refused_before_anything_runs(tmp_path, capsys, address):
    """Exit status 2 naming the option and the form expected (Dask's ValueError was an internal
    error; an empty address ran here, silently)."""
    table = write_table(tmp_path / "t.csv", [E], [("90000",)])
    out = tmp_path / "out"
    args = ["batch", str(DEFAULT), "--variants", str(table), "-o", str(out), "--frames", "2", "--quiet"]
    assert cli([*args, "--scheduler", address]) == 2
    err = capsys.readouterr().err
    assert f"--scheduler {address!r}: expected" in err and "tcp://HOST:PORT" in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_a_lost_scheduler_is_one_line_and_resume_goes_on(tmp_path, monkeypatch, capsys):
    """The scheduler going away mid-batch: Dask cancels the futures (FutureCancelledError,
    scheduler-connection-lost); one line naming the scheduler, exit status 2, and --resume
    (here, without the scheduler) finishes the batch."""
    distributed = pytest.importorskip("distributed")
    from distributed.client import FutureCancelledError

    import warp_tube.batch.cluster as cluster
    import warp_tube.batch.run as batch_run

    class Done:
        def __init__(self, payload, lost):
            self.payload, self.lost = payload, lost

        def result(self):
            if self.lost:
                raise FutureCancelledError("chunk-1", "scheduler-connection-lost")
            return cluster._dask_task(self.payload)

    class Client:  # the first chunk runs here, the scheduler is lost before the second
        submitted = 0

        def submit(self, fn, payload, pure=False):
            Client.submitted += 1
            return Done(payload, Client.submitted > 1)

        def cancel(self, futures):
            pass

        def close(self):
            pass

    monkeypatch.setattr(cluster, "dask_client", lambda address: Client())
    monkeypatch.setattr(batch_run, "dask_client", lambda address: Client())
    monkeypatch.setattr(distributed, "as_completed", lambda futures: iter(futures))
    table = write_table(tmp_path / "t.csv", [E], [("90000",), ("95000",)])
    out = tmp_path / "out"
    args = ["batch", str(DEFAULT), "--variants", str(table), "-o", str(out), "--frames", "3", "--chunk", "1", "--quiet"]
    assert cli([*args, "--scheduler", "tcp://127.0.0.1:8791"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == ("warp-tube: batch: --scheduler tcp://127.0.0.1:8791: lost the connection to the Dask scheduler; "
                   "the variants finished before it are kept: --resume goes on")  # fmt: skip
    assert cli([*args, "--resume"]) == 0
    assert sorted(p.name for p in out.iterdir() if p.suffix == ".usdc") == ["variant_00000.usdc", "variant_00001.usdc"]


def test_local_dask_cluster_of_two_workers_matches_one_process(sweep, tmp_path):
    distributed = pytest.importorskip("distributed")
    d, _, _, _ = sweep
    one = tmp_path / "one"
    run_batch(str(DEFAULT), str(one), str(d / "table.csv"), frames=FRAMES, layout="arrays", surface=True, writers=0)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        out = tmp_path / "dask"
        result = run_batch(str(DEFAULT), str(out), str(d / "table.csv"), frames=FRAMES, layout="arrays", surface=True,
                           chunk=1, scheduler=cluster.scheduler_address)  # fmt: skip
        with distributed.Client(cluster.scheduler_address) as client:
            workers_used = len(client.scheduler_info()["workers"])
    assert result.ok == 5 and workers_used == 2 and result.devices[0].startswith("dask")
    for name in ("centerline.npy", "surface.npy"):
        # the same CPU kernels on the same inputs in other processes: identical arrays
        assert np.array_equal(np.load(one / name), np.load(out / name), equal_nan=True), name
    assert filecmp.cmp(one / "summary.csv", out / "summary.csv", shallow=False)


def _alone_equal(tmp_path, base_scene, overrides: dict, batch_file, frames: int):
    """Run the scene with ``overrides`` alone and compare its output with ``batch_file``, byte for byte."""
    from pxr import Sdf, Usd

    path = tmp_path / "alone_scene.usda"
    Sdf.Layer.FindOrOpen(str(base_scene)).Export(str(path))
    stage = Usd.Stage.Open(str(path))
    for target, value in overrides.items():
        prim, attr = target.rsplit(".", 1)
        a = stage.GetPrimAtPath(prim).GetAttribute(attr)
        a.Clear()
        a.Set(value)
    stage.GetRootLayer().Save()
    alone = tmp_path / "alone.usdc"
    assert cli(["run", str(path), "-o", str(alone), "--frames", str(frames), "--quiet"]) == 0
    return filecmp.cmp(alone, batch_file, shallow=False)


def test_every_feature_of_the_intestine_scene_per_world(tmp_path):
    """Curved rest shape, gravity, anchors, a time-sampled push with its assistant line, caps:
    per-world materials and anchors give each world what its variant gets alone."""
    scene = SCENES / "intestine.usda"
    header = ["/World/Bowel.warptube:anchorStiffness", "/World/Bowel.warptube:damping", "/World/Bowel.warptube:density"]
    table = write_table(tmp_path / "t.csv", header, [("60", "8", "1050"), ("120", "4", "1050"), ("30", "8", "900")])
    out = tmp_path / "out"
    result = run_batch(str(scene), str(out), str(table), frames=6, writers=0)
    assert result.ok == 3
    assert _alone_equal(tmp_path, scene, {header[0]: 120.0, header[1]: 4.0, header[2]: 1050.0}, out / "variant_00001.usdc", 6)


def test_an_axial_push_beside_an_assisted_one(tmp_path):
    """A push along the tube's axis gets no assistant line and is looked at again every frame; a
    world beside it whose line is built keeps its line's state (the low-order parts of its
    positions included) exactly as when run alone: the files are the same bytes."""
    from pxr import Gf

    table = write_table(tmp_path / "t.csv", [FORCE], [("(0.03, 0, 0)",), ("(0, 0.02, 0.01)",)])
    out = tmp_path / "out"
    result = run_batch(str(DEFAULT), str(out), str(table), frames=FRAMES, writers=0)
    assert result.ok == 2
    assert _alone_equal(tmp_path, DEFAULT, {FORCE: Gf.Vec3f(0, 0.02, 0.01)}, out / "variant_00001.usdc", FRAMES)


FRAMES_BENT = 24


def near_axis_batches(tmp_path, device: str):
    """Pushes at 6-20 degrees from the tube's axis, most inside the 15-degree cone where no line
    is built, and a side push that bends the tube away from them: eight variants run as one chunk
    and as chunks of one on ``device``. Returns the pushes, the scene, the two batch folders and
    which variants got their line after the first frame."""
    from pxr import Gf, Sdf, Usd

    stage = Usd.Stage.Open(str(DEFAULT))
    side = stage.DefinePrim("/World/Side", "Scope")
    side.CreateRelationship("warptube:target").SetTargets([Sdf.Path("/World/Tube")])
    side.CreateAttribute("warptube:point", Sdf.ValueTypeNames.Int).Set(10)
    side.CreateAttribute("warptube:force", Sdf.ValueTypeNames.Float3).Set(Gf.Vec3f(0, 0.03, 0))
    side.CreateAttribute("warptube:assistantLine", Sdf.ValueTypeNames.Bool).Set(False)
    scene = tmp_path / "side.usda"
    stage.GetRootLayer().Export(str(scene))
    angles = np.radians([6, 8, 10, 11, 12, 13, 14, 20])
    pushes = [f"({0.02 * np.cos(a):.6f}, {-0.02 * np.sin(a):.6f}, 0)" for a in angles]
    table = write_table(tmp_path / "t.csv", [FORCE], [(p,) for p in pushes])
    together, apart = tmp_path / "together", tmp_path / "apart"
    seen = []
    import warp_tube.batch.control as control

    update = control.WorldControl.update

    def spy(self, frame, state):
        update(self, frame, state)
        seen.append(self.control.al_active.numpy()[:, 0].copy())

    control.WorldControl.update = spy
    try:
        assert run_batch(str(scene), str(together), str(table), frames=FRAMES_BENT, writers=0, chunk=8, device=device).ok == 8
    finally:
        control.WorldControl.update = update
    assert run_batch(str(scene), str(apart), str(table), frames=FRAMES_BENT, writers=0, chunk=1, device=device).ok == 8
    return pushes, scene, together, apart, (seen[-1] != 0) & (seen[0] == 0)


def test_pushes_near_the_axis_get_their_lines_as_each_world_alone(tmp_path):
    """Worlds whose push is inside the cone are looked at again each frame and get their line once
    the tube has turned away: as one chunk the same bytes as each alone in its chunk (no world's
    line mixed up with another's), and two of them the bytes of a run alone."""
    from pxr import Gf

    pushes, scene, together, apart, late = near_axis_batches(tmp_path, "cpu")
    assert late.sum() >= 2, late  # the case exercises lines built after the first frame
    for k in range(8):
        name = f"variant_{k:05d}.usdc"
        assert filecmp.cmp(together / name, apart / name, shallow=False), name
    for k in np.flatnonzero(late)[:2]:
        x, y, z = (float(v) for v in pushes[k].strip("()").split(","))
        assert _alone_equal(tmp_path, scene, {FORCE: Gf.Vec3f(x, y, z)}, together / f"variant_{k:05d}.usdc", FRAMES_BENT)


def test_a_frame_that_builds_no_line_leaves_the_lines_state_as_it_is():
    """Simulation's control with two assisted pushes on one tube: one along the axis (no line,
    looked at again each frame), one across (its line built at the first frame). Updating the
    control for the next frame builds nothing, so the built line's state stays bit for bit what
    the kernels left, the low-order parts of its positions included."""
    import dataclasses

    from warp_tube import Simulation, load_scene
    from warp_tube.scene.spec import ForceSpec

    scene = load_scene(str(DEFAULT))
    push = scene.forces[0]
    forces = (
        dataclasses.replace(push, times=np.zeros(1), values=np.array([[0.0, 0.03, 0.01]])),
        ForceSpec(path="/World/Along", tube=push.tube, point=8, times=np.zeros(1), values=np.array([[0.02, 0.0, 0.0]])),
    )
    sim = Simulation(dataclasses.replace(scene, forces=forces), device="cpu", surface=False)
    sim.step()
    sim.step()
    before = [a.numpy().copy() for a in (sim.state.al_q, sim.state.al_q_lo, sim.state.al_qd)]
    assert np.abs(before[1]).max() > 0  # the line's positions carry a low-order part
    sim.controls.update(2, sim.state)
    after = [a.numpy() for a in (sim.state.al_q, sim.state.al_q_lo, sim.state.al_qd)]
    for x, y in zip(before, after):
        np.testing.assert_array_equal(x, y)


def test_several_prims_and_curves_per_variant(tmp_path):
    from warp_tube.scene.spec import ForceSpec, Scene, StageInfo, TubeParams, TubeSpec
    from warp_tube.scene.usd import save_scene

    x = np.linspace(0.0, 0.2, 12)
    line = np.stack([x, 0 * x, 0 * x], 1)
    a = TubeSpec("/World/A", np.concatenate([line, line + [0, 0.1, 0]]), [12, 12], np.full(24, 0.01),
                 TubeParams(density=1000.0, youngs_modulus=2e5, damping=3.0, spokes=8), pinned=[0, 1, 12, 13])  # fmt: skip
    b = TubeSpec("/World/B", line + [0, 0, 0.1], [12], np.full(12, 0.008), TubeParams(density=1100.0, youngs_modulus=1e5, spokes=6, caps=True),
                 pinned=[0])  # fmt: skip
    pushes = (ForceSpec("/World/PushA", 0, 20, [0.0, 0.1], [[0, 0, 0], [0, 0.05, 0]]), ForceSpec("/World/PushB", 1, 11, [0.0], [[0, 0, 0.03]], False))
    scene = tmp_path / "two.usda"
    save_scene(Scene((a, b), pushes, stage=StageInfo(meters_per_unit=1.0, time_codes_per_second=30, frames_per_second=30,
                                                     end_time_code=10)), str(scene))  # fmt: skip
    table = write_table(tmp_path / "t.csv", ["/World/B.warptube:youngsModulus", "/World/PushA.warptube:force"],
                        [("100000", "(0, 0.05, 0)"), ("300000", "(0, 0.02, 0.04)"), ("100000", "(0.01, 0.03, 0)")])  # fmt: skip
    out = tmp_path / "out"
    from pxr import Gf

    assert run_batch(str(scene), str(out), str(table), frames=6, writers=0).ok == 3
    assert _alone_equal(tmp_path, scene, {"/World/B.warptube:youngsModulus": 1e5, "/World/PushA.warptube:force": Gf.Vec3f(0.01, 0.03, 0)},
                        out / "variant_00002.usdc", 6)  # fmt: skip


def test_run_choices_are_what_simulation_chooses():
    """The batch groups variants by the integrator and substeps each gets alone: the same as
    Simulation's own choice, for scenes of several layouts and stiffnesses at once."""
    import dataclasses

    from warp_tube import load_scene
    from warp_tube.batch.plan import run_choices
    from warp_tube.sim.simulation import Simulation

    scenes = []
    for name in ("default.usda", "intestine.usda", "cantilever.usda"):
        base = load_scene(SCENES / name)
        for e in (2e4, 1e5, 5e6):
            t = base.tubes[0]
            scenes.append(dataclasses.replace(base, tubes=(dataclasses.replace(t, params=dataclasses.replace(t.params, youngs_modulus=e)),)
                                              + base.tubes[1:]))  # fmt: skip
    choices = run_choices(scenes)
    for s, c in zip(scenes, choices):
        sim = Simulation(s, device="cpu", surface=False)
        assert (c.integrator, c.substeps, c.reason) == (sim.integrator, sim.substeps, sim.reason)


def test_run_choices_with_lines_placed_on_other_tubes():
    """Scenes of one node layout whose pushes (with assistant lines) sit on other tubes: two lines
    on one tube in one scene, one on each tube in the other. Each scene's stability bound counts
    its own lines (planned together, they must not take each other's): the choices Simulation
    makes for each alone."""
    from warp_tube.batch.plan import run_choices
    from warp_tube.scene.spec import ForceSpec, Scene, SimulationSettings, TubeParams, TubeSpec
    from warp_tube.sim.simulation import Simulation

    params = TubeParams(density=1000.0, youngs_modulus=2e6, damping=1.0)
    pts = np.stack([np.linspace(0.0, 0.3, 16), np.zeros(16), np.zeros(16)], axis=1)
    tubes = tuple(TubeSpec(f"/T{k}", pts + (0.0, 0.1 * k, 0.0), [16], np.full(16, 0.01), params, pinned=[0, 1]) for k in range(2))

    def push(name, tube, point):
        return ForceSpec(name, tube, point, np.zeros(1), np.array([[0.0, 0.0, 0.01]]), assistant_line=True)

    both_on_one = Scene(tubes, (push("/A", 0, 8), push("/B", 0, 12)), SimulationSettings())
    one_each = Scene(tubes, (push("/A", 0, 8), push("/B", 1, 12)), SimulationSettings())
    for order in ((both_on_one, one_each), (one_each, both_on_one)):
        for s, c in zip(order, run_choices(list(order))):
            sim = Simulation(s, device="cpu", surface=False)
            assert (c.integrator, c.substeps, c.reason) == (sim.integrator, sim.substeps, sim.reason)


def test_a_large_table_read_by_several_processes(sweep, tmp_path, monkeypatch, capsys):
    """Reading split over processes (as for a large table on a many-core host) gives the same
    batch, and problems from every part, in row order."""
    import warp_tube.batch.prepare as prepare

    monkeypatch.setattr(prepare, "PREPARE_ROWS_PER_PROCESS", 2)
    monkeypatch.setattr(prepare, "PLAIN_ROWS_FACTOR", 1)  # plain rows too: split at 2 rows a process
    monkeypatch.setattr(prepare.os, "cpu_count", lambda: 2)
    d, files_out, _, _ = sweep
    out = tmp_path / "split"
    assert run_batch(str(DEFAULT), str(out), str(d / "table.csv"), frames=FRAMES, writers=0).ok == 5
    for k in range(5):
        assert filecmp.cmp(files_out / f"variant_{k:05d}.usdc", out / f"variant_{k:05d}.usdc", shallow=False)
    assert filecmp.cmp(files_out / "summary.csv", out / "summary.csv", shallow=False)
    # read by the batch's writer processes (started first, idle until a chunk is simulated)
    by_writers = tmp_path / "by_writers"
    assert run_batch(str(DEFAULT), str(by_writers), str(d / "table.csv"), frames=FRAMES, writers=2).ok == 5
    for name in [f"variant_{k:05d}.usdc" for k in range(5)] + ["summary.csv"]:
        assert filecmp.cmp(files_out / name, by_writers / name, shallow=False), name
    table = write_table(tmp_path / "bad.csv", [E], [("1e5",), ("x",), ("1e5",), ("2e5",), ("-1",)])
    status = cli(["batch", str(DEFAULT), "--variants", str(table), "-o", str(tmp_path / "bad"), "--frames", "2"])
    err = capsys.readouterr().err
    assert status == 2 and "2 problem(s)" in err
    assert err.index("row 1 (line 3)") < err.index("row 4 (line 6)")


def test_ctrl_c_keeps_finished_variants_and_resume_completes(tmp_path):
    """A real SIGINT to the command: exit status 130, finished variants kept, --resume completes
    the batch with the same files as an uninterrupted one."""
    import signal
    import subprocess
    import sys
    import time

    table = write_table(tmp_path / "t.csv", [E, FORCE], [(str(80000 + 3000 * k), f"(0, {0.01 + 0.001 * k}, 0)") for k in range(12)])
    args = ["batch", str(DEFAULT), "--variants", str(table), "--frames", "15", "--chunk", "1", "--quiet"]
    cut = tmp_path / "cut"
    proc = subprocess.Popen([sys.executable, "-m", "warp_tube", *args, "-o", str(cut)], stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))  # fmt: skip
    deadline = time.time() + 300
    while not (cut / "variant_00001.usdc").exists() and proc.poll() is None and time.time() < deadline:
        time.sleep(0.05)
    proc.send_signal(signal.SIGINT)
    err = proc.communicate(timeout=300)[1]
    assert proc.returncode == 130, err
    assert "--resume goes on" in err and (cut / ".batch").is_dir()
    assert cli([*args, "-o", str(cut), "--resume"]) == 0
    whole = tmp_path / "whole"
    assert cli([*args, "-o", str(whole)]) == 0
    names = sorted(p.name for p in whole.iterdir())
    assert names == sorted(p.name for p in cut.iterdir())
    for n in names:
        assert filecmp.cmp(whole / n, cut / n, shallow=False), n


def test_a_scene_warning_is_given_once_not_per_variant(tmp_path, caplog):
    from warp_tube.batch.table import read_table
    from warp_tube.batch.variants import prepare_variants

    table = write_table(tmp_path / "t.csv", [E, "/World/Push.warptube:point"], [(str(9e4 + k), "1") for k in range(4)])
    with caplog.at_level("WARNING", logger="warp_tube.scene.usd"):
        variants = prepare_variants(str(DEFAULT), read_table(str(table)))
    assert len(variants) == 4
    pinned = [r.getMessage() for r in caplog.records if "is pinned" in r.getMessage()]
    assert len(pinned) == 1  # point 1 is pinned in all four: one warning
    # naming the first row that gave it and how many others did (before: no row)
    assert pinned[0].startswith(f"{table}: row 0 (line 2), column /World/Push.warptube:point, and 3 other row(s): ")


def test_a_rows_warning_names_the_first_row_across_processes_reading_parts(tmp_path, monkeypatch, caplog):
    """Rows read by several processes: their warnings are said once by the batch, naming the first
    row and counting every part's rows (a row equal to an earlier one too)."""
    import warp_tube.batch.prepare as prepare

    monkeypatch.setattr(prepare, "PREPARE_ROWS_PER_PROCESS", 2)
    monkeypatch.setattr(prepare.os, "cpu_count", lambda: 2)
    rows = [("9e4", "15"), ("9.1e4", "1"), ("9.2e4", "15"), ("9.3e4", "1"), ("9.1e4", "1")]
    table = write_table(tmp_path / "t.csv", [E, "/World/Push.warptube:point"], rows)
    with caplog.at_level("WARNING"):
        assert run_batch(str(DEFAULT), str(tmp_path / "o"), str(table), layout="arrays", frames=2, writers=0).ok == 5
    pinned = [r.getMessage() for r in caplog.records if "is pinned" in r.getMessage()]
    assert pinned == [f"{table}: row 1 (line 3), column /World/Push.warptube:point, and 2 other row(s): {DEFAULT}: "
                      "/World/Push.warptube:point: point 1 of /World/Tube is pinned: this force does nothing"], pinned


def test_critical_time_steps_of_many_parts_equal_each_part_alone():
    """The batch plans every variant's stability bound from one launch over the group's model; each
    part's bound must be the one its own nodes give (same float64 row sums: equal to 1e-12)."""
    from types import SimpleNamespace

    from warp_tube import load_scene
    from warp_tube.batch.worlds import combined_tubes
    from warp_tube.centerline.stability import critical_time_step, critical_time_steps
    from warp_tube.model.tube import build_model, node_parameters

    base = load_scene(str(DEFAULT))
    scenes = []
    for e, d in ((1e5, 0.0), (4e5, 0.0), (2.5e4, 0.3)):
        t = base.tubes[0]
        scenes.append(replace(base, tubes=(replace(t, params=replace(t.params, youngs_modulus=e, spring_damping=d)),)))
    # as the planner builds it: every part's per-node parameters, with one part's topology
    per_node, _ = node_parameters(combined_tubes(scenes))
    h = SimpleNamespace(**per_node, tube_al_force=build_model(scenes[0], world_count=1, device="cpu").host.tube_al_force)
    n = len(h.node_mass) // 3
    damping = np.array([s.tubes[0].params.spring_damping for s in scenes])
    many = critical_time_steps(h, 3, True, damping)
    for k in range(3):
        own = {name: getattr(h, name)[k * n : (k + 1) * n] for name in ("seg_ke", "seg_rest_length", "node_bend_k", "node_anchor_k", "node_inv_mass")}
        own["tube_node_start"] = np.array([0, n])
        alone = build_model(scenes[k], world_count=1, device="cpu").host
        assert np.allclose(own["seg_ke"], alone.seg_ke)  # the slice is the part's own model
        assert many[k] == pytest.approx(critical_time_step(alone, True, damping[k]), rel=1e-12)
    assert len(set(np.round(many, 12))) == 3  # the three stiffnesses give three bounds


def test_a_script_piped_to_python_reads_its_table_in_one_process(sweep, tmp_path):
    """Processes started by spawn cannot import a main module read from stdin; the table is read in
    the batch's own process (no process is started to fail first), and the batch completes."""
    import subprocess
    import sys

    d, files_out, _, _ = sweep
    out = tmp_path / "piped"
    script = f"""
import warp_tube.batch.prepare as prepare
prepare.PREPARE_ROWS_PER_PROCESS = 2
prepare.os.cpu_count = lambda: 2
from warp_tube.batch import run_batch
r = run_batch({str(DEFAULT)!r}, {str(out)!r}, {str(d / "table.csv")!r}, frames={FRAMES}, device="cpu", writers=0)
print("ok", r.ok)
"""
    p = subprocess.run([sys.executable, "-"], input=script, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr[-2000:]
    assert "ok 5" in p.stdout and "Traceback" not in p.stderr and "FileNotFoundError" not in p.stderr, p.stderr[-2000:]
    for k in range(5):
        assert filecmp.cmp(files_out / f"variant_{k:05d}.usdc", out / f"variant_{k:05d}.usdc", shallow=False)


@pytest.mark.parametrize("block_bytes", [1 << 30, 3 * 4 * 3 * 5 * 4 + 1])
def test_arrays_written_in_blocks_of_variants_that_follow_one_another(tmp_path, monkeypatch, block_bytes):
    """The arrays layout writes each run of variants consecutive in the batch and in the chunk with
    one copy and one write: runs broken by gaps in the batch's indices, by the chunk's order and by
    the block size (the second case: at most 4 variants a block) land at their rows, each
    variant's frames copied exactly and padded with NaN past its points."""
    import warp_tube.batch.outputs as outputs

    monkeypatch.setattr(outputs, "ARRAY_BLOCK_BYTES", block_bytes)
    F, W, m, n = 3, 9, 4, 5  # frames, worlds in the chunk, the chunk's points, the batch's most points
    spec = outputs.OutputSpec(layout="arrays", out_dir=str(tmp_path), surface=False, time_codes=(0.0, 1.0, 2.0), variants=14,
                              points=n, work_dir=str(tmp_path))  # fmt: skip
    outputs.prepare_arrays(spec, resume=False)
    chunk = np.random.default_rng(0).normal(size=(F, W, m, 3)).astype(np.float32)
    indices = [0, 1, 2, 3, 4, 5, 8, 9, 13]  # a gap after 5 and after 9
    positions = [0, 1, 2, 3, 4, 5, 6, 8, 7]  # the last two swapped in the chunk
    task = outputs.WriteTask(spec=spec, chunk=0, variants=tuple((i, f"v{i}", None) for i in indices), positions=tuple(positions),
                             rows=(), arrays={"centerline": chunk})  # fmt: skip
    assert outputs.write(task) == ["centerline.npy"] * W
    got = np.load(tmp_path / "centerline.npy")
    for i, p in zip(indices, positions):
        assert np.array_equal(got[i, :, :m], chunk[:, p]) and np.isnan(got[i, :, m:]).all(), i
    untouched = sorted(set(range(14)) - set(indices))
    assert not got[untouched].any()  # rows of other chunks: not written here (still the file's zeros)


def _straight_tube(name: str, y: float) -> str:
    """A pinned straight tube prim of 11 points along x at height ``y`` [m], radius 1 cm."""
    points = ", ".join(f"({0.02 * k:.2f}, {y}, 0)" for k in range(11))
    return f"""
    def BasisCurves "{name}"
    {{
        uniform token type = "linear"
        int[] curveVertexCounts = [11]
        point3f[] points = [{points}]
        float[] widths = [0.02] (interpolation = "constant")
        double warptube:youngsModulus = 200000
        double warptube:density = 1000
        double warptube:damping = 4
        int[] warptube:pinnedPoints = [0, 10]
    }}
"""


TWO_TUBES = (
    """#usda 1.0
(
    defaultPrim = "World"
    metersPerUnit = 1
    upAxis = "Y"
    timeCodesPerSecond = 24
    framesPerSecond = 24
    startTimeCode = 0
    endTimeCode = 24
)

def Xform "World"
{"""
    + _straight_tube("A", 0.0)
    + _straight_tube("B", 0.03)
    + """
    def Scope "Push"
    {
        rel warptube:target = </World/A>
        int warptube:point = 5
        float3 warptube:force = (0, 0.05, 0)
    }
}
"""
)


@pytest.mark.parametrize("pairs_max", [None, 4])
def test_batch_records_the_frame_distant_parts_first_touch(tmp_path, monkeypatch, pairs_max):
    """Two parallel tubes 1 cm apart (surface to surface), one pushed towards the other: with
    the stronger pushes they touch (contact is not modelled: they pass through each other), with
    the weak one they never do. The summary's contact_frame of each variant is the frame at which
    Simulation alone first warns of it (the same test on the same positions), empty where it
    never does; with every pair of a world tested (22 points) and through the hash grid."""
    import csv

    import warp_tube.batch.contacts as contacts

    if pairs_max is not None:
        monkeypatch.setattr(contacts, "PAIRS_MAX", pairs_max)

    from warp_tube.batch.table import read_table
    from warp_tube.batch.variants import prepare_variants
    from warp_tube.sim.simulation import Simulation

    scene = tmp_path / "two.usda"
    scene.write_text(TWO_TUBES)
    table = write_table(tmp_path / "t.csv", ["/World/Push.warptube:force"], [("(0, 0.002, 0)",), ("(0, 0.6, 0)",), ("(0, 1.5, 0)",)])
    out = tmp_path / "out"
    result = run_batch(str(scene), str(out), str(table), frames=24, layout="arrays", writers=0)
    assert result.ok == 3
    with open(out / "summary.csv", newline="") as f:
        got = [r["contact_frame"] for r in csv.DictReader(f)]
    alone = []
    for v in prepare_variants(str(scene), read_table(str(table))).variants:
        sim = Simulation(v.scene, device="cpu", surface=False)
        for _ in range(23):
            sim.step()
        alone.append("" if sim.contact_frame is None else str(sim.contact_frame))
    assert got == alone
    assert alone[0] == "" and alone[1] != "" and alone[2] != "" and int(alone[2]) <= int(alone[1])
    assert result.contacts == [("variant_00001", int(alone[1])), ("variant_00002", int(alone[2]))]
    assert "contact      2 variant(s)" in result.text()


def test_cpu_workers_beyond_the_cores_are_capped_with_a_warning(monkeypatch, caplog):
    """Each CPU worker runs one thread: more workers than cores only compete for them."""
    import warp_tube.batch.result as result
    import warp_tube.batch.run as run

    monkeypatch.setattr(run.os, "sched_getaffinity", lambda pid: {0, 1}, raising=False)
    with caplog.at_level("WARNING"):
        devices = run._devices("cpu", 64, None)
    assert devices == ["cpu", "cpu"]
    assert "--workers 64: this host gives this process 2 CPU core(s); running 2 worker(s)" in caplog.text
    assert run._devices("cpu", 2, None) == ["cpu", "cpu"] and run._devices("cpu", None, None) == ["cpu"]
    assert result._device_list(devices) == "cpu x 2" and result._device_list(["cuda:0", "cuda:1"]) == "cuda:0, cuda:1"


def test_points_of_another_count_name_their_column(tmp_path, capsys):
    """A points file with fewer points than the scene's curveVertexCounts: the message names the
    points column (not only the scene's curveVertexCounts) and says to set the counts too."""
    x = np.linspace(0.0, 20.0, 15)
    err = _bad(tmp_path, capsys, ["@/World/Tube.points"], [("short.npy",)], files={"short.npy": np.stack([x, 0 * x, 0 * x], 1)})
    assert "column @/World/Tube.points" in err and "summing to the 15 points" in err
    assert "set /World/Tube.curveVertexCounts in the table too" in err


def failing_world_among_others(tmp_path, scene, tube, device):
    """A batch of three variants with one forced substep, beyond the middle (stiff) one's
    stability bound: it fails, and the frames of the other two equal their runs alone."""
    import csv

    from pxr import Sdf, Usd

    E_ = f"{tube}.warptube:youngsModulus"
    cols = [E_, "/World/Simulation.warptube:integrator", "/World/Simulation.warptube:timeStep"]
    table = write_table(tmp_path / "t.csv", cols, [("100000", "semiImplicitEuler", "0.0002"), ("50000000", "semiImplicitEuler", "0.0002"),
                                                   ("80000", "semiImplicitEuler", "0.0002")])  # fmt: skip
    out = tmp_path / "out"
    result = run_batch(str(scene), str(out), str(table), frames=8, device=device, writers=1, layout="arrays", surface=True)
    assert result.variants == 3 and result.failed == 1, result.failures
    rows = list(csv.DictReader(open(out / "summary.csv", encoding="utf-8")))
    assert [r["status"] for r in rows] == ["ok", "failed", "ok"]
    centerline = np.load(out / "centerline.npy")  # (variants, frames, points, 3), stage units
    for k, e in ((0, 100000.0), (2, 80000.0)):
        path = variant_scene(tmp_path, f"v{k}", {E_: e, "/World/Simulation.warptube:integrator": "semiImplicitEuler"}, base=scene)
        st = Usd.Stage.Open(str(path))
        st.GetPrimAtPath("/World/Simulation").CreateAttribute("warptube:timeStep", Sdf.ValueTypeNames.Double).Set(0.0002)
        st.GetRootLayer().Save()
        alone = tmp_path / f"alone{k}.usdc"
        assert cli(["run", str(path), "-o", str(alone), "--frames", "8", "--device", device, "--quiet"]) == 0
        (times, frames_alone), = [v for n, v in stage_samples(alone).items() if n.endswith("Centerline.points")]
        ref = np.stack(frames_alone)
        # the same kernels on the same float32 inputs: float32 round-off at most (on a GPU its
        # fast-math surface kernels alike in both), 2e-5 of the ~20-unit tube (~16 ulps)
        assert ref.shape == centerline[k].shape and np.abs(centerline[k] - ref).max() <= 2e-5


def test_a_failing_world_among_others_with_the_contact_grid(tmp_path):
    """As test_failed_variant_is_marked_and_the_others_go_on, for a tube of 41 points: its
    worlds' contact test queries a grid, which holds the failed world's blown-up points for the
    frame queued after its failure."""
    failing_world_among_others(tmp_path, DEFAULT.parent / "intestine.usda", "/World/Bowel", "cpu")
