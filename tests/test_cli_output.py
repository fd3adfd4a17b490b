"""warp-tube run end to end: the output contract, every example scene, failures and interrupts."""

import os
import subprocess
import sys

import numpy as np
import pytest
from pxr import Usd, UsdGeom

from warp_tube.cli import main

from .conftest import SCENES, check_output_problems, needs_shared

SCENE_FILES = sorted(SCENES.glob("*.usda"))


def centerline_samples(path, prim):
    st = Usd.Stage.Open(str(path))
    return UsdGeom.BasisCurves(st.GetPrimAtPath(prim + "/Centerline")).GetPointsAttr().GetTimeSamples(), st


@needs_shared
@pytest.mark.parametrize("scene", SCENE_FILES, ids=lambda p: p.stem)
def test_every_scene_runs_and_meets_the_output_contract(scene, tmp_cwd):
    out = tmp_cwd / f"{scene.stem}.usdc"
    assert main(["run", str(scene), "-o", str(out), "--frames", "3", "--quiet"]) == 0
    assert check_output_problems(out, scene=scene) == []


@needs_shared
def test_default_run_without_arguments_writes_tube_usdc(tmp_cwd):
    assert main(["run", "--frames", "4", "--quiet"]) == 0
    out = tmp_cwd / "tube.usdc"
    assert check_output_problems(out) == []
    samples, st = centerline_samples(out, "/World/Tube")
    assert len(samples) == 4 and st.GetEndTimeCode() == 3.0
    assert UsdGeom.GetStageMetersPerUnit(st) == 0.01 and st.GetTimeCodesPerSecond() == 24


def test_every_k_writes_every_kth_frame_and_ends_at_the_last(tmp_cwd):
    out = tmp_cwd / "e.usda"
    assert main(["run", str(SCENES / "default.usda"), "-o", str(out), "--frames", "7", "--every", "3", "--quiet", "--no-surface"]) == 0
    samples, st = centerline_samples(out, "/World/Tube")
    assert list(samples) == [0.0, 3.0, 6.0] and st.GetEndTimeCode() == 6.0


def test_runs_on_the_cpu_are_deterministic(tmp_cwd):
    for name in ("a.usdc", "b.usdc"):
        assert main(["run", str(SCENES / "default.usda"), "-o", name, "--frames", "5", "--quiet"]) == 0
    assert (tmp_cwd / "a.usdc").read_bytes() == (tmp_cwd / "b.usdc").read_bytes()


def test_existing_output_is_replaced_only_by_a_complete_one(tmp_cwd):
    out = tmp_cwd / "keep.usdc"
    out.write_bytes(b"previous result")
    bad = tmp_cwd / "bad.usda"
    bad.write_text((SCENES / "default.usda").read_text().replace("warptube:density = 1050", "warptube:density = 0"))
    assert main(["run", str(bad), "-o", str(out)]) == 2
    assert out.read_bytes() == b"previous result"
    assert main(["run", str(SCENES / "default.usda"), "-o", str(out), "--frames", "2", "--quiet"]) == 0
    assert out.read_bytes() != b"previous result" and not list(tmp_cwd.glob(".keep*"))


@needs_shared
def test_blow_up_exits_3_and_keeps_the_finished_frames(tmp_cwd, capsys):
    # A forced semi-implicit step 40x beyond its stability bound blows up within a few frames.
    text = (SCENES / "default.usda").read_text().replace(
        'token warptube:integrator = "auto"',
        'token warptube:integrator = "semiImplicitEuler"\n        double warptube:timeStep = 0.02',
    )
    (tmp_cwd / "stiff.usda").write_text(text)
    out = tmp_cwd / "stiff.usdc"
    assert main(["run", "stiff.usda", "-o", str(out)]) == 3
    err = capsys.readouterr().err
    assert "numerical failure at frame" in err and "/World/Tube" in err and "stability bound" in err
    # The finished frames are in stiff.partial.usdc, named in the message; stiff.usdc is not written.
    partial = tmp_cwd / "stiff.partial.usdc"
    assert f"kept in {partial}" in err and not out.exists()
    out = partial
    samples, st = centerline_samples(out, "/World/Tube")
    assert 1 <= len(samples) < 97 and st.GetEndTimeCode() == samples[-1]
    assert check_output_problems(out) == []
    assert np.isfinite(np.array(UsdGeom.BasisCurves(st.GetPrimAtPath("/World/Tube/Centerline")).GetPointsAttr().Get(samples[-1]))).all()


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="needs /dev/full (a device that is always full)")
def test_a_full_standard_output_is_named_and_the_output_kept(tmp_cwd):
    """Standard output on a full disk (a CI log): exit 1 "internal error ... please report it",
    although the output was complete. Now exit 2 naming standard output, the output as written."""
    with open("/dev/full", "w") as full:
        r = subprocess.run([sys.executable, "-m", "warp_tube", "run", "--frames", "2", "-o", "out.usdc"], stdout=full,
                           stderr=subprocess.PIPE, text=True, timeout=300)  # fmt: skip
    assert r.returncode == 2, r.stderr
    assert "cannot write to standard output (No space left on device)" in r.stderr and "internal error" not in r.stderr
    assert Usd.Stage.Open("out.usdc").GetEndTimeCode() == 1.0  # frames 0 and 1


def test_check_validates_without_writing(tmp_cwd, capsys):
    assert main(["check", str(SCENES / "intestine.usda")]) == 0
    assert "valid" in capsys.readouterr().out
    assert not list(tmp_cwd.iterdir())


def test_writer_copies_large_and_small_arrays_exactly():
    """The direct-copy path (>= DIRECT_COPY_MIN vertices) and FromNumpy give the input bit for bit,
    and the blocked extent equals NumPy's plain min/max, for sizes on both sides of each switch."""
    from warp_tube.io.writer import DIRECT_COPY_MIN, points_extent, vec3f_array

    rng = np.random.default_rng(3)
    for n in (1, 5, DIRECT_COPY_MIN - 1, DIRECT_COPY_MIN, 4095, 4096, 4097, 70_001):
        p = rng.normal(size=(n, 3)).astype(np.float32)
        assert np.array_equal(np.asarray(vec3f_array(p)), p), n
        assert np.array_equal(np.asarray(vec3f_array(p.astype(np.float64))), p), n
        ext = points_extent(p)
        assert np.array_equal(ext, np.stack([p.min(axis=0), p.max(axis=0)])), n
