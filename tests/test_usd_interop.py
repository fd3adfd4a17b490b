"""Scenes as DCC tools write them: composition (sublayers, references, payloads, instances), time
samples on every attribute, BasisCurves options the simulator does not follow, and the messages
and results each gets from ``warp-tube run``."""

from __future__ import annotations

import numpy as np
import pytest

from warp_tube.cli import main
from warp_tube.scene.spec import SceneError
from warp_tube.scene.usd import load_scene

from .conftest import SHARED, check_output_problems

HEADER = """#usda 1.0
(
    metersPerUnit = 0.01
    upAxis = "Y"
    timeCodesPerSecond = 24
    startTimeCode = 0
    endTimeCode = 2
)
"""

#: a 4 cm tube of 5 points along x, clamped at its start (stage units: cm)
BODY = """
        uniform token type = "linear"
        int[] curveVertexCounts = [5]
        point3f[] points = [(0, 0, 0), (1, 0, 0), (2, 0, 0), (3, 0, 0), (4, 0, 0)]
        float[] widths = [0.5] (interpolation = "constant")
        double warptube:youngsModulus = 100000
        double warptube:density = 1050
        int[] warptube:pinnedPoints = [0, 1]
        int warptube:spokes = 4
"""


def tube(body=BODY, name="Tube", meta=""):
    return f'def BasisCurves "{name}"{meta}\n{{{body}}}\n'


def world(inner, meta=""):
    return f'def Xform "World"{meta}\n{{\n{inner}\n}}\n'


def run(args, capsys):
    """``warp-tube run ... --quiet`` in this process: (exit status, stderr)."""
    status = main(["run", *map(str, args), "--quiet"])
    return status, capsys.readouterr().err


def centerline(path, time):
    from pxr import Usd

    stage = Usd.Stage.Open(str(path))
    prims = [p for p in stage.Traverse() if p.GetName() == "Centerline"]
    return {str(p.GetParent().GetPath()): np.array(p.GetAttribute("points").Get(time)) for p in prims}


def assert_checked(path):
    if SHARED.is_dir():
        assert check_output_problems(path) == []


# -- time samples on warptube: attributes -------------------------------------------------------


def test_time_sampled_parameter_is_read_at_the_first_frame_with_a_warning(tmp_path, capsys):
    """DCC tools often write every attribute as time samples: the value at startTimeCode is used,
    a warning names the attribute where the samples differ (before: an internal error)."""
    body = BODY.replace("double warptube:density = 1050", "double warptube:density.timeSamples = { 0: 1050, 2: 2000 }")
    body = body.replace("double warptube:youngsModulus = 100000", "double warptube:youngsModulus.timeSamples = { 5: 300000 }")
    scene = tmp_path / "sampled.usda"
    scene.write_text(HEADER.replace("startTimeCode = 0", "startTimeCode = 1") + world(tube(body)))
    params = load_scene(str(scene)).tubes[0].params
    # at time 1: density halfway between its samples (USD interpolates linearly), the one sample held
    assert (params.density, params.youngs_modulus) == (1525.0, 300000.0)
    status, err = run([scene, "-o", tmp_path / "out.usdc"], capsys)
    assert status == 0, err
    assert "sampled.usda: /World/Tube.warptube:density: time-sampled" in err
    assert "youngsModulus" not in err  # one sample: nothing varies
    assert_checked(tmp_path / "out.usdc")


def test_samples_of_one_value_on_every_frame_are_no_animation(tmp_path, caplog):
    """Houdini writes a constant as the same sample on every frame: no warning for those (before:
    one per attribute); samples that differ are still warned of."""
    body = BODY.replace("double warptube:youngsModulus = 100000", "double warptube:youngsModulus.timeSamples = { 0: 100000, 1: 100000, 2: 100000 }")
    body = body.replace('float[] widths = [0.5] (interpolation = "constant")',
                        'float[] widths.timeSamples = { 0: [0.5], 1: [0.5], 2: [0.5] }')
    body = body.replace("int warptube:spokes = 4", "int warptube:spokes.timeSamples = { 0: 4, 2: 4 }")
    scene = tmp_path / "constant.usda"
    scene.write_text(HEADER + world(tube(body)))
    with caplog.at_level("WARNING"):
        load_scene(str(scene))
    assert "time-sampled" not in caplog.text
    scene.write_text(HEADER + world(tube(body.replace("2: [0.5]", "2: [0.6]"))))
    with caplog.at_level("WARNING"):
        load_scene(str(scene))
    assert "widths: time-sampled" in caplog.text and "youngsModulus" not in caplog.text


