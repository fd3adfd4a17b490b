"""Batch columns on prims the table cannot simply author: widths a scene gives as primvars:widths,
and tubes inside an instance."""

import subprocess
import sys

import numpy as np
import pytest

from tests.conftest import SCENES
from warp_tube.batch import run_batch
from warp_tube.scene.spec import SceneError

TUBE = """
        uniform token type = "linear"
        int[] curveVertexCounts = [6]
        point3f[] points = [(0, 0, 0), (1, 0, 0), (2, 0, 0), (3, 0, 0), (4, 0, 0), (5, 0, 0)]
        {widths}
        double warptube:youngsModulus = 100000
        double warptube:density = 1000
        int[] warptube:pinnedPoints = [0, 1]
"""
HEAD = """#usda 1.0
(
    defaultPrim = "World"
    metersPerUnit = 0.01
    upAxis = "Y"
    endTimeCode = 4
)

def Scope "Simulation"
{
    float3 warptube:gravity = (0, -9.81, 0)
}
"""


def write(path, text):
    path.write_text(text)
    return str(path)


def cli(*args):
    return subprocess.run([sys.executable, "-m", "warp_tube", *map(str, args)], capture_output=True, text=True)


def test_a_widths_column_where_the_scene_authors_primvars_widths_is_refused_and_the_primvar_is_taken(tmp_path):
    """The reader takes primvars:widths over widths (as USD does), so a widths column would change
    nothing: refused, naming the column to use; that column changes the variants' radii."""
    widths = 'float[] primvars:widths = [1] (interpolation = "constant")'
    scene = write(tmp_path / "s.usda", HEAD + 'def Xform "World"\n{\ndef BasisCurves "Tube"\n{' + TUBE.format(widths=widths) + "}\n}\n")
    bad = write(tmp_path / "bad.csv", "/World/Tube.widths\n1\n3\n")
    r = cli("batch", scene, "--variants", bad, "-o", tmp_path / "out", "--frames", 3, "--layout", "arrays")
    assert r.returncode == 2, r.stderr
    assert "column /World/Tube.widths" in r.stderr and "name the column /World/Tube.primvars:widths" in r.stderr
    assert not (tmp_path / "out").exists()
    good = write(tmp_path / "good.csv", "/World/Tube.primvars:widths\n1\n3\n")
    out = tmp_path / "good"
    assert run_batch(scene, str(out), good, layout="arrays", frames=3).ok == 2
    q = np.load(out / "centerline.npy")
    # Under gravity a thicker tube of the same material sags differently (stiffness grows as r^4,
    # weight as r^2): the two variants' tips part by far more than float round-off.
    assert np.abs(q[0, -1] - q[1, -1]).max() > 1e-4


INSTANCED = HEAD + """
class Xform "Proto"
{
    def BasisCurves "Tube"
    {""" + TUBE.format(widths='float[] widths = [1] (interpolation = "constant")') + """    }
}

def Xform "World"
{
    def Xform "Holder" (
        instanceable = true
        references = </Proto>
    )
    {
    }
}
"""


def test_a_tube_inside_an_instance_takes_plain_values_and_names_the_instance_otherwise(tmp_path):
    """Plain values (a warptube: parameter) are made from the base scene and need no edit of the
    instance: taken, each variant its own; a column usd-core would have to author inside the
    instance (an int[] pinnedPoints) is refused before anything runs, naming the instance."""
    scene = write(tmp_path / "inst.usda", INSTANCED)
    plain = write(tmp_path / "plain.csv", "/World/Holder/Tube.warptube:youngsModulus\n20000\n200000\n")
    out = tmp_path / "plain"
    assert run_batch(scene, str(out), plain, layout="arrays", frames=3).ok == 2
    q = np.load(out / "centerline.npy")
    # A 10x stiffer tube sags about 10x less under its weight: the tips part by far more than round-off.
    assert np.abs(q[0, -1] - q[1, -1]).max() > 1e-4
    staged = write(tmp_path / "staged.csv", '/World/Holder/Tube.warptube:pinnedPoints\n"[0, 1]"\n"[0, 1, 2]"\n')
    with pytest.raises(SceneError, match=r"column /World/Holder/Tube.warptube:pinnedPoints: .* inside the instance "
                                         r"/World/Holder.*make /World/Holder not instanceable"):  # fmt: skip
        run_batch(scene, str(tmp_path / "staged"), staged, layout="arrays", frames=3)
    assert not (tmp_path / "staged").exists()


