"""A mesh shaped like a Y: the tube follows the longest route between its ends and the branch it
leaves out, as long as a good part of the tube, is warned of (warp_tube.extract.tube_check)."""

import numpy as np

from tests.test_extract import voxel_surface
from warp_tube.extract.pipeline import extract_centerline
from warp_tube.extract.tube_check import LARGE_BRANCH, tube_warnings


def y_mesh(h=0.125):
    """A trunk along x (length 16, radius 1.5) and an arm along +y from x = 8 (radius 1.2, tip at
    y = 10): the longest route runs from the trunk's x = 0 end up the arm, leaving the trunk's
    other half (about 8 of the trunk's axis beyond the junction) out."""
    x, y, z = np.meshgrid(np.arange(-1, 17, h), np.arange(-2, 11, h), np.arange(-2, 2, h), indexing="ij")
    trunk = (x >= 0) & (x <= 16) & (y**2 + z**2 <= 1.5**2)
    arm = (y >= 0) & (y <= 10) & ((x - 8) ** 2 + z**2 <= 1.2**2)
    return voxel_surface(trunk | arm, h)


def test_a_y_warns_of_the_route_left_out():
    tube = extract_centerline(y_mesh())
    assert len(tube.branches) == 1
    _, branch = tube.branches[0]
    assert branch >= LARGE_BRANCH * tube.length  # (about half: 9.1 of 17.1)
    found = [w for w in tube_warnings(tube, tube.fidelity, units="units") if "side branch" in w]
    assert len(found) == 1 and "longest route" in found[0] and f"{branch:.3g} units long" in found[0]


def test_a_small_side_branch_is_one_and_not_warned_of():
    # one stub, one branch: its two flanks leave the main tube's cover before its middle does (two
    # regions, whose tips lie within the tube's radius of each other)
    tube = extract_centerline(y_mesh_short())
    assert len(tube.branches) == 1 and tube.branches[0][1] < LARGE_BRANCH * tube.length
    assert all("side branch" not in w for w in tube_warnings(tube, tube.fidelity, units="units"))


def y_mesh_short(h=0.125):
    """The trunk with a stub along +y to y = 2.5: a side branch of about 2.9 from the axis, 18% of
    the tube's length (a vessel's side branches: the shared meshes' largest is 14%)."""
    x, y, z = np.meshgrid(np.arange(-1, 17, h), np.arange(-2, 4, h), np.arange(-2, 2, h), indexing="ij")
    trunk = (x >= 0) & (x <= 16) & (y**2 + z**2 <= 1.5**2)
    stub = (y >= 0) & (y <= 2.5) & ((x - 8) ** 2 + z**2 <= 0.9**2)
    return voxel_surface(trunk | stub, h)
