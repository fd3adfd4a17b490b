"""Rest shapes that read but will not simulate as meant are warned of when the scene loads
(warp_tube.scene.shape_notes), and the example scenes get none of these warnings.

Oracle: the scenes are the default scene with its 21 points (1 cm apart, 2 cm wide, in a
centimetre stage) replaced by shapes whose turning angles, lengths and coordinates are exact.
"""

import re

import numpy as np
import pytest

from warp_tube.scene.usd import load_scene

from .conftest import SCENES

BASE = (SCENES / "default.usda").read_text()
POINTS = re.search(r"point3f\[\] points = \[[^\]]*\]", BASE).group(0)


def _with_points(pts, extra: str = "") -> str:
    text = BASE.replace(POINTS, "point3f[] points = [" + ", ".join(f"({float(x)!r}, {float(y)!r}, {float(z)!r})" for x, y, z in pts) + "]")
    return text.replace("double warptube:density = 1050", "double warptube:density = 1050" + extra)


def _folded(turn_deg: float) -> np.ndarray:
    """11 points along +x, then 10 more turned by ``turn_deg`` at point 10 (1 cm apart)."""
    a = np.radians(turn_deg)
    first = np.stack([np.arange(11.0), np.zeros(11), np.zeros(11)], 1)
    k = np.arange(1.0, 11.0)[:, None]
    return np.concatenate([first, first[-1] + k * [np.cos(a), np.sin(a), 0.0]])


def _messages(tmp_path, text, caplog) -> str:
    (tmp_path / "s.usda").write_text(text)
    with caplog.at_level("WARNING"):
        load_scene(str(tmp_path / "s.usda"))
    return " ".join(r.getMessage() for r in caplog.records)


STRAIGHT = np.stack([np.arange(21.0), np.zeros(21), np.zeros(21)], 1)


@pytest.mark.parametrize("case, text, words", [
    # a fold of 170 degrees at one point: its discrete bending 1 / cos^2(85 deg) = 131.6x as stiff
    ("fold 170", _with_points(_folded(170.0)), ["turns by 170 degrees at point 10", "132x stiffer"]),
    ("fold 150", _with_points(_folded(150.0)), []),  # (15x: measured to settle within 0.05% of a fine step)
    # points in metres in a centimetre stage: 0.2 cm long, 2 cm wide
    ("points in metres", _with_points(STRAIGHT * 0.01), ["curve 0 is 0.002 m long and 0.02 m wide: shorter than its diameter",
                                                          "are the points and widths in the same units"]),
    # a stub 1.6 cm long and 2 cm wide, as made (a unit's mix-up is off by 10x or more): no unit asked about
    ("a stub", _with_points(STRAIGHT * 0.08), ["curve 0 is 0.016 m long and 0.02 m wide: shorter than its diameter (a body "
                                               "this stubby is modelled only roughly by a centerline"]),
    # 1 km from the origin in cm: float32 steps of 1e5 x 2^-23 = 0.0119 cm, 1.2% of a 1 cm segment
    ("far from the origin", _with_points(STRAIGHT + [1e5, 0.0, 0.0]), ["float32 points carry them in steps of 1.2% of a segment"]),
    # the same tube placed there by its parent's transform (double precision): the points are exact, but the
    # simulation holds them, and writes them, as float32 world coordinates: 1,000 m x 2^-23 = 0.0119 cm, 1.2%
    ("placed by a transform", _with_points(STRAIGHT).replace('def Xform "World"\n{', 'def Xform "World"\n{\n    double3 '
     'xformOp:translate = (100000, 0, 0)\n    uniform token[] xformOpOrder = ["xformOp:translate"]'),
     ["placed up to 1e+03 m from the origin", "float32 world coordinates, in steps of 1.2% of a segment"]),
    # placed near the origin by a transform from points authored far away: the points' own steps are warned of
    ("authored far, placed near", _with_points(STRAIGHT + [1e5, 0.0, 0.0]).replace('def Xform "World"\n{', 'def Xform "World"'
     '\n{\n    double3 xformOp:translate = (-100000, 0, 0)\n    uniform token[] xformOpOrder = ["xformOp:translate"]'),
     ["float32 points carry them in steps of 1.2% of a segment"]),
    # both widths and primvars:widths, other values: USD takes the primvar; the other is said to be ignored
    ("both widths", _with_points(STRAIGHT).replace('float[] widths = [2] (interpolation = "constant")', 'float[] widths = [2] '
     '(interpolation = "constant")\n        float[] primvars:widths = [0.5] (interpolation = "constant")'),
     ["primvars:widths: both authored, with other values than widths: primvars:widths is used"]),
    ("anchor on a pin", _with_points(STRAIGHT, "\n        int[] warptube:anchorPoints = [1, 10]\n        double "
     "warptube:anchorStiffness = 5"), ["warptube:anchorPoints: point 1 is pinned: a returning spring on a pinned point does nothing"]),
])  # fmt: skip
def test_a_rest_shape_that_will_not_simulate_as_meant_is_warned_of(case, text, words, tmp_path, caplog):
    said = _messages(tmp_path, text, caplog)
    for w in words:
        assert w in said, (case, w, said)
    if not words:
        for w in ("turns by", "shorter than its diameter", "float32 points", "a returning spring on a pinned", "both authored"):
            assert w not in said, (case, said)


def test_a_stub_is_not_taken_for_a_units_mix_up(tmp_path, caplog):
    """A tube 0.8 of its diameter long is a stub as made: units mixed up would put it 10x or more
    off (centimetres for metres: 100x), so the warning does not ask about units (it did)."""
    said = _messages(tmp_path, _with_points(STRAIGHT * 0.08), caplog)
    assert "shorter than its diameter" in said and "same units" not in said, said


@pytest.mark.parametrize("name", ["default.usda", "cantilever.usda", "intestine.usda"])
def test_the_example_scenes_get_no_shape_warning(name, caplog):
    with caplog.at_level("WARNING"):
        load_scene(str(SCENES / name))
    said = " ".join(r.getMessage() for r in caplog.records)
    for w in ("turns by", "shorter than its diameter", "float32 points", "a returning spring on a pinned"):
        assert w not in said, (name, said)


@pytest.mark.parametrize("offset, refused", [(4e5, False), (1e6, True)])
def test_a_tube_placed_where_float32_cannot_hold_it_is_refused(offset, refused, tmp_path):
    """The simulation's positions and its output are float32 world coordinates: a tube placed so far
    from the origin (here by its parent's transform, in centimetres) that float32 steps by more
    than a tenth of its 1 cm segments is refused, naming the distance and the steps; short of that
    it is warned of. Steps: offset [cm] x 0.01 m x 2^-23 over 0.01 m: 4e5 cm -> 4.8%, 1e6 cm -> 11.9%."""
    from warp_tube.scene.spec import SceneError

    text = _with_points(STRAIGHT).replace('def Xform "World"\n{', 'def Xform "World"\n{\n    double3 xformOp:translate = '
                                          f'({offset!r}, 0, 0)\n    uniform token[] xformOpOrder = ["xformOp:translate"]')
    (tmp_path / "s.usda").write_text(text)
    if refused:
        with pytest.raises(SceneError, match=r"/World/Tube.points: placed up to 1e\+04 m from the origin .* steps there are "
                                             r"11.9% of a segment: expected at most 10%"):
            load_scene(str(tmp_path / "s.usda"))
    else:
        assert load_scene(str(tmp_path / "s.usda")).tubes[0].points[0, 0] == 4e3  # [m]
