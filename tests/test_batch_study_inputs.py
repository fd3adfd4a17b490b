"""A batch as a parameter study uses it: inputs that sit where the batch writes, the Python API
called from a script without ``if __name__ == "__main__":``, and a bad cell crossed with
variantSets."""

import multiprocessing
import os
from pathlib import Path

import pytest

from warp_tube.batch import run_batch
from warp_tube import load_scene
from warp_tube.scene.spec import SceneError

DEFAULT = Path(__file__).resolve().parents[1] / "scenes" / "default.usda"


def scene_with_sublayer(tmp_path: Path, layer: Path) -> Path:
    """The default scene with ``layer`` (a damping override) as a sublayer, written as
    ``tmp_path/scene.usda``."""
    from pxr import Sdf, Usd

    layer.parent.mkdir(parents=True, exist_ok=True)
    sub = Sdf.Layer.CreateNew(str(layer))
    stage = Usd.Stage.Open(sub)
    stage.OverridePrim("/World/Tube").CreateAttribute("warptube:damping", Sdf.ValueTypeNames.Double).Set(3.0)
    sub.Save()
    text = DEFAULT.read_text().replace("endTimeCode = 96\n", f"endTimeCode = 96\n    subLayers = [@{layer}@]\n", 1)
    scene = tmp_path / "scene.usda"
    scene.write_text(text)
    return scene


def test_a_scene_layer_where_the_grid_writes_its_chunks_is_refused_and_left_as_it_was(tmp_path):
    """A layer the scene uses, at ``DIR/grid/chunk_00000.usdc``, is refused before anything is
    written (it would be replaced by the grid's first chunk)."""
    out = tmp_path / "out"
    layer = out / "grid" / "chunk_00000.usdc"
    scene = scene_with_sublayer(tmp_path, layer)
    before = layer.read_bytes()
    table = tmp_path / "t.csv"
    table.write_text("/World/Tube.warptube:youngsModulus\n100000\n")
    with pytest.raises(SceneError, match=r"a layer or asset the scene uses is in .* under a name the batch writes there \(chunk_00000\.usdc\)"):
        run_batch(str(scene), str(out), str(table), layout="grid", frames=2)
    assert layer.read_bytes() == before
    assert sorted(os.listdir(out)) == ["grid"] and os.listdir(out / "grid") == ["chunk_00000.usdc"]


def test_a_scene_layer_named_as_a_variant_output_is_named_as_an_input_not_a_batch(tmp_path):
    """A layer the scene uses, at ``DIR/variant_00001.usdc``, is named as an input of the batch
    (not as an earlier batch's output that ``--resume`` would continue)."""
    out = tmp_path / "out"
    layer = out / "variant_00001.usdc"
    scene = scene_with_sublayer(tmp_path, layer)
    table = tmp_path / "t.csv"
    table.write_text("/World/Tube.warptube:youngsModulus\n100000\n200000\n")
    for resume in (False, True):
        with pytest.raises(SceneError, match=r"a layer or asset the scene uses .*\(variant_00001\.usdc\)"):
            run_batch(str(scene), str(out), str(table), frames=2, resume=resume)
    assert sorted(os.listdir(out)) == ["variant_00001.usdc"]


def test_a_file_the_table_names_where_the_arrays_are_written_is_named_as_an_input(tmp_path):
    """A points file the table names (``@``), at ``DIR/centerline.npy``, is refused as an input
    in the folder, and left as it was."""
    np = pytest.importorskip("numpy")
    out = tmp_path / "out"
    out.mkdir()
    points = out / "centerline.npy"
    np.save(points, np.array([(i, 0.0, 0.0) for i in range(21)], dtype=np.float32))
    before = points.read_bytes()
    table = out / "t.csv"
    table.write_text("@/World/Tube.points\ncenterline.npy\n")
    with pytest.raises(SceneError, match=r"a file the table names is in .*\(centerline\.npy\)"):
        run_batch(str(DEFAULT), str(out), str(table), layout="arrays", frames=2)
    assert points.read_bytes() == before
    assert sorted(os.listdir(out)) == ["centerline.npy", "t.csv"]


def test_a_call_made_while_a_spawned_process_imports_the_main_module_is_refused(tmp_path, monkeypatch):
    """``run_batch`` at the top level of a script, without ``if __name__ == "__main__":``, runs
    again in every process the batch spawns, while that process starts: refused there with the
    reason (not as "another batch is writing there"), nothing written."""
    monkeypatch.setattr(multiprocessing.current_process(), "_inheriting", True, raising=False)
    table = tmp_path / "t.csv"
    table.write_text("/World/Tube.warptube:youngsModulus\n100000\n")
    out = tmp_path / "out"
    with pytest.raises(SceneError, match=r'if __name__ == "__main__":'):
        run_batch(str(DEFAULT), str(out), str(table), frames=2)
    assert not out.exists()


