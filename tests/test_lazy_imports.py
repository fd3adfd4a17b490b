"""A scene pays only for what it uses: reading and running a scene of curves imports neither
trimesh nor SciPy (the extraction of Mesh prims and the contact monitor's search for the deepest
overlap need them, and import them where they are used; scenes with a Mesh to extract are tested
through the same ``warp_tube.load_scene`` in ``test_extract_usd_inputs.py``). The two imports took
~0.25 s on a 2-core CPU: ``warp-tube run`` of the default scene, set-up 0.27 s against 0.52 s."""

import subprocess
import sys
from pathlib import Path

SCENES = Path(__file__).resolve().parents[1] / "scenes"

SCRIPT = """
import sys
import warp_tube

sim = warp_tube.Simulation(warp_tube.load_scene(sys.argv[1]), device="cpu")
sim.run(frames=3, output=sys.argv[2])
print(" ".join(sorted(m for m in ("scipy", "trimesh") if m in sys.modules)) or "none")
"""


def test_a_scene_of_curves_runs_without_importing_trimesh_or_scipy(tmp_path):
    r = subprocess.run([sys.executable, "-c", SCRIPT, str(SCENES / "default.usda"), str(tmp_path / "out.usdc")],
                       capture_output=True, text=True, timeout=300)  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert r.stdout.split()[-1] == "none", r.stdout
    assert (tmp_path / "out.usdc").stat().st_size > 0