def test_a_mistyped_column_names_the_closest_prim_or_attribute(tmp_path):
    """A typo in a header's prim path or attribute is refused (exit 2, nothing written) with the
    closest name the scene has, so the user sees what was meant."""
    from pathlib import Path

    scene = Path(__file__).resolve().parents[1] / "scenes" / "default.usda"
    for header, hint in (("/World/Tub.warptube:youngsModulus", "(did you mean /World/Tube?)"),
                         ("/World/Tube.warptube:youngModulus", "(did you mean warptube:youngsModulus?)")):  # fmt: skip
        table = write(tmp_path / "t.csv", f"{header}\n100000\n")
        r = cli("batch", scene, "--variants", table, "-o", tmp_path / "out", "--frames", 2)
        assert r.returncode == 2 and hint in r.stderr, r.stderr
        assert not (tmp_path / "out").exists()
    # a tube's column is matched against a tube's attributes only (warptube:foo is not warptube:force)
    table = write(tmp_path / "t.csv", "/World/Tube.warptube:foo\n1\n")
    r = cli("batch", scene, "--variants", table, "-o", tmp_path / "out", "--frames", 2)
    assert r.returncode == 2 and "no attribute warptube:foo" in r.stderr and "did you mean" not in r.stderr, r.stderr
    table = write(tmp_path / "t.csv", "/World/Elsewhere.warptube:youngsModulus\n100000\n")
    r = cli("batch", scene, "--variants", table, "-o", tmp_path / "out", "--frames", 2)
    assert r.returncode == 2 and "no prim /World/Elsewhere" in r.stderr and "did you mean" not in r.stderr


DEFAULT = str(SCENES / "default.usda")
NO_SETTINGS = """#usda 1.0
(
    defaultPrim = "World"
    metersPerUnit = 0.01
    upAxis = "Y"
    endTimeCode = 4
)

def Xform "World"
{
    def BasisCurves "Tube"
    {""" + TUBE.format(widths='float[] widths = [1] (interpolation = "constant")') + """    }
}
"""


@pytest.mark.parametrize("column, value, kind", [
    ("/World/Simulation.warptube:spokes", "8", "/World/Simulation is a simulation settings prim, which takes gravity, integrator, timeStep"),
    ("/World/Simulation.warptube:density", "1000", "/World/Simulation is a simulation settings prim"),
    ("/World/Push.warptube:youngsModulus", "1e5", "/World/Push is a force prim, which takes assistantLine, force, point"),
    ("/World/Push.warptube:density", "1000", "/World/Push is a force prim"),
    ("/World/Tube.warptube:gravity", '"(0, -9.81, 0)"', "/World/Tube is a tube prim, which takes anchorPoints, anchorStiffness"),
    ("/World.warptube:point", "3", "/World has no warptube:target relationship"),
    ("/World.warptube:timeStep", "0.001", "the scene's simulation settings prim is /World/Simulation: set warptube:timeStep there"),
])  # fmt: skip
def test_a_column_its_prims_kind_does_not_take_is_refused_naming_what_it_takes(tmp_path, column, value, kind):
    """As `warp-tube check` refuses such a scene. Before: authored, never read (the batch re-reads
    only the prims a row changes, without the reader's per-kind check), exit 0 and no effect."""
    table = write(tmp_path / "t.csv", f"{column}\n{value}\n{value}\n")
    with pytest.raises(SceneError) as e:
        run_batch(DEFAULT, str(tmp_path / "out"), table, layout="arrays", frames=3)
    assert f"t.csv: column {column}: {kind}" in str(e.value)
    assert not (tmp_path / "out").exists()


def test_a_tube_column_on_a_prim_of_no_kind_is_warned_of_once_and_a_new_settings_prim_is_read(tmp_path, caplog):
    """A tube's attribute on a prim that is no tube, force or settings prim: ignored with the
    reader's warning, said once and naming the column (before: no word). A setting on a prim of a
    scene without a settings prim makes it the settings prim, as the reader would take it."""
    table = write(tmp_path / "t.csv", "/World.warptube:density\n1000\n2000\n")
    with caplog.at_level("WARNING"):
        assert run_batch(DEFAULT, str(tmp_path / "out"), table, layout="arrays", frames=3).ok == 2
    said = [r.getMessage() for r in caplog.records if "is not a tube, force or settings prim" in r.getMessage()]
    assert len(said) == 1 and "t.csv: column /World.warptube:density: /World (a Xform prim)" in said[0], said
    scene = write(tmp_path / "s.usda", NO_SETTINGS)
    gravity = write(tmp_path / "g.csv", '/World.warptube:gravity\n"(0, 0, 0)"\n"(0, -9.81, 0)"\n')
    assert run_batch(scene, str(tmp_path / "g"), gravity, layout="arrays", frames=3).ok == 2
    q = np.load(tmp_path / "g" / "centerline.npy")
    assert np.abs(q[0, -1] - q[0, 0]).max() < 1e-6 and q[1, -1, -1, 1] < -1e-3  # the second falls
