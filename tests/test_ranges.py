"""The physical ranges of the scene's real-valued quantities (warp_tube/scene/ranges.py): a value
inside loads and builds a model with no NumPy warning; outside, the reader, the batch's fast path
and the substep count refuse it with a message (tests/test_scene_validation.py's BAD table holds
the messages)."""

import math
import subprocess
import sys
import warnings

import pytest

from warp_tube.centerline.policy import substeps_for
from warp_tube.scene.ranges import RANGES, out_of_range
from warp_tube.scene.spec import SceneError, SimulationSettings
from warp_tube.scene.usd import load_scene

from .test_scene_validation import BASE, mutate

D = "double warptube:density = 1050"
S = 'token warptube:integrator = "auto"'
CORNERS = {
    "softest": [("double warptube:youngsModulus = 100000", "double warptube:youngsModulus = 0.001")],
    "stiffest, authored as a float": [("double warptube:youngsModulus = 100000", "float warptube:youngsModulus = 1e13")],
    "lightest, authored as a float": [(D, "float warptube:density = 0.01")],
    "heaviest": [(D, "double warptube:density = 1e6")],
    "stiffnesses at their bounds": [(D, D + "\n        double warptube:stretchStiffness = 1e15\n        double warptube:bendStiffness = 1e-30")],
    "dampings and anchors at their bounds": [
        ("warptube:damping = 2", "warptube:damping = 1e6\n        double warptube:springDamping = 10\n"
                                 "        double warptube:anchorStiffness = 1e12\n        int[] warptube:anchorPoints = [10]")],
    "thinnest, at the smallest metersPerUnit": [("metersPerUnit = 0.01", "metersPerUnit = 1e-9")],
    "thickest": [("float[] widths = [2]", "float[] widths = [2e5]")],
    "strongest gravity, a float timeStep at its bound": [(S, S + "\n        float3 warptube:gravity = (0, -1e6, 0)\n        float warptube:timeStep = 10")],
    "a huge and a subnormal reference normal": [(D, D + "\n        double3 warptube:referenceNormal = (0, 1e300, 1e300)")]
                                               + [("def Scope \"Push\"", "def BasisCurves \"Two\"\n    {\n        uniform token type = \"linear\"\n"
                                                   "        point3f[] points = [(0, 0, 0), (1, 0, 0)]\n        float[] widths = [1]\n"
                                                   "        double warptube:youngsModulus = 1e5\n        double warptube:density = 1000\n"
                                                   "        double3 warptube:referenceNormal = (0, 5e-324, 0)\n    }\n\n    def Scope \"Push\"")],
}  # fmt: skip


@pytest.mark.parametrize("case", sorted(CORNERS))
def test_values_at_the_bounds_load_and_build_without_numpy_warnings(case, tmp_cwd, caplog):
    import warp_tube

    text = BASE
    for old, new in CORNERS[case]:
        assert old in text, old
        text = text.replace(old, new)
    (tmp_cwd / "s.usda").write_text(text)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        scene = load_scene(str(tmp_cwd / "s.usda"))
        warp_tube.Simulation(scene, device="cpu")
    for t in scene.tubes:
        assert all(math.isfinite(x) for x in t.params.reference_normal or (0.0,))


def test_every_real_tube_attribute_has_a_range():
    from warp_tube.scene.attributes import TUBE_ATTRS

    real = {"warptube:youngsModulus", "warptube:stretchStiffness", "warptube:bendStiffness", "warptube:density",
            "warptube:damping", "warptube:springDamping", "warptube:anchorStiffness"}  # fmt: skip
    assert real <= TUBE_ATTRS and set(RANGES) == real
    for r in RANGES.values():
        assert 0.0 < r.lo < r.hi
        assert out_of_range(r.hi * 1.01, r) and out_of_range(r.lo * 0.99, r) and out_of_range(math.nan, r)
        assert out_of_range(0.0, r) != r.zero


@pytest.mark.parametrize("dt", [5e-324, 1e-300, 1e-20])
def test_a_substep_count_too_large_is_refused_in_a_few_digits(dt):
    with pytest.raises(SceneError) as err:
        substeps_for(1.0 / 24.0, dt, SimulationSettings(time_step=dt))
    count = str(err.value).split(" makes ")[1].split(" substeps")[0]
    assert len(count) < 20 and "expected at most 2,147,483,647" in str(err.value), str(err.value)


def test_the_batch_fast_path_leaves_values_outside_a_range_to_the_reader(tmp_cwd):
    from warp_tube.batch.fastread import PlainColumns

    base = load_scene(str(__import__("tests.conftest", fromlist=["SCENES"]).SCENES / "default.usda"))
    cols = PlainColumns.of(base, [("/World/Tube", "warptube:damping", "double"), ("/World/Tube", "warptube:density", "double")])
    got = cols.scenes([[2.0, 1e308, 1e6, 0.0, 2.0], [1050.0, 1050.0, 1050.0, 1050.0, 5e-324]])
    assert [g is not None for g in got] == [True, False, True, True, False]
    assert got[2].tubes[0].params.damping == 1e6


@pytest.mark.parametrize("old, new", [("metersPerUnit = 0.01", "metersPerUnit = 1e-38"),
                                      ("warptube:density = 1050", "warptube:density = 5e-324")])  # fmt: skip
def test_no_numpy_warning_reaches_stderr(old, new, tmp_cwd):
    (tmp_cwd / "bad.usda").write_text(mutate(old, new))
    r = subprocess.run([sys.executable, "-m", "warp_tube", "run", "bad.usda", "-o", "o.usdc", "--frames", "2"],
                       capture_output=True, text=True)  # fmt: skip
    assert r.returncode == 2, r.stderr
    assert "RuntimeWarning" not in r.stderr and "Traceback" not in r.stderr, r.stderr
    assert not (tmp_cwd / "o.usdc").exists()


@pytest.mark.parametrize("name, value, words", [
    ("warptube:damping", 1e308, ["/World/Tube.warptube:damping: found 1e308", "0 or 1e-12 to 1e6 1/s"]),
    ("warptube:density", 1e12, ["/World/Tube.warptube:density: found 1e12", "0.01 to 1e6 kg/m^3"]),
])  # fmt: skip
def test_a_mesh_tube_s_attributes_have_the_same_ranges(name, value, words, tmp_path):
    from pxr import Sdf

    from warp_tube import load_scene as load_with_extraction

    from .test_extract_robustness import straight_tube
    from .test_extract_usd_inputs import mesh_tube_stage

    v, f = straight_tube(length=10.0, radius=1.0)
    stage, prim = mesh_tube_stage(tmp_path / "s.usda", v, f)
    prim.CreateAttribute("warptube:density", Sdf.ValueTypeNames.Double).Set(1000.0)
    prim.CreateAttribute(name, Sdf.ValueTypeNames.Double).Set(value)
    stage.GetRootLayer().Save()
    with pytest.raises(SceneError) as err:
        load_with_extraction(str(tmp_path / "s.usda"))
    for w in words:
        assert w in str(err.value), str(err.value)