# -- composition --------------------------------------------------------------------------------


def test_a_tube_among_a_point_instancers_prototypes_is_said_to_be_simulated_once(tmp_path, caplog):
    """A PointInstancer's instances are not simulated (only instanceable prims are): a tube among
    its prototypes is simulated where it is authored, and a warning says so (before: nothing)."""
    inner = ('def PointInstancer "Inst"\n{\n    point3f[] positions = [(0, 0, 0), (0, 10, 0)]\n    int[] protoIndices = [0, 0]\n'
             '    rel prototypes = </World/Inst/Protos/Tube>\n    def Scope "Protos"\n    {\n' + tube() + "    }\n}\n")
    scene = tmp_path / "instancer.usda"
    scene.write_text(HEADER + world(inner))
    with caplog.at_level("WARNING"):
        loaded = load_scene(str(scene))
    assert [t.path for t in loaded.tubes] == ["/World/Inst/Protos/Tube"]
    assert "/World/Inst/Protos/Tube: inside the PointInstancer /World/Inst: simulated once" in caplog.text


def test_a_broken_sublayer_is_named_with_its_syntax_error(tmp_path, capsys):
    (tmp_path / "layer.usda").write_text('#usda 1.0\ndef Xform "World" {\n')
    scene = tmp_path / "scene.usda"
    scene.write_text('#usda 1.0\n(\n    subLayers = [@layer.usda@]\n)\n')
    status, err = run([scene, "-o", tmp_path / "out.usdc"], capsys)
    assert status == 2
    assert f"scene.usda: cannot open the sublayer {tmp_path / 'layer.usda'}: USD syntax error at line" in err
    assert not (tmp_path / "out.usdc").exists()


