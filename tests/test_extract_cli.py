"""warp-tube extract end to end on the five real meshes: extract, simulate 60 frames under the
scene's push, write an output that meets the contract. Meshes: ../shared/data/meshes (credited in
its SOURCES.md: HuBMAP VH Female vasculature, CC BY 4.0; Edinburgh Gut Cell Atlas, CC BY 4.0)."""

import pytest
from pxr import Usd

from warp_tube.cli import main

from .conftest import SHARED, check_output_problems, needs_shared

MESHES = SHARED / "data" / "meshes"
# The vessels are in metres; the intestine segments in CT voxels of 0.832031 x 0.832031 x 1 mm.
VOXEL = ["0.000832031", "0.000832031", "0.001"]
CASES = {
    "VH_F_Vasculature__VHF_descending_aorta_a.ply": [],
    "VH_F_Vasculature__VHF_left_anterior_descending_artery.ply": [],
    "VH_F_Vasculature__VHF_right_coronary_artery.ply": [],
    "EdinGCA_3D_00090_large_intestine_DSJ-SF-.ply": ["--scale", *VOXEL],
    "EdinGCA_3D_00090_small_intestine_JIJ-DJJ.ply": ["--scale", *VOXEL],
}


@needs_shared
@pytest.mark.parametrize("mesh", sorted(CASES), ids=lambda m: m.split("_", 3)[-1][:24])
def test_real_mesh_extracts_simulates_60_frames_and_writes_output(mesh, tmp_cwd):
    scene = tmp_cwd / "scene.usda"
    assert main(["extract", str(MESHES / mesh), "-o", str(scene), *CASES[mesh]]) == 0
    out = tmp_cwd / "out.usdc"
    assert main(["run", str(scene), "-o", str(out), "--frames", "61", "--quiet"]) == 0
    assert check_output_problems(out, scene=scene, require_surface=True) == []
    st = Usd.Stage.Open(str(out))
    assert st.GetEndTimeCode() - st.GetStartTimeCode() == 60


def test_extract_of_a_bad_mesh_exits_2(tmp_cwd):
    (tmp_cwd / "bad.ply").write_text("not a mesh")
    assert main(["extract", "bad.ply", "-o", "s.usda"]) == 2
    assert main(["extract", "missing.stl", "-o", "s.usda"]) == 2
    assert main(["extract", "bad.ply", "-o", "s.usda", "--scale", "1", "2"]) == 2
    assert not (tmp_cwd / "s.usda").exists()
