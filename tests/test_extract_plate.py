"""A closed plate is not a tube: its extraction leaves nearly all of the mesh off the thin "tube"
it finds across it, and says so (warp_tube.extract.tubelike); a short capsule does not."""

import trimesh

from warp_tube.extract.pipeline import extract_centerline
from warp_tube.extract.tubelike import MAX_LEFT_OUT, NOT_A_TUBE


def test_a_plate_is_not_tube_like():
    tube = extract_centerline(trimesh.creation.box(extents=(40.0, 40.0, 2.0)).subdivide_to_size(2.0))
    f = tube.fidelity.to_surface
    assert f.left_out / (f.counted + f.left_out) > MAX_LEFT_OUT  # (measured 0.99)
    assert any(w.startswith(NOT_A_TUBE) and "off the tube's rings" in w for w in tube.warnings)


def test_a_capsule_six_radii_long_is_a_tube():
    # its ends (one end radius of axis at each, and the caps) are the vertices left out: 15%
    tube = extract_centerline(trimesh.creation.capsule(height=20.0, radius=5.0, count=[32, 32]).subdivide_to_size(1.0))
    assert not [w for w in tube.warnings if w.startswith(NOT_A_TUBE)]