def test_a_truncated_payload_is_named_as_damaged(tmp_path, capsys):
    from pxr import Sdf

    (tmp_path / "asset.usda").write_text(HEADER + world(tube()))
    Sdf.Layer.FindOrOpen(str(tmp_path / "asset.usda")).Export(str(tmp_path / "asset.usdc"))
    data = (tmp_path / "asset.usdc").read_bytes()
    (tmp_path / "asset.usdc").write_bytes(data[: len(data) // 2])
    scene = tmp_path / "scene.usda"
    scene.write_text(HEADER + 'def "Shot" (\n    payload = @asset.usdc@</World>\n)\n{\n}\n')
    status, err = run([scene, "-o", tmp_path / "out.usdc"], capsys)
    assert status == 2
    assert "cannot open the payload" in err and "asset.usdc (at /Shot): damaged or truncated binary USD" in err


@pytest.mark.parametrize("make, name, words", [
    ("usdc", "binary.usda", "binary.usda: a binary USD (crate) file named .usda: rename it .usdc or .usd"),
    ("usda", "text.usdc", "text.usdc: a USD text file named .usdc: rename it .usda or .usd"),
    ("usdz", "package.usda", "package.usda: a USD package (a zip archive) named .usda: rename it .usdz"),
])  # fmt: skip
def test_a_sound_file_under_another_formats_extension_is_named_so(tmp_path, capsys, make, name, words):
    """usd-core reads a file by its extension: a sound binary file named .usda was reported as "damaged
    or truncated binary USD", a text one named .usdc as "not a valid USD text file"."""
    from pxr import Sdf, UsdUtils

    (tmp_path / "scene.usda").write_text(HEADER + world(tube()))
    made = tmp_path / f"scene.{make}"
    if make == "usdc":
        Sdf.Layer.FindOrOpen(str(tmp_path / "scene.usda")).Export(str(made))
    elif make == "usdz":
        assert UsdUtils.CreateNewUsdzPackage(str(tmp_path / "scene.usda"), str(made))
    made.rename(tmp_path / name)
    status, err = run([tmp_path / name, "-o", tmp_path / "out.usdc"], capsys)
    assert status == 2 and words in err, err
    assert not (tmp_path / "out.usdc").exists()


def test_tubes_under_instanceable_prims_are_simulated_at_their_instances(tmp_path, capsys):
    """Two instances of one referenced asset, each with its own translation: two tubes, each where
    its instance puts it, each pushed by its own instance's force (before: 'no tube')."""
    asset = HEADER + world(
        tube() + 'def Scope "Push"\n{\n    rel warptube:target = </World/Tube>\n    int warptube:point = 4\n'
        "    float3 warptube:force = (0, 0.001, 0)\n}\n"
    )  # fmt: skip
    (tmp_path / "asset.usda").write_text(asset)
    inst = lambda name, z: (  # noqa: E731
        f'def Xform "{name}" (\n    instanceable = true\n    references = @asset.usda@</World>\n)\n{{\n'
        f'    double3 xformOp:translate = (0, 0, {z})\n    uniform token[] xformOpOrder = ["xformOp:translate"]\n}}\n'
    )
    scene = tmp_path / "scene.usda"
    scene.write_text(HEADER + world(inst("A", 10) + inst("B", 20)))
    s = load_scene(str(scene))
    assert [t.path for t in s.tubes] == ["/World/A/Tube", "/World/B/Tube"]
    assert [(f.path, f.tube) for f in s.forces] == [("/World/A/Push", 0), ("/World/B/Push", 1)]
    out = tmp_path / "out.usdc"
    status, err = run([scene, "-o", out], capsys)
    assert status == 0, err
    first = centerline(out, 0)
    # The rest points in world space are the asset's points moved by the instance's translation,
    # exactly (float32 of small integers).
    np.testing.assert_array_equal(first["/World/A/Tube"][:, 2], 10.0)
    np.testing.assert_array_equal(first["/World/B/Tube"][:, 2], 20.0)
    np.testing.assert_array_equal(first["/World/B/Tube"][:, 0], [0, 1, 2, 3, 4])
    last = centerline(out, 2)
    assert last["/World/A/Tube"][4, 1] > 0 and last["/World/B/Tube"][4, 1] > 0  # both tips pushed up
    assert_checked(out)


# -- BasisCurves as DCC tools author them -------------------------------------------------------


def _two_curves(widths_line):
    body = BODY.replace("int[] curveVertexCounts = [5]", "int[] curveVertexCounts = [2, 3]")
    body = body.replace("int[] warptube:pinnedPoints = [0, 1]", "int[] warptube:pinnedPoints = [0, 2]")
    return body.replace('float[] widths = [0.5] (interpolation = "constant")', widths_line)


@pytest.mark.parametrize(
    "line, expected",
    [
        ('float[] widths = [0.5, 0.8] (interpolation = "uniform")', [0.5, 0.5, 0.8, 0.8, 0.8]),  # one per curve
        ('float[] primvars:widths = [0.6] (interpolation = "constant")', [0.6] * 5),
        ('float[] primvars:widths = [0.5, 0.9] (interpolation = "vertex")\n        int[] primvars:widths:indices = [0, 0, 1, 1, 0]',
         [0.5, 0.5, 0.9, 0.9, 0.5]),  # indexed primvar, flattened
        ('float[] widths = [0.1]\n        float[] primvars:widths = [0.7] (interpolation = "constant")', [0.7] * 5),  # primvar wins
    ],
)  # fmt: skip
def test_widths_in_every_interpolation_and_as_primvars(tmp_path, line, expected):
    scene = tmp_path / "widths.usda"
    scene.write_text(HEADER + world(tube(_two_curves(line))))
    # radius [m] = diameter / 2 x metersPerUnit 0.01; float32 widths, so 1e-9 relative
    np.testing.assert_allclose(load_scene(str(scene)).tubes[0].radius, np.array(expected) * 0.005, rtol=1e-7)


@pytest.mark.parametrize(
    "body, words",
    [
        (_two_curves('float[] widths = [0.5, 0.8, 0.9] (interpolation = "uniform")'),
         ["/World/Tube.widths", "3 values", "2 (uniform: one per curve)", "5 (one per point)"]),
        (BODY.replace('float[] widths = [0.5] (interpolation = "constant")', ""),
         ["/World/Tube.widths", "missing", "primvars:widths"]),
        (_two_curves("float[] widths = [0.5, 0.8]"),
         ["/World/Tube.widths: found 2 values with no interpolation authored (USD's fallback 'vertex': one per point): "
          'expected 5 (one per point), or author interpolation = "uniform" on widths for 2, one per curve']),
        (_two_curves('float[] primvars:widths = [0.5, 0.8] (interpolation = "vertex")'),
         ["/World/Tube.primvars:widths: found 2 values (interpolation 'vertex': one per point): expected 5 (one per point), "
          'or author interpolation = "uniform" on primvars:widths for 2, one per curve']),
        (BODY.replace('float[] widths = [0.5] (interpolation = "constant")', 'float[] primvars:widths = [0.5, -1, 1, 1, 1]'),
         ["/World/Tube.primvars:widths", "-1.0 at index 1", "positive"]),
        (BODY + '        uniform token wrap = "periodic"\n', ["/World/Tube.wrap", "'periodic'", "'nonperiodic'"]),
        (BODY.replace('uniform token type = "linear"', ""), ["/World/Tube.type", "not authored", "'cubic'", '"linear"']),
    ],
)  # fmt: skip
def test_curves_the_simulator_cannot_follow_are_named(tmp_path, capsys, body, words):
    """A closed (periodic) curve was simulated as an open one without a word; an unauthored type
    was reported as if 'cubic' had been written; primvars:widths was reported missing; one width per
    curve without interpolation "uniform" was refused with one per curve among the counts expected."""
    scene = tmp_path / "curves.usda"
    scene.write_text(HEADER + world(tube(body)))
    status, err = run([scene, "-o", tmp_path / "out.usdc"], capsys)
    assert status == 2
    assert "curves.usda: " in err
    for w in words:
        assert w in err, f"{w!r} not in {err!r}"
    assert not (tmp_path / "out.usdc").exists()


def test_a_tube_named_surface_under_another_tube_is_refused(tmp_path, capsys):
    """/World/Tube/Surface as a tube under the tube /World/Tube: the output wrote the outer tube's
    Surface Mesh and the inner tube's Xform at one path (a Mesh holding a Centerline and a Surface)."""
    inner = tube(BODY.replace("(0, 0, 0), (1, 0, 0)", "(0, 5, 0), (1, 5, 0)"), name="Surface")
    scene = tmp_path / "nested.usda"
    scene.write_text(HEADER + world(tube(BODY + inner)))
    status, err = run([scene, "-o", tmp_path / "out.usdc"], capsys)
    assert status == 2
    assert "nested.usda: /World/Tube/Surface: a tube prim named Surface under the tube /World/Tube" in err
    assert not (tmp_path / "out.usdc").exists()


@pytest.mark.parametrize("group", ["Centerline", "Surface"])
def test_a_tube_deeper_under_a_tubes_output_prim_is_refused(tmp_path, capsys, group):
    """A tube in a group named Surface (or Centerline) under a tube: its output Xform was written
    under the outer tube's Surface Mesh, exit 0, an output usd-core's validators refuse (nested
    gprims)."""
    inner = tube(BODY.replace("(0, 0, 0), (1, 0, 0)", "(0, 5, 0), (1, 5, 0)"), name="Inner")
    scene = tmp_path / "deep.usda"
    scene.write_text(HEADER + world(tube(BODY + f'def Xform "{group}" {{\n{inner}\n}}\n')))
    status, err = run([scene, "-o", tmp_path / "out.usdc"], capsys)
    assert status == 2
    assert f"deep.usda: /World/Tube/{group}/Inner: a tube under /World/Tube/{group}, where the output writes" in err
    assert not (tmp_path / "out.usdc").exists()


def test_a_lone_tube_named_surface_runs_with_a_warning(tmp_path, capsys):
    """As `warp-tube extract Surface.stl` names it: its parent then holds a child 'Surface' that is
    not a Mesh, which the warning says; the tube itself is written as the contract says."""
    scene = tmp_path / "lone.usda"
    scene.write_text(HEADER + world(tube(name="Surface")))
    out = tmp_path / "out.usdc"
    status, err = run([scene, "-o", out], capsys)
    assert status == 0
    assert "lone.usda: /World/Surface: a tube prim named Surface: in the output /World holds a child Surface" in err
    np.testing.assert_array_equal(centerline(out, 0)["/World/Surface"][:, 0], [0, 1, 2, 3, 4])


# -- units and axes of referenced layers --------------------------------------------------------


def _asset(tmp_path, metadata):
    """asset.usda: the tube, with HEADER's metersPerUnit or upAxis replaced by ``metadata``."""
    key = metadata.split("=")[0].strip()
    lines = [line for line in HEADER.splitlines(keepends=True) if not line.strip().startswith(key)]
    lines.insert(2, metadata + '    defaultPrim = "World"\n')
    (tmp_path / "asset.usda").write_text("".join(lines) + world(tube()))


@pytest.mark.parametrize(
    "metadata, holder, warning",
    [
        ("    metersPerUnit = 0.001\n", "", "whose metersPerUnit is 0.001, but the stage's is 0.01"),
        ('    upAxis = "Z"\n', "", "whose upAxis is Z, but the stage's is Y"),
        ("    metersPerUnit = 0.001\n", '    float3 xformOp:scale = (0.1, 0.1, 0.1)\n    uniform token[] xformOpOrder = ["xformOp:scale"]\n', None),
        ('    upAxis = "Z"\n', '    float xformOp:rotateX = -90\n    uniform token[] xformOpOrder = ["xformOp:rotateX"]\n', None),
    ],
)  # fmt: skip
def test_a_reference_in_other_units_or_axes_is_warned_of_unless_made_up_for(tmp_path, caplog, metadata, holder, warning):
    """USD does not convert a referenced layer's metersPerUnit or upAxis: a millimetre asset in a
    centimetre stage is silently ten times too large unless the referencing prim scales it."""
    _asset(tmp_path, metadata)
    scene = tmp_path / "scene.usda"
    scene.write_text(HEADER + f'def Xform "Shot" (\n    references = @asset.usda@\n)\n{{\n{holder}}}\n')
    caplog.set_level("WARNING")
    s = load_scene(str(scene))
    found = [r.getMessage() for r in caplog.records if "comes from" in r.getMessage()]
    if warning is None:
        assert found == []
    else:
        assert len(found) == 1 and "scene.usda: /Shot/Tube.points" in found[0] and warning in found[0]
    if "scale" in holder:  # made up for: the 4 mm tube is 4 mm long, 0.5 mm across (float32 inputs)
        np.testing.assert_allclose(s.tubes[0].points[:, 0], [0, 0.001, 0.002, 0.003, 0.004], atol=1e-9)
        np.testing.assert_allclose(s.tubes[0].radius, 0.00025, rtol=1e-6)


@pytest.mark.parametrize(
    "old, new, words",
    [
        ("float[] widths = [0.5]", "float widths = 0.5", ["/World/Tube.widths", "type float", "float[]"]),
        ("float[] widths = [0.5]", 'string widths = "0.5"', ["/World/Tube.widths", "type string", "float[]"]),
        ('float[] widths = [0.5] (interpolation = "constant")',
         'float[] primvars:widths = [0.5] (interpolation = "vertex")\n        int[] primvars:widths:indices = [0, 0, 7, 0, 0]',
         ["/World/Tube.primvars:widths:indices", "7 at position 2", "0..0"]),
        ('uniform token type = "linear"', 'uniform token type = "linear"\n        uniform token wrap = "loop"',
         ["/World/Tube.wrap", "'loop'", "'nonperiodic'"]),
        ("point3f[] points = [(0, 0, 0), (1, 0, 0), (2, 0, 0), (3, 0, 0), (4, 0, 0)]", 'string points = "a"',
         ["/World/Tube.points", "type string", "point3f[]"]),
        ("point3f[] points = [(0, 0, 0), (1, 0, 0), (2, 0, 0), (3, 0, 0), (4, 0, 0)]", "int[] points = [1, 2, 3, 4, 5]",
         ["/World/Tube.points", "type int[]", "point3f[]"]),
        # (was "curveVertexCounts 5: expected counts >= 2 summing to 5 points")
        ("int[] curveVertexCounts = [5]", "int curveVertexCounts = 5", ["/World/Tube.curveVertexCounts", "found type int: expected int[]"]),
    ],
)  # fmt: skip
def test_mistyped_curve_attributes_are_named(tmp_path, capsys, old, new, words):
    """A scalar or string widths or points was an internal error (or read as numbers, or reported
    as a curveVertexCounts mismatch); out-of-range primvar indices leaked usd-core's own warning
    and were reported as empty widths."""
    assert old in BODY
    scene = tmp_path / "typed.usda"
    scene.write_text(HEADER + world(tube(BODY.replace(old, new))))
    status, err = run([scene, "-o", tmp_path / "out.usdc"], capsys)
    assert status == 2, err
    assert "typed.usda: " in err and "internal error" not in err and "Warning: in" not in err
    for w in words:
        assert w in err, f"{w!r} not in {err!r}"


# -- transforms ---------------------------------------------------------------------------------

XFORM = '        {}\n        uniform token[] xformOpOrder = ["{}"]\n'


@pytest.mark.parametrize(
    "on_world, op, words",
    [
        (False, 'string xformOp:translate = "x"', ["/World/Tube.xformOpOrder", "cannot be computed", "Invalid combination"]),
        (False, "double3 xformOp:translate = (nan, 0, 0)", ["/World/Tube.xformOpOrder", "is not finite"]),
        (True, "float3 xformOp:scale = (1, 0, 1)", ["/World.xformOpOrder", "zero scale", "places the tube /World/Tube"]),
        # a projective part was dropped without a word (the points placed by the affine part only)
        (True, "matrix4d xformOp:transform = ((1, 0, 0, 0), (0, 1, 0, 0), (0, 0, 1, 0.5), (0, 0, 0, 1))",
         ["/World.xformOpOrder", "is projective (last column [0.0, 0.0, 0.5, 1.0]", "expected finite, affine"]),
    ],
)  # fmt: skip
def test_a_transform_that_cannot_place_the_tube_is_named(tmp_path, capsys, on_world, op, words):
    """A mistyped xformOp was an internal error; a NaN or zero scale was reported as NaN points or
    a zero width, naming the tube instead of the prim whose transform is wrong."""
    ops = XFORM.format(op, op.split()[1])  # "TYPE xformOp:NAME = VALUE"
    if on_world:
        scene_text = HEADER + world(tube()).replace('def Xform "World"\n{\n', 'def Xform "World"\n{\n' + ops, 1)
    else:
        scene_text = HEADER + world(tube(BODY + ops))
    scene = tmp_path / "xf.usda"
    scene.write_text(scene_text)
    status, err = run([scene, "-o", tmp_path / "out.usdc"], capsys)
    assert status == 2, err
    assert "xf.usda: " in err and "internal error" not in err and "RuntimeWarning" not in err
    for w in words:
        assert w in err, f"{w!r} not in {err!r}"


def test_a_tiny_uniform_scale_is_a_valid_transform(tmp_path):
    """1e-4 on every axis is small, not singular: the tube is placed and sized by it exactly."""
    ops = XFORM.format("float3 xformOp:scale = (1e-4, 1e-4, 1e-4)", "xformOp:scale")
    scene = tmp_path / "tiny.usda"
    scene.write_text(HEADER + world(tube(BODY + ops)))
    t = load_scene(str(scene)).tubes[0]
    # x [m] = i x 1e-4 x 0.01; float32 scale, so 1e-7 relative
    np.testing.assert_allclose(t.points[:, 0], np.arange(5) * 1e-6, rtol=1e-6, atol=1e-15)
    np.testing.assert_allclose(t.radius, 0.25 * 1e-6, rtol=1e-6)


def test_time_sampled_widths_are_read_at_the_first_frame_with_a_warning(tmp_path, caplog):
    body = BODY.replace('float[] widths = [0.5] (interpolation = "constant")',
                        'float[] widths.timeSamples = { 0: [0.4], 2: [0.8] }')  # fmt: skip
    scene = tmp_path / "w.usda"
    scene.write_text(HEADER.replace("startTimeCode = 0", "startTimeCode = 1") + world(tube(body)))
    caplog.set_level("WARNING")
    t = load_scene(str(scene)).tubes[0]
    # diameter 0.6 at time 1 (USD interpolates linearly), radius 0.3 cm = 0.003 m; float32 inputs
    np.testing.assert_allclose(t.radius, 0.003, rtol=1e-6)
    assert any("w.usda: /World/Tube.widths: time-sampled" in r.getMessage() for r in caplog.records)


def test_a_transform_that_puts_the_tube_past_any_size_is_refused(tmp_path, capsys):
    """A scale of 1e30 ran (exit 0) with overflow warnings from NumPy and a surface flattened to
    zero thickness in one axis."""
    ops = XFORM.format("float3 xformOp:scale = (1e30, 1e30, 1e30)", "xformOp:scale")
    scene = tmp_path / "huge.usda"
    scene.write_text(HEADER + world(tube(BODY + ops)))
    status, err = run([scene, "-o", tmp_path / "out.usdc"], capsys)
    assert status == 2
    assert "huge.usda: /World/Tube.points: found a coordinate of 4e+28 m" in err
    assert "RuntimeWarning" not in err and not (tmp_path / "out.usdc").exists()


def test_time_sampled_curve_vertex_counts_are_read(tmp_path):
    """curveVertexCounts written as time samples (as DCC exports of animated curves are) was read
    at the default time, found unauthored, and the two curves silently joined into one tube."""
    body = BODY.replace("int[] curveVertexCounts = [5]", "int[] curveVertexCounts.timeSamples = { 0: [2, 3] }")
    scene = tmp_path / "counts.usda"
    scene.write_text(HEADER + world(tube(body.replace("pinnedPoints = [0, 1]", "pinnedPoints = [0, 2]"))))
    assert load_scene(str(scene)).tubes[0].curve_counts.tolist() == [2, 3]


def test_unauthored_curve_vertex_counts_are_one_curve_with_a_warning(tmp_path, caplog):
    """Without curveVertexCounts the points ran as one curve without a word."""
    scene = tmp_path / "counts.usda"
    scene.write_text(HEADER + world(tube(BODY.replace("        int[] curveVertexCounts = [5]\n", ""))))
    with caplog.at_level("WARNING"):
        assert load_scene(str(scene)).tubes[0].curve_counts.tolist() == [5]
    assert ("counts.usda: /World/Tube: no curveVertexCounts: taken as one curve of 5 points; author "
            "curveVertexCounts = [5]") in caplog.text


def test_animated_curve_vertex_counts_are_read_at_the_first_frame_with_a_warning(tmp_path, caplog):
    """Samples of other counts (a topology that changes) were left out without a word."""
    body = BODY.replace("int[] curveVertexCounts = [5]", "int[] curveVertexCounts.timeSamples = { 0: [5], 2: [2, 3] }")
    scene = tmp_path / "counts.usda"
    scene.write_text(HEADER + world(tube(body)))
    with caplog.at_level("WARNING"):
        assert load_scene(str(scene)).tubes[0].curve_counts.tolist() == [5]
    assert "counts.usda: /World/Tube.curveVertexCounts: time-sampled: the curves at the first frame ([5])" in caplog.text
    caplog.clear()
    scene.write_text(HEADER + world(tube(body.replace("2: [2, 3]", "2: [5]"))))
    with caplog.at_level("WARNING"):
        load_scene(str(scene))
    assert "time-sampled" not in caplog.text


# -- directions under transforms -----------------------------------------------------------------

#: the tube of BODY with a cross-section that is no circle (4 spokes of 0.3, 0.5, 0.2 and 0.4 at
#: every hub: no symmetry) whose spoke 0 points along +y
SECTION = BODY.replace(
    'int warptube:spokes = 4',
    "int warptube:spokes = 4\n        float[] warptube:spokeLengths = [" + ", ".join(["0.3, 0.5, 0.2, 0.4"] * 5) + "]\n"
    "        float3 warptube:referenceNormal = (0, 1, 0)",
)


@pytest.mark.parametrize("op", ['float3 xformOp:rotateXYZ = (90, 30, 0)', 'float3 xformOp:scale = (1, -1, 1)',
                                'float3 xformOp:scale = (2, 0.5, 1)'])  # fmt: skip
def test_a_section_turns_mirrors_and_scales_with_its_prim(tmp_path, op):
    """A tube's referenceNormal is a direction in its prim's space: under a rotated, mirrored or
    unevenly scaled parent the rest surface is the untransformed scene's surface moved by that
    transform (before, the spokes kept their authored world direction: the section did not turn)."""
    from pxr import Usd, UsdGeom

    from warp_tube.sim.simulation import Simulation

    name = op.split(":")[1].split(" ")[0]
    plain, moved = tmp_path / "plain.usda", tmp_path / "moved.usda"
    plain.write_text(HEADER + world(tube(SECTION)))
    moved.write_text(HEADER + world(f'def Xform "Parent"\n{{\n{op}\nuniform token[] xformOpOrder = ["xformOp:{name}"]\n'
                                    + tube(SECTION) + "}\n"))  # fmt: skip
    stage = Usd.Stage.Open(str(moved))
    m = np.array(UsdGeom.Xformable(stage.GetPrimAtPath("/World/Parent/Tube")).ComputeLocalToWorldTransform(0))
    scale = abs(np.linalg.det(m[:3, :3])) ** (1 / 3)
    surfaces = [Simulation(load_scene(str(p)), device="cpu").surface()[0][0] for p in (plain, moved)]
    centre = load_scene(str(plain)).tubes[0].points / 0.01  # (stage units)
    # The spokes of a hub of the plain tube, carried by the transform's linear part: the moved
    # tube's spokes (as sets per ring, so that a mirror's reversed order compares) but for the
    # section's size, which an uneven scale takes as the circle of the section's area (the radii
    # are lengths, not vectors: scene.transforms.section_scale, checked against exact geometry
    # in tests/test_scene_validation.py)
    from warp_tube.scene.transforms import section_scale

    across = section_scale(centre, np.array([len(centre)]), m)
    factor = np.full((len(centre), 1), scale) if across is None else across[:, None]
    expected = surfaces[0].reshape(5, 4, 3) - centre[:, None]
    expected = expected @ m[:3, :3]
    expected *= (factor * np.linalg.norm(surfaces[0].reshape(5, 4, 3) - centre[:, None], axis=2)
                 / np.linalg.norm(expected, axis=2))[..., None]  # fmt: skip
    got = surfaces[1].reshape(5, 4, 3) - (centre @ m[:3, :3] + m[3, :3])[:, None]
    for ring in range(5):
        d = np.linalg.norm(expected[ring][:, None] - got[ring][None], axis=2)
        # float32 surface points of a 4-unit tube: 1e-5 units is ~100 ulps, far below the 0.1-unit
        # differences between the section's spokes that a wrong turn gives
        assert d.min(axis=1).max() < 1e-5, (ring, d.min(axis=1))


def test_a_reference_normal_along_the_tube_is_warned_of(tmp_path, caplog):
    """Spoke 0 points across the tube: a referenceNormal along its first segment cannot set it
    (before: taken silently)."""
    for normal, warned in (("(1, 0, 0)", True), ("(1, 0.001, 0)", True), ("(0, 1, 0)", False), ("(1, 0.1, 0)", False)):
        scene = tmp_path / "normal.usda"
        scene.write_text(HEADER + world(tube(BODY + f"        float3 warptube:referenceNormal = {normal}\n")))
        caplog.clear()
        with caplog.at_level("WARNING"):
            load_scene(str(scene))
        assert ("/World/Tube.warptube:referenceNormal: along the first segment of curve 0" in caplog.text) == warned, normal


def test_a_warptube_attribute_written_as_a_primvar_is_named(tmp_path, capsys):
    """DCC tools export custom attributes as primvars: primvars:warptube:youngsModulus is named,
    with the spelling to use (before: "youngsModulus: missing", with no hint)."""
    body = BODY.replace("double warptube:youngsModulus", "double primvars:warptube:youngsModulus")
    scene = tmp_path / "primvar.usda"
    scene.write_text(HEADER + world(tube(body)))
    status, err = run([scene, "-o", tmp_path / "out.usdc"], capsys)
    assert status == 2
    assert "/World/Tube.primvars:warptube:youngsModulus: warptube: attributes are plain attributes, not primvars: " \
           "author it as warptube:youngsModulus" in err, err  # fmt: skip


def test_gravity_across_the_stages_up_axis_is_warned_of(tmp_path, caplog):
    """A Z-up stage with gravity along -Y (a scene moved between up axes): warned (before: none)."""
    settings = 'def Scope "Simulation"\n{\n    float3 warptube:gravity = (0, -9.81, 0)\n}\n'
    for up, warned in (("Z", True), ("Y", False)):
        scene = tmp_path / f"up{up}.usda"
        scene.write_text(HEADER.replace('upAxis = "Y"', f'upAxis = "{up}"') + world(settings + tube()))
        caplog.clear()
        with caplog.at_level("WARNING"):
            load_scene(str(scene))
        assert ("warptube:gravity (0, -9.81, 0) is not down the stage's upAxis Z (down is (0, 0, -1))" in caplog.text) == warned, caplog.text


def test_a_namespace_spelled_otherwise_is_named(tmp_path, capsys):
    """warpTube:, WarpTube:, warp_tube: (also under primvars:) read as warptube: to a person, not
    to USD: a second tube written so was left out with exit 0 (before), a tube's only such
    attribute reported "missing". Named, with the spelling to use, exit 2, no output."""
    for written in ("warpTube:youngsModulus", "WarpTube:youngsModulus", "warp_tube:youngsModulus",
                    "primvars:warpTube:youngsModulus", "warptube:youngsModulus"):  # fmt: skip
        body = BODY.replace("double warptube:youngsModulus", f"double {written}")
        scene = tmp_path / "ns.usda"
        scene.write_text(HEADER + world(tube(body)))
        out = tmp_path / "out.usdc"
        status, err = run([scene, "-o", out], capsys)
        if written == "warptube:youngsModulus":  # (the spelling itself)
            assert status == 0
            out.unlink()
            continue
        assert status == 2 and not out.exists(), written
        assert f"/World/Tube.{written}: the namespace is spelled warptube (all lower case, one word): author it as " \
               "warptube:youngsModulus" in err, err
