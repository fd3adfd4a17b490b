"""A chunk makes the surface outputs its layout writes (warp_tube/batch/engine.py): the arrays
layout writes the surface's points alone, so its chunks neither store nor copy back normals and
extents, and the points they give are those of a chunk that makes all three."""

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from warp_tube import load_scene
from warp_tube.batch import engine, execute, run_batch
from warp_tube.batch.engine import SURFACE_OUTPUTS, chunk_shapes, simulate_chunk, surface_outputs
from warp_tube.batch.plan import run_choices

SCENES = Path(__file__).resolve().parents[1] / "scenes"


def _chunk(moduli):
    base = load_scene(SCENES / "default.usda")
    t = base.tubes[0]
    return [dataclasses.replace(base, tubes=(dataclasses.replace(t, params=dataclasses.replace(t.params, youngs_modulus=e)),))
            for e in moduli]  # fmt: skip


def test_surface_outputs_names_what_is_asked_for():
    assert surface_outputs(True) == SURFACE_OUTPUTS
    assert surface_outputs(False) == surface_outputs(()) == ()
    assert surface_outputs(("extent", "points")) == ("points", "extent")  # (in their own order)
    with pytest.raises(ValueError, match="colours"):
        surface_outputs(("points", "colours"))
    scenes = _chunk([2e4, 3e4])
    n = len(scenes[0].tubes[0].points)
    shapes = chunk_shapes(scenes, frames=5, every=2, surface=("points",), vertex_count=7)  # frames 0, 2, 4
    assert shapes == {"centerline": (3, 2, n, 3), "points": (3, 2, 7, 3)}


def test_a_chunk_of_the_points_alone_gives_the_points_of_a_whole_surface():
    scenes = _chunk([2e4, 5e4])
    choice = run_choices(scenes)[0]
    whole = simulate_chunk(scenes, choice, "cpu", frames=4, every=1, surface=True)
    points = simulate_chunk(scenes, choice, "cpu", frames=4, every=1, surface=("points",))
    whole.ready.result()
    points.ready.result()
    assert set(whole.arrays) == {"centerline", *SURFACE_OUTPUTS}
    assert set(points.arrays) == {"centerline", "points"}  # no normals or extents stored
    # The same kernels on the same states: equal to the bit.
    np.testing.assert_array_equal(points.arrays["points"], whole.arrays["points"])
    np.testing.assert_array_equal(points.arrays["centerline"], whole.arrays["centerline"])
    assert np.isfinite(points.arrays["points"]).all()


@pytest.mark.parametrize("layout, parts", [("arrays", ("points",)), ("files", SURFACE_OUTPUTS)])
def test_each_layout_asks_its_chunks_for_the_surface_it_writes(tmp_path, monkeypatch, layout, parts):
    asked = []

    def recording(scenes, choice, device, frames, every, surface, **kw):
        asked.append(surface)
        return engine.simulate_chunk(scenes, choice, device, frames, every, surface, **kw)

    monkeypatch.setattr(execute, "simulate_chunk", recording)
    table = tmp_path / "v.csv"
    table.write_text("/World/Tube.warptube:youngsModulus\n20000\n40000\n")
    run_batch(str(SCENES / "default.usda"), str(tmp_path / "out"), str(table), frames=3, layout=layout, surface=True,
              writers=0, workers=1)  # fmt: skip
    assert asked and all(tuple(s) == parts for s in asked)
