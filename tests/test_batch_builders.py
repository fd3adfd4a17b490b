"""A batch's chunks of plain values share their surface builders (warp_tube/batch/worlds.py): a
chunk made of the same rest points, spokes and world count as the last takes its builders again,
and its surfaces are those a builder of its own gives."""

import dataclasses
from pathlib import Path

import numpy as np

from warp_tube import load_scene
from warp_tube.batch.worlds import build_worlds, initial_state, release_builders

SCENES = Path(__file__).resolve().parents[1] / "scenes"


def _chunk(moduli, points=None):
    base = load_scene(SCENES / "default.usda")
    t = base.tubes[0]
    if points is not None:
        t = dataclasses.replace(t, points=points)
    return [dataclasses.replace(base, tubes=(dataclasses.replace(t, params=dataclasses.replace(t.params, youngs_modulus=e)),))
            for e in moduli]  # fmt: skip


def _surface(worlds):
    state, _, _ = initial_state(worlds)
    pts, nrm = worlds.surfaces[0].compute(state.node_q)
    return pts.numpy().copy(), nrm.numpy().copy()


def test_a_chunk_like_the_last_takes_its_surface_builders():
    release_builders()
    first = build_worlds(_chunk([2e4, 5e4, 1e5]), "cpu", True)
    again = build_worlds(_chunk([3e4, 4e4, 6e4]), "cpu", True)
    assert again.surfaces[0] is first.surfaces[0]  # the same rest shape, spokes and world count
    fewer = build_worlds(_chunk([3e4, 4e4]), "cpu", True)  # (the last chunk of a batch: fewer worlds)
    assert fewer.surfaces[0] is not first.surfaces[0]
    base = load_scene(SCENES / "default.usda").tubes[0].points
    moved = build_worlds(_chunk([3e4, 4e4], points=base + np.array([0.0, 0.0, 0.001])), "cpu", True)
    assert moved.surfaces[0] is not fewer.surfaces[0]  # another rest shape: a builder of its own
    # What a reused builder gives is what a new one gives, to the bit (the same arrays, written afresh).
    release_builders()
    own = build_worlds(_chunk([3e4, 4e4, 6e4]), "cpu", True)
    assert own.surfaces[0] is not first.surfaces[0]
    for a, b in zip(_surface(again), _surface(own)):
        np.testing.assert_array_equal(a, b)
    release_builders()
