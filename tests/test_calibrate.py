"""Sizing an extracted scene's push (``warp-tube extract``): its trial runs warn as one run does."""

import logging

import numpy as np

from warp_tube.sim.calibrate import PUSH_RUNS, size_push


def _hairpin_scene(path, gap=0.015, gravity=""):
    """A hairpin tube whose legs lie ``gap`` apart (15 mm: overlapping at rest) with a radius of 10 mm,
    clamped at one end (the lower leg), pushed at its bend; ``gravity``: a settings prim's line."""
    legs = np.linspace(0.0, 0.1, 9)
    h = 0.5 * gap
    bend = [(0.1 + h * np.sin(a), h - h * np.cos(a), 0.0) for a in np.linspace(0.0, np.pi, 5)[1:-1]]
    pts = [(x, 0.0, 0.0) for x in legs] + bend + [(x, gap, 0.0) for x in legs[::-1]]
    text = f"""#usda 1.0
(
    metersPerUnit = 1
    upAxis = "Y"
    timeCodesPerSecond = 24
    startTimeCode = 0
    endTimeCode = 48
)
def Xform "World"
{{
    def Scope "Simulation"
    {{
        {gravity}
    }}
    def BasisCurves "Tube"
    {{
        uniform token type = "linear"
        int[] curveVertexCounts = [{len(pts)}]
        point3f[] points = [{", ".join(f"({x:.6f}, {y:.6f}, {z:.6f})" for x, y, z in pts)}]
        float[] widths = [0.02] (interpolation = "constant")
        double warptube:youngsModulus = 100000
        double warptube:density = 1050
        int[] warptube:pinnedPoints = [0, 1]
    }}
    def Scope "Push"
    {{
        rel warptube:target = </World/Tube>
        int warptube:point = 10
        float3 warptube:force = (0, 0, 0.001)
    }}
}}
"""
    path.write_text(text)
    return path


def test_the_trial_runs_warn_of_a_contact_once(tmp_path, caplog):
    """The hairpin's legs 25 mm apart (not touching: 20 mm of radii), its free leg falling onto the
    clamped one under gravity: every trial run of the sizing meets the contact; it is said once,
    as the sizing's."""
    path = _hairpin_scene(tmp_path / "hairpin.usda", gap=0.025, gravity="float3 warptube:gravity = (0, -9.81, 0)")
    with caplog.at_level(logging.WARNING, logger="warp_tube.sim.simulation"):
        size = size_push(str(path))
    assert size is not None and 2 <= size.runs <= PUSH_RUNS, size  # (more than one run warned)
    contacts = [r for r in caplog.records if "closer than the sum of their radii" in r.getMessage()]
    assert len(contacts) == 1, [r.getMessage() for r in contacts]
    assert contacts[0].getMessage().startswith("while sizing the push, a run of the scene: frame ")  # (said as the sizing's)


def test_legs_in_contact_at_rest_are_not_warned_of(tmp_path, caplog):
    """The hairpin's legs 15 mm apart with 10 mm radii overlap at rest, as the scene lays them: the
    trial runs say nothing of it."""
    path = _hairpin_scene(tmp_path / "hairpin.usda")
    with caplog.at_level(logging.WARNING, logger="warp_tube.sim.simulation"):
        size = size_push(str(path))
    assert size is not None
    assert not [r for r in caplog.records if "closer than the sum of their radii" in r.getMessage()]


def test_a_push_that_would_pass_the_force_limit_is_held_there(tmp_path):
    """A tube 3 km long, 160 m across (a mesh in mm taken as metres): the push that would move it
    two radii is beyond the 1e9 N a scene may hold; it is held at that limit and said to be (before:
    the sizing stopped with "force /World/Push: a component of 5.4e+11 N", nothing written)."""
    from pxr import Usd

    x = np.linspace(0.0, 3000.0, 21)
    pts = ", ".join(f"({v:.1f}, 0, 0)" for v in x)
    path = tmp_path / "huge.usda"
    path.write_text(_hairpin_scene(tmp_path / "h.usda").read_text().split("point3f[] points = [")[0] + f"point3f[] points = [{pts}]\n"
                    + '        float[] widths = [160] (interpolation = "constant")\n'
                    + "        double warptube:youngsModulus = 100000\n        double warptube:density = 1050\n"
                    + "        int[] warptube:pinnedPoints = [0, 1]\n    }\n"
                    + '    def Scope "Push"\n    {\n        rel warptube:target = </World/Tube>\n        int warptube:point = 10\n'
                    + "        float3 warptube:force = (0, 0, 1)\n    }\n}\n")  # fmt: skip
    size = size_push(str(path))
    assert size is not None and size.at_limit and not size.within_tolerance
    stage = Usd.Stage.Open(str(path))
    force = stage.GetAttributeAtPath("/World/Push.warptube:force").Get()
    assert abs(force[2]) <= 1e9 and abs(force[2]) > 0.99e9, force


def test_only_the_run_whose_push_is_written_is_warned_of(tmp_path, caplog, monkeypatch):
    """Each trial run's warnings are held and only those of the run whose push is written are said
    (a trial with a push far from the one kept, the straight-beam estimate 30x too large for a
    stub, strained the tube as the written scene never does). The runs here answer in proportion
    (a stand-in for the simulation, warning of the push it ran): the second run meets the target
    and is kept; the first one's warning is not said."""
    import warp_tube.sim.calibrate as calibrate

    path = _hairpin_scene(tmp_path / "hairpin.usda")
    log = logging.getLogger("warp_tube.sim.simulation")

    def proportional(scene, frames):
        push = float(np.abs(scene.forces[0].values).max())
        log.warning("a run pushed with %.6g N", push)
        return 1e3 * push  # [m]

    monkeypatch.setattr(calibrate, "largest_displacement", proportional)
    with caplog.at_level(logging.WARNING, logger="warp_tube.sim.simulation"):
        size = size_push(str(path))
    said = [r.getMessage() for r in caplog.records if "a run pushed with" in r.getMessage()]
    assert size is not None and size.runs == 2 and size.factor != 1.0, size
    assert said == [f"{calibrate.SAID}a run pushed with {size.force_n:.6g} N"], said
