"""The contact monitor and the hollow-tube test on CUDA: the same answers as on the CPU."""

from __future__ import annotations

import numpy as np
import pytest
import warp as wp

from warp_tube.sim.proximity import ContactMonitor

from .test_contact import _bifurcation
from .test_extract_hollow import OUTER, _hose

pytestmark = [
    pytest.mark.gpu,
    pytest.mark.skipif(wp.get_cuda_device_count() == 0, reason="needs a CUDA device"),
]


@pytest.mark.parametrize("small", [0, 10**9])  # hash grid, all pairs
def test_junction_contacts_on_cuda_equal_the_cpu(small):
    """The bifurcation of tests/test_contact.py swung to 80 and 60 degrees: the deepest overlap on
    cuda:0 is the CPU's to the bit (the same float32 distances)."""
    n, r = 31, 0.02
    rest = _bifurcation(90.0)
    start = np.array([0, n, 2 * n, 3 * n])
    got = {}
    for device in ("cpu", "cuda:0"):
        mon = ContactMonitor(rest, np.full(len(rest), r), start, device=device, small=small)
        for angle in (80.0, 60.0):
            q = wp.array(_bifurcation(angle), dtype=wp.vec3, device=device)
            got[device, angle] = mon.deepest(q)
    for angle in (80.0, 60.0):
        np.testing.assert_array_equal(got["cuda:0", angle], got["cpu", angle])
    assert got["cpu", 80.0][0] == 0.0 and got["cpu", 60.0][0] < 0.0


def test_a_hose_is_found_hollow_on_cuda():
    """The hose with flat rims of tests/test_extract_hollow.py, its walls' nesting tested on cuda:0:
    the outer wall kept, the bore's size from the walls' areas (0.8)."""
    from warp_tube.extract import hollow

    with wp.ScopedDevice("cuda:0"):
        wall, bore = hollow.outer_wall(_hose("rims"), "hose")
    assert bore is not None and abs(bore.ratio - 0.8) < 0.01
    r = np.linalg.norm(np.asarray(wall.vertices)[:, [1]], axis=1)  # (y: across the bend's plane)
    assert r.max() == pytest.approx(OUTER, rel=1e-6)