def default_with_variant_set(folder, attribute: str, type_name: str, name: str, choices: dict, selected: bool = True) -> Path:
    """The default scene, its tube's ``attribute`` authored in a variantSet ``name`` instead
    (``choices``: variant -> value; the last one selected, or none), written into ``folder``.
    Edited in a copy: the layer usd-core keeps of the scene itself stays as it is for the other tests."""
    import shutil

    from pxr import Sdf, Usd

    stage = Usd.Stage.Open(str(shutil.copy(DEFAULT, Path(folder) / "default_copy.usda")))
    tube = stage.GetPrimAtPath("/World/Tube")
    tube.RemoveProperty(attribute)
    vset = tube.GetVariantSets().AddVariantSet(name)
    for choice, value in choices.items():
        vset.AddVariant(choice)
        vset.SetVariantSelection(choice)
        with vset.GetVariantEditContext():
            tube.CreateAttribute(attribute, getattr(Sdf.ValueTypeNames, type_name)).Set(value)
    if not selected:
        vset.ClearVariantSelection()
    scene = Path(folder) / "vs.usda"
    stage.GetRootLayer().Export(str(scene))
    return scene


def test_a_bad_cell_crossed_with_variant_sets_is_reported_once(tmp_path):
    """A cell that cannot be read is the same problem in every variantSet combination: one line."""
    scene = default_with_variant_set(tmp_path, "warptube:damping", "Double", "damping", {"low": 1.0, "high": 4.0})
    table = tmp_path / "t.csv"
    table.write_text("/World/Tube.warptube:youngsModulus\n100000\n1e5 Pa\n")
    out = tmp_path / "out"
    with pytest.raises(SceneError) as info:
        run_batch(str(scene), str(out), str(table), variant_sets="all", frames=2)
    text = str(info.value)
    assert text.startswith("1 problem(s)")
    assert text.count("row 1 (line 3), column /World/Tube.warptube:youngsModulus") == 1
    assert not out.exists()


def test_variant_sets_without_a_default_selection_expand(tmp_path):
    """A variantSet that authors the tube's widths and has no default selection: the scene as it
    is lacks widths, but every combination ``--variant-sets`` makes is whole, so the batch runs
    them all (a scene read without the option is still refused)."""
    scene = default_with_variant_set(tmp_path, "widths", "FloatArray", "shape", {"thin": [1.0], "thick": [3.0]}, selected=False)
    with pytest.raises(SceneError, match="widths: missing"):
        load_scene(str(scene))
    result = run_batch(str(scene), str(tmp_path / "out"), variant_sets="all", frames=2, surface=False)
    assert result.ok == 2
    summary = (tmp_path / "out" / "summary.csv").read_text()
    assert ",thin," in summary and ",thick," in summary


def test_resuming_a_finished_batch_whose_output_was_deleted_warns_naming_it(tmp_path, caplog):
    """``--resume`` of a finished batch writes nothing again; an output deleted since is named in
    a warning rather than passed over as finished."""
    table = tmp_path / "t.csv"
    table.write_text("/World/Tube.warptube:youngsModulus\n100000\n200000\n")
    out = tmp_path / "out"
    assert run_batch(str(DEFAULT), str(out), str(table), frames=2, surface=False).ok == 2
    (out / "variant_00001.usdc").unlink()
    caplog.clear()
    with caplog.at_level("WARNING"):
        result = run_batch(str(DEFAULT), str(out), str(table), frames=2, surface=False, resume=True)
    assert result.resumed == 2
    warned = [r.getMessage() for r in caplog.records if r.levelname == "WARNING"]
    assert any("variant_00001.usdc" in m and "missing" in m for m in warned), warned
    assert not (out / "variant_00001.usdc").exists()


def test_a_column_for_a_prim_the_scene_does_not_have_names_the_scenes_prims(tmp_path):
    # /World/Tube is the default scene's tube; the intestine's is /World/Bowel (too far apart for
    # a did-you-mean): the message lists the prims a column can set.
    table = tmp_path / "t.csv"
    table.write_text("/World/Tube.warptube:youngsModulus\n20000\n")
    scene = Path(__file__).resolve().parents[1] / "scenes" / "intestine.usda"
    with pytest.raises(SceneError, match=r"no prim /World/Tube in .*\(the scene's warp_tube prims: .*/World/Bowel, /World/Push\)"):
        run_batch(str(scene), str(tmp_path / "out"), str(table), frames=2)
    assert not (tmp_path / "out").exists()


def test_a_large_arrays_batch_on_the_cpu_runs_a_worker_on_each_core(tmp_path):
    """Without ``--workers``, a CPU batch written as arrays with at least 512 table rows a core
    runs a simulating process on each core; files and a grid, or a smaller table, one."""
    from warp_tube.batch import run as batch_run

    class Rows:
        def __init__(self, n):
            self.rows = [()] * n

    assert batch_run._default_cpu_workers("arrays", Rows(1024)) == 2
    assert batch_run._default_cpu_workers("arrays", Rows(1023)) == 1
    assert batch_run._default_cpu_workers("files", Rows(100_000)) == 1
    assert batch_run._default_cpu_workers("arrays", None) == 1
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    assert batch_run._cpu_workers(None, 64) == min(64, cores)  # (at most one a core)
    assert batch_run._cpu_workers(None) == 1 and batch_run._cpu_workers(1, 64) == 1
