"""Bad input: a clear message naming file, prim and attribute; exit status 2; no output file."""

import os
import subprocess
import sys

import numpy as np
import pytest

from warp_tube.cli import main
from warp_tube.scene.spec import SceneError
from warp_tube.scene.usd import load_scene

from .conftest import SCENES

BASE = (SCENES / "default.usda").read_text()


def mutate(old, new):
    assert old in BASE, old
    return BASE.replace(old, new)


BAD = {
    "nan point": (mutate("(3, 0, 0), (4, 0, 0)", "(3, nan, 0), (4, 0, 0)"), ["/World/Tube", "points", "finite"]),
    "coincident points": (mutate("(3, 0, 0), (4, 0, 0)", "(3, 0, 0), (3, 0, 0)"), ["/World/Tube", "points[3]", "distinct"]),
    "missing density": (mutate("        double warptube:density = 1050\n", ""), ["/World/Tube", "warptube:density", "missing"]),
    "density as string": (mutate("double warptube:density = 1050", 'string warptube:density = "1050"'), ["warptube:density", "type string", "float or double"]),
    "negative density": (mutate("warptube:density = 1050", "warptube:density = -3"), ["warptube:density", "-3", "> 0"]),
    "absurd density": (mutate("warptube:density = 1050", "warptube:density = 1e12"), ["/World/Tube", "density"]),
    "no stiffness": (mutate("        double warptube:youngsModulus = 100000\n", ""), ["warptube:youngsModulus", "missing", "bendStiffness"]),
    "pinned out of range": (mutate("warptube:pinnedPoints = [0, 1]", "warptube:pinnedPoints = [0, 21]"), ["warptube:pinnedPoints", "21", "0..20"]),
    "pinned as floats": (mutate("int[] warptube:pinnedPoints = [0, 1]", "float[] warptube:pinnedPoints = [0, 1]"), ["warptube:pinnedPoints", "float[]", "int[]"]),
    "force point out of range": (mutate("int warptube:point = 15", "int warptube:point = 99"), ["/World/Push", "warptube:point", "99"]),
    "force target missing": (mutate("rel warptube:target = </World/Tube>", "rel warptube:target = </World/Nothing>"), ["/World/Push", "warptube:target", "/World/Nothing"]),
    "bad integrator": (mutate('token warptube:integrator = "auto"', 'token warptube:integrator = "rk4"'), ["warptube:integrator", "'rk4'", "implicitEuler"]),
    "cubic curves": (mutate('uniform token type = "linear"', 'uniform token type = "cubic"'), ["/World/Tube", "type", "linear"]),
    "zero width": (mutate("float[] widths = [2]", "float[] widths = [0]"), ["widths", "positive"]),
    "wrong width count": (mutate("float[] widths = [2] (interpolation = \"constant\")", "float[] widths = [2, 2, 2]"), ["widths", "3 values"]),
    "spokes too few": (mutate("int warptube:spokes = 16", "int warptube:spokes = 2"), ["warptube:spokes", "2"]),
    "spoke lengths count": (mutate("int warptube:spokes = 16", "int warptube:spokes = 16\n        float[] warptube:spokeLengths = [1, 2]"), ["warptube:spokeLengths", "2 values", "21 x 16"]),
    "two settings prims": (mutate('def Scope "Push"', 'def Scope "More"\n    {\n        double warptube:timeStep = 0.001\n    }\n\n    def Scope "Push"'), ["2 simulation settings prims", "/World/Simulation", "/World/More"]),
    "negative time step": (mutate('token warptube:integrator = "auto"', 'token warptube:integrator = "auto"\n        double warptube:timeStep = -1'), ["warptube:timeStep", "-1"]),
    "huge force": (mutate("24: (0, 0.02, 0)", "24: (0, 1e12, 0)"), ["warptube:force", "1e+12"]),
    "misspelled attribute": (mutate("warptube:density = 1050", "warptube:densty = 1050"), ["/World/Tube.warptube:densty", "unknown attribute", "did you mean warptube:density"]),
    "force attribute on a tube": (mutate("warptube:density = 1050", "warptube:density = 1050\n        bool warptube:assistantLine = true"), ["/World/Tube.warptube:assistantLine", "not an attribute of a tube prim"]),
    # a settings attribute on a tube is named as the mistake (the tube's own attributes were blamed)
    "time step on a tube": (mutate("warptube:density = 1050", "warptube:density = 1050\n        double warptube:timeStep = 0.001"), ["/World/Tube.warptube:timeStep", "not an attribute of a tube prim", "belongs on the simulation settings prim"]),
    "integrator on a tube": (mutate("warptube:density = 1050", 'warptube:density = 1050\n        token warptube:integrator = "auto"'), ["/World/Tube.warptube:integrator", "belongs on the simulation settings prim"]),
    # a force whose target is left out or misspelled would be left out of the run without a word
    "force without target": (mutate("        rel warptube:target = </World/Tube>\n", ""), ["/World/Push", "warptube:force", "without a warptube:target relationship"]),
    "misspelled target": (mutate("rel warptube:target", "rel warptube:targt"), ["/World/Push.warptube:targt", "unknown relationship", "did you mean warptube:target"]),
    # absurd magnitudes: each value outside its physical range, named with the range
    "tiny metersPerUnit": (mutate("metersPerUnit = 0.01", "metersPerUnit = 1e-38"), ["metersPerUnit 1e-38", "expected 1e-9 to 1e6 m"]),
    "small metersPerUnit": (mutate("metersPerUnit = 0.01", "metersPerUnit = 1e-12"), ["metersPerUnit 1e-12", "expected 1e-9 to 1e6 m"]),
    "blocked force sample": (mutate("            24: (0, 0.02, 0),\n", "            1: None,\n            24: (0, 0.02, 0),\n"),
                             ["/World/Push.warptube:force", "found a blocked sample (None) at time 1", "expected a float3 at every sample"]),
    "huge spring damping": (mutate("warptube:damping = 2", "warptube:damping = 2\n        double warptube:springDamping = 1e38"),
                            ["/World/Tube.warptube:springDamping", "found 1e38", "0 or 1e-15 to 10 s"]),
    "denormal time step": (mutate('warptube:integrator = "auto"', 'warptube:integrator = "auto"\n        double warptube:timeStep = 5e-324'),
                           ["/World/Simulation.warptube:timeStep", "found 5e-324", "1e-12 to 10 s"]),
    "tiny time step": (mutate('warptube:integrator = "auto"', 'warptube:integrator = "auto"\n        double warptube:timeStep = 1e-300'),
                       ["warptube:timeStep", "found 1e-300", "1e-12 to 10 s"]),
    "denormal density": (mutate("warptube:density = 1050", "warptube:density = 5e-324"), ["/World/Tube.warptube:density", "0.01 to 1e6 kg/m^3"]),
    "huge damping": (mutate("warptube:damping = 2", "warptube:damping = 1e308"), ["/World/Tube.warptube:damping", "found 1e308", "0 or 1e-12 to 1e6 1/s"]),
    "large damping": (mutate("warptube:damping = 2", "warptube:damping = 1e38"), ["warptube:damping", "found 1e38"]),
    "denormal Young's modulus": (mutate("warptube:youngsModulus = 100000", "warptube:youngsModulus = 5e-324"),
                                 ["/World/Tube.warptube:youngsModulus", "0.001 to 1e13 Pa"]),
    "huge anchor stiffness": (mutate("warptube:damping = 2", "warptube:damping = 2\n        double warptube:anchorStiffness = 1e38\n"
                                     "        int[] warptube:anchorPoints = [10]"), ["warptube:anchorStiffness", "found 1e38", "0 or 1e-12 to 1e12 N/m"]),
    "huge stretch stiffness": (mutate("warptube:damping = 2", "warptube:damping = 2\n        double warptube:stretchStiffness = 1e38\n"
                                      "        double warptube:bendStiffness = 1"), ["warptube:stretchStiffness", "found 1e38", "1e-12 to 1e15 N"]),
    "huge bend stiffness": (mutate("warptube:damping = 2", "warptube:damping = 2\n        double warptube:stretchStiffness = 30\n"
                                   "        double warptube:bendStiffness = 1e38"), ["warptube:bendStiffness", "found 1e38", "0 or 1e-30 to 1e15 N m^2"]),
    "huge gravity": (mutate('warptube:integrator = "auto"', 'warptube:integrator = "auto"\n        float3 warptube:gravity = (0, -1e38, 0)'),
                     ["/World/Simulation.warptube:gravity", "a magnitude of 1e38 m/s^2", "0 to 1e6 m/s^2"]),
    "huge double gravity": (mutate('warptube:integrator = "auto"', 'warptube:integrator = "auto"\n        double3 warptube:gravity = (0, -1e300, 1e300)'),
                            ["warptube:gravity", "a magnitude of 1e300 m/s^2"]),
    "tiny widths": (mutate("float[] widths = [2]", "float[] widths = [1e-30]"), ["/World/Tube.widths", "a radius of 5e-33 m", "1e-9 to 1000 m"]),
    "tiny parent scale": (mutate('def Xform "World"\n{', 'def Xform "World"\n{\n    double3 xformOp:scale = (1e-30, 1e-30, 1e-30)\n'
                                 '    uniform token[] xformOpOrder = ["xformOp:scale"]'), ["/World/Tube.widths", "a radius of 1e-32 m", "1e-9 to 1000 m"]),
    "huge spoke lengths": (mutate("int warptube:spokes = 16", "int warptube:spokes = 16\n        float[] warptube:spokeLengths = ["
                                  + ", ".join(["1e30"] * 21 * 16) + "]"), ["warptube:spokeLengths", "a length of 1e28 m", "1e-9 to 1000 m"]),
    # a far last point makes the first segments short against the tube's extent: said so, with the extent
    "far last point": (mutate("(19, 0, 0), (20, 0, 0)]", "(19, 0, 0), (2000000, 0, 0)]"),
                       ["points[0] and points[1] are 0.01 m apart", "shorter than 1e-6 of the tube's extent (2e+04 m)", "longer than 0.02 m"]),
    # the line of the broken `def Xform`, counted in the scene as it is
    "syntax error": (BASE.replace("def Xform", "def Xform {{"),
                     [f"USD syntax error at line {BASE[: BASE.index('def Xform')].count(chr(10)) + 1}", "unexpected end of file"]),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_scene_is_named_and_exits_2(case, tmp_cwd, capsys):
    text, words = BAD[case]
    path = tmp_cwd / "bad.usda"
    path.write_text(text)
    with pytest.raises(SceneError) as err:
        load_scene(str(path))
    msg = str(err.value)
    assert "bad.usda" in msg
    for w in words:
        assert w in msg, f"{w!r} not in {msg!r}"
    out = tmp_cwd / "out.usdc"
    assert main(["run", str(path), "-o", str(out)]) == 2
    assert not out.exists() and not list(tmp_cwd.glob(".out*"))
    assert "warp-tube: " in capsys.readouterr().err


def test_missing_file_and_unwritable_output_exit_2(tmp_cwd):
    assert main(["check", str(tmp_cwd / "nope.usda")]) == 2
    assert main(["run", str(SCENES / "default.usda"), "-o", str(tmp_cwd / "no" / "dir" / "x.usdc")]) == 2
    assert main(["run", str(SCENES / "default.usda"), "-o", str(tmp_cwd / "x.png")]) == 2
    assert main(["run", str(SCENES / "default.usda"), "--frames", "0"]) == 2
    assert main(["run", str(SCENES / "default.usda"), "--device", "cuda:7"]) == 2
    assert not list(tmp_cwd.iterdir())


def test_an_output_below_a_file_names_the_file(tmp_cwd, capsys):
    (tmp_cwd / "notes.txt").write_text("mine")
    assert main(["run", str(SCENES / "default.usda"), "-o", str(tmp_cwd / "notes.txt" / "x.usdc")]) == 2
    assert "notes.txt is a file, not a folder" in capsys.readouterr().err
    assert (tmp_cwd / "notes.txt").read_text() == "mine"


def test_bad_input_from_the_console_script_has_no_traceback(tmp_cwd):
    (tmp_cwd / "bad.usda").write_text(BAD["nan point"][0])
    r = subprocess.run([sys.executable, "-m", "warp_tube", "run", "bad.usda"], capture_output=True, text=True)
    assert r.returncode == 2
    assert "Traceback" not in r.stderr and "/World/Tube" in r.stderr


def test_force_on_pinned_point_warns(tmp_cwd, caplog):
    (tmp_cwd / "s.usda").write_text(mutate("int warptube:point = 15", "int warptube:point = 1"))
    scene = load_scene(str(tmp_cwd / "s.usda"))
    assert scene.forces[0].point == 1
    assert any("pinned" in r.message for r in caplog.records)


def test_units_and_transforms_are_honoured(tmp_cwd):
    # The same tube authored in cm under a parent transform (translate 5 m, scale 2) reads as
    # metres in world space: a point at x = 10 cm becomes 5 + 2 * 0.10 = 5.2 m.
    text = BASE.replace('def Xform "World"\n{', 'def Xform "World" (\n)\n{\n    double3 xformOp:translate = (500, 0, 0)\n    float3 xformOp:scale = (2, 2, 2)\n    uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:scale"]\n')
    (tmp_cwd / "t.usda").write_text(text)
    s = load_scene(str(tmp_cwd / "t.usda"))
    t = s.tubes[0]
    assert s.stage.meters_per_unit == 0.01
    np.testing.assert_allclose(t.points[10], [5.2, 0.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(t.radius, 0.02, rtol=1e-6)  # width 2 cm, scaled by 2: radius 2 cm


def test_an_uneven_scale_keeps_the_area_of_the_section(tmp_cwd):
    """A scale along the tube (x) lengthens it and leaves its section as it was; a scale across it
    (z) makes the round section an ellipse of 3x its area, taken as the circle of that area. Exact
    geometry: a slab across the tube keeps |det M| / |M t| times its section's area. (Before: both
    radii scaled by the geometric mean, 2^(1/3) and 3^(1/3).)"""
    for scale, radius in (((2, 1, 1), 0.01), ((1, 1, 3), 0.01 * np.sqrt(3.0)), ((2, 2, 2), 0.02)):
        op = f'def Xform "World"\n{{\n    double3 xformOp:scale = {scale}\n    uniform token[] xformOpOrder = ["xformOp:scale"]'
        (tmp_cwd / "s.usda").write_text(mutate('def Xform "World"\n{', op))
        t = load_scene(str(tmp_cwd / "s.usda")).tubes[0]
        np.testing.assert_allclose(t.radius, radius, rtol=1e-12)  # width 2 cm, stage in cm
        np.testing.assert_allclose(t.points[10], [0.1 * scale[0], 0.0, 0.0], atol=1e-12)
    # A quarter circle of radius R under scale (1, 2, 1) about its centre: at angle a from +x the
    # tangent (-sin a, cos a, 0) becomes (-sin a, 2 cos a, 0), det 2: radius r sqrt(2 / |M t|).
    from warp_tube.scene.transforms import section_scale

    a = np.linspace(0.0, 0.5 * np.pi, 9)
    pts = np.stack([np.cos(a), np.sin(a), 0 * a], 1)
    got = section_scale(pts, np.array([9]), np.diag([1.0, 2.0, 1.0, 1.0]))
    mid = 0.5 * (a[1:] + a[:-1])  # a chord's direction is the tangent at its middle; a point's: the bisector
    t = np.stack([-np.sin(mid), np.cos(mid)], 1)
    bis = np.concatenate([t[:1], t[:-1] + t[1:], t[-1:]])
    bis /= np.linalg.norm(bis, axis=1, keepdims=True)
    np.testing.assert_allclose(got, np.sqrt(2.0 / np.hypot(bis[:, 0], 2.0 * bis[:, 1])), rtol=1e-12)
    assert section_scale(pts, np.array([9]), np.diag([3.0, 3.0, 3.0, 1.0])) is None  # even: the one scale


def test_unauthored_metadata_takes_usd_fallbacks(tmp_cwd):
    text = BASE
    for line in ("    metersPerUnit = 0.01\n", '    upAxis = "Y"\n', "    timeCodesPerSecond = 24\n"):
        text = text.replace(line, "")
    (tmp_cwd / "u.usda").write_text(text)
    s = load_scene(str(tmp_cwd / "u.usda"))
    assert (s.stage.meters_per_unit, s.stage.up_axis, s.stage.time_codes_per_second) == (0.01, "Y", 24.0)
    assert "metersPerUnit" not in s.stage.authored


@pytest.mark.parametrize("edit, words", [
    # a scale that differs along the axes: a section of the same area
    (('def Xform "World"\n{', 'def Xform "World"\n{\n    double3 xformOp:scale = (2, 1, 1)\n    uniform token[] xformOpOrder = ["xformOp:scale"]'),
     ["scales unevenly", "taken as the circle of its area"]),
    # a tube's attribute on a prim that is no tube: ignored, said with a hint
    (('def Scope "Push"', 'def Scope "Stray"\n    {\n        double warptube:density = 5\n    }\n\n    def Scope "Push"'),
     ["/World/Stray (a Scope prim) carries warptube:density but is not a tube", "ignored"]),
    # returning springs without points to act on, a modulus the stiffnesses replace
    (("double warptube:density = 1050", "double warptube:density = 1050\n        double warptube:anchorStiffness = 5"),
     ["warptube:anchorStiffness: no anchorPoints"]),
    (("double warptube:density = 1050", "double warptube:density = 1050\n        double warptube:stretchStiffness = 30\n"
                                         "        double warptube:bendStiffness = 1e-4"),
     ["warptube:youngsModulus: not used: stretchStiffness and bendStiffness are both given"]),
    # an animated parent transform with untimed points: not followed
    (('def Xform "World"\n{', 'def Xform "World"\n{\n    double3 xformOp:translate.timeSamples = {0: (0, 0, 0), 10: (5, 0, 0)}\n'
                               '    uniform token[] xformOpOrder = ["xformOp:translate"]'),
     ["the transform of /World is animated", "does not follow"]),
])  # fmt: skip
def test_what_the_scene_cannot_follow_is_warned_of(edit, words, tmp_cwd, caplog):
    (tmp_cwd / "s.usda").write_text(mutate(*edit))
    with caplog.at_level("WARNING"):
        load_scene(str(tmp_cwd / "s.usda"))
    text = " ".join(r.getMessage() for r in caplog.records)
    for w in words:
        assert w in text, (w, text)


def test_time_sampled_points_without_pins_are_warned_of(tmp_cwd, caplog):
    import re

    m = re.search(r"point3f\[\] points = (\[[^\]]*\])", BASE)
    text = BASE.replace(m.group(0), f"point3f[] points.timeSamples = {{0: {m.group(1)}, 10: {m.group(1)}}}")
    text = re.sub(r"\s*int\[\] warptube:pinnedPoints = \[[^\]]*\]", "", text)
    (tmp_cwd / "s.usda").write_text(text)
    with caplog.at_level("WARNING"):
        load_scene(str(tmp_cwd / "s.usda"))
    assert any("time-sampled, but the tube has no pinnedPoints" in r.getMessage() for r in caplog.records)


def test_moving_pins_follow_their_samples_past_the_end_time_code(tmp_cwd):
    """Points sampled at 0 and 3 with endTimeCode 2, run for 5 frames: the pinned point reaches the
    sample at frame 3 and holds it after (as USD holds a value after its last sample, and as a
    force's samples are followed), instead of stopping at the stage's last frame."""
    from pxr import Usd

    text = """#usda 1.0
(
    metersPerUnit = 0.01
    timeCodesPerSecond = 24
    startTimeCode = 0
    endTimeCode = 2
)
def BasisCurves "Tube"
{
    uniform token type = "linear"
    int[] curveVertexCounts = [5]
    point3f[] points.timeSamples = {
        0: [(0, 0, 0), (1, 0, 0), (2, 0, 0), (3, 0, 0), (4, 0, 0)],
        3: [(0, 2, 0), (1, 0, 0), (2, 0, 0), (3, 0, 0), (4, 0, 0)],
    }
    float[] widths = [1] (interpolation = "constant")
    int[] warptube:pinnedPoints = [0]
    double warptube:youngsModulus = 100000
    double warptube:density = 1000
}
"""
    (tmp_cwd / "pins.usda").write_text(text)
    tube = load_scene(str(tmp_cwd / "pins.usda")).tubes[0]
    assert len(tube.pin_track) == 4  # frames 0..3: the stage's 3 and on to the last sample
    assert main(["run", "pins.usda", "-o", "pins.usdc", "--frames", "5", "--quiet"]) == 0
    stage = Usd.Stage.Open(str(tmp_cwd / "pins.usdc"))
    attr = stage.GetPrimAtPath("/Tube/Centerline").GetAttribute("points")
    y = [float(attr.Get(t)[0][1]) for t in attr.GetTimeSamples()]
    # linear between the samples (pins move linearly between frames), then held; float32 centimetres
    np.testing.assert_allclose(y, [0.0, 2 / 3, 4 / 3, 2.0, 2.0], atol=1e-6)


def test_a_warning_of_many_prims_alike_is_said_once_with_how_many_more(tmp_cwd, caplog):
    """300 prims with the same time-sampled damping: one warning naming the first, and one line
    saying that the same holds for 299 more (not 300 lines)."""
    lines = ["#usda 1.0", "(", "    metersPerUnit = 0.01", "    startTimeCode = 0", "    endTimeCode = 2", ")"]
    for k in range(300):
        lines += [f'def BasisCurves "T{k}"', "{", '    uniform token type = "linear"', "    int[] curveVertexCounts = [3]",
                  f"    point3f[] points = [(0, 0, {3 * k}), (1, 0, {3 * k}), (2, 0, {3 * k})]",
                  '    float[] widths = [0.5] (interpolation = "constant")', "    double warptube:youngsModulus = 100000",
                  "    double warptube:density = 1000", "    double warptube:damping.timeSamples = {0: 1, 2: 2}", "}"]  # fmt: skip
    (tmp_cwd / "many.usda").write_text("\n".join(lines) + "\n")
    with caplog.at_level("WARNING"):
        load_scene(str(tmp_cwd / "many.usda"))
    said = [r.getMessage() for r in caplog.records]
    assert len([m for m in said if "warptube:damping: time-sampled" in m]) == 1, said
    assert "the same for 299 more prim(s) of the scene" in said


@pytest.mark.parametrize("authored, time", [("startTimeCode = 1001\n", 1001.0), ("endTimeCode = -5\n", -5.0)])
def test_an_unauthored_end_or_start_time_code_is_taken_as_the_authored_one(authored, time, tmp_cwd, capsys):
    """USD's fallback 0 for the one not authored lay on the wrong side of the other: the scene was
    refused ("expected end >= start"), even with --frames N."""
    from pxr import Usd

    (tmp_cwd / "s.usda").write_text(mutate("startTimeCode = 0\n    endTimeCode = 96\n", authored))
    info = load_scene("s.usda").stage
    assert (info.start_time_code, info.end_time_code, info.frame_count) == (time, time, 1)
    assert main(["run", "s.usda", "-o", "one.usdc", "--no-surface", "--quiet"]) == 0
    assert "not authored: taken as the" in capsys.readouterr().err
    assert main(["run", "s.usda", "-o", "three.usdc", "--frames", "3", "--no-surface", "--quiet"]) == 0
    stage = Usd.Stage.Open(str(tmp_cwd / "three.usdc"))
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (time, time + 2)


@pytest.mark.parametrize("start, end, said", [
    (0.25, 0.75, "startTimeCode 0.25 and endTimeCode 0.75 are less than one frame (1 time code) apart"),
    (5, 5, "startTimeCode and endTimeCode are both 5"),
])  # fmt: skip
def test_an_authored_time_range_shorter_than_a_frame_is_warned_of(start, end, said, tmp_cwd, capsys):
    """A range of less than one frame ran one frame, simulated none, and said nothing."""
    (tmp_cwd / "s.usda").write_text(mutate("startTimeCode = 0\n    endTimeCode = 96\n", f"startTimeCode = {start}\n    endTimeCode = {end}\n"))
    assert main(["run", "s.usda", "-o", "one.usdc", "--no-surface", "--quiet"]) == 0
    assert (f"warp-tube: warning: s.usda: {said}, which gives one frame and nothing to simulate; author an endTimeCode of "
            f"at least {start + 1:g} or pass --frames N") in capsys.readouterr().err  # fmt: skip
    assert main(["run", "s.usda", "-o", "three.usdc", "--frames", "3", "--no-surface", "--quiet"]) == 0
    assert "nothing to simulate" not in capsys.readouterr().err


@pytest.mark.parametrize("old, new, words", [
    ("startTimeCode = 0\n    endTimeCode = 96", "startTimeCode = 5\n    endTimeCode = 2", "startTimeCode 5.0, endTimeCode 2.0: expected end >= start"),
    ("endTimeCode = 96", "endTimeCode = inf", "endTimeCode inf: expected a finite time code"),
    ("startTimeCode = 0", "startTimeCode = nan", "startTimeCode nan: expected a finite time code"),
])  # fmt: skip
def test_a_time_range_that_cannot_be_run_is_named(old, new, words, tmp_cwd):
    """A non-finite time code was reported as "expected end >= start"."""
    (tmp_cwd / "bad.usda").write_text(mutate(old, new))
    with pytest.raises(SceneError) as err:
        load_scene("bad.usda")
    assert str(err.value) == f"bad.usda: {words}"


#: the default scene's 21 points along x, as authored
POINTS = [f"({i}, 0, 0)" for i in range(21)]


def sampled_points(time, later):
    """The default scene with its points time-sampled: at 0 as authored, at ``time`` ``later``."""
    authored = "point3f[] points = [" + ", ".join(POINTS) + "]"
    assert authored in BASE
    return BASE.replace(authored, f"point3f[] points.timeSamples = {{0: [{', '.join(POINTS)}], {time}: [{', '.join(later)}]}}")


@pytest.mark.parametrize("time, later, words", [
    # between frames 1 and 2 (read there interpolated): the sample itself is named
    (1.5, POINTS[:7] + ["(nan, 0, 0)"] + POINTS[8:],
     "/World/Tube.points: found [nan, 0.0, 0.0] at index 7 in the sample at time 1.5: expected finite values"),
    # a pinned point's track is read at every frame; the first frame's limit holds there too (it ran, exit 3)
    (2, POINTS[:7] + ["(1e30, 0, 0)"] + POINTS[8:],
     "/World/Tube.points: found a coordinate of 1e+28 m (after the transforms and metersPerUnit) in the sample at time 2: "
     "expected at most 1e+06 m"),
    (2, POINTS[:9], "/World/Tube.points: found shape (9, 3) in the sample at time 2: expected points of the first frame's shape (21, 3)"),
])  # fmt: skip
def test_later_samples_of_points_are_checked_as_the_first_frames(time, later, words, tmp_cwd, capsys):
    """A NaN in a later sample was "found a sample at time 1.0 of shape (21, 3): expected finite
    points of shape (21, 3)": neither the value nor the sample was named."""
    (tmp_cwd / "bad.usda").write_text(sampled_points(time, later).replace("pinnedPoints = [0, 1]", "pinnedPoints = [0, 1, 7]"))
    with pytest.raises(SceneError) as err:
        load_scene("bad.usda")
    assert str(err.value).startswith(f"bad.usda: {words}"), str(err.value)
    assert main(["run", "bad.usda", "-o", "out.usdc", "--frames", "3", "--quiet"]) == 2
    assert not list(tmp_cwd.glob("out*")) and words in capsys.readouterr().err


def test_an_over_without_a_def_is_warned_of_or_named_where_it_was_the_tube(tmp_cwd, caplog):
    """An `over` (no `def` in any layer: USD composes no prim there) was skipped without a word:
    an override at a mistyped path, or a tube written with `over` instead of `def`."""
    (tmp_cwd / "asset.usda").write_text(BASE)
    (tmp_cwd / "shot.usda").write_text('#usda 1.0\n(\n    subLayers = [@asset.usda@]\n)\n'
                                       'over "World"\n{\n    over "Tub"\n    {\n        double warptube:density = 5000\n    }\n}\n')
    with caplog.at_level("WARNING"):
        assert load_scene("shot.usda").tubes[0].params.density == 1050.0
    assert ("shot.usda: /World/Tub (an `over` with no `def`) carries warptube:density but is not a tube, force or settings "
            "prim: ignored (a mistyped path? did you mean /World/Tube?)") in caplog.text
    (tmp_cwd / "over.usda").write_text(BASE.replace('def BasisCurves "Tube"', 'over BasisCurves "Tube"'))
    with pytest.raises(SceneError) as err:
        load_scene("over.usda")
    assert str(err.value).startswith("over.usda: no tube: expected a BasisCurves prim")
    assert str(err.value).endswith("; /World/Tube is an `over` with no `def`: define it")


@pytest.mark.parametrize("text, where", [
    (b'#usda 1.0\ndef Xform "W" (doc = "caf\xe9") {}\n', "byte 35 (0xe9, line 2, column 26)"),
    (b'#usda 1.0\ndef Xform "W\xe9" {\n}\n', "byte 22 (0xe9, line 2, column 13)"),
])  # fmt: skip
def test_a_usda_file_that_is_not_utf8_is_named_with_its_first_bad_byte(text, where, tmp_cwd, capsys):
    (tmp_cwd / "latin1.usda").write_bytes(text)
    for command in ("check", "run"):
        assert main([command, "latin1.usda"]) == 2
        err = capsys.readouterr().err.strip()
        assert err == f"warp-tube: latin1.usda: not UTF-8 text at {where}: a USD text file is UTF-8; save it as UTF-8", err
    assert sorted(p.name for p in tmp_cwd.iterdir()) == ["latin1.usda"]


def test_a_composition_cycle_is_one_line_without_addresses(tmp_cwd, capsys):
    """A tube that inherits from itself: usd-core's error is four lines naming its session layer by
    its address in memory; the message is one line without it."""
    (tmp_cwd / "cycle.usda").write_text(mutate('def BasisCurves "Tube"', 'def BasisCurves "Tube" (\n        inherits = </World/Tube>\n    )'))
    assert main(["check", "cycle.usda"]) == 2
    err = capsys.readouterr().err.strip()
    assert "cannot be composed: Cycle detected" in err and "anon:0x" not in err and "\n" not in err, err


def test_a_scene_that_is_a_broken_link_is_named_so(tmp_cwd, capsys):
    """A scene given as a symbolic link loop, or a link to nothing, is named so (was "no such file"),
    as extract names a mesh that is one."""
    os.symlink("loop.usda", tmp_cwd / "loop.usda")
    os.symlink("gone.usda", tmp_cwd / "dangling.usda")
    assert main(["check", "loop.usda"]) == 2
    assert "loop.usda: a symbolic link loop (the link leads back to itself): expected a USD file" in capsys.readouterr().err
    assert main(["check", "dangling.usda"]) == 2
    assert "dangling.usda: a symbolic link to gone.usda, which does not exist" in capsys.readouterr().err
