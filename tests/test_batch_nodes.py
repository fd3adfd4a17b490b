"""Per-node parameters kept from planning (warp_tube.batch.nodes) are the ones building a chunk's
worlds works out itself: the same function of the same tubes, so equal bit for bit, for chunks
that are a run of the planned variants, a scattered pick of them, and variants equal to an
earlier one; beyond the limit nothing is kept and the build works them out again."""

import dataclasses
from pathlib import Path

import numpy as np

from warp_tube import load_scene
from warp_tube.batch.nodes import KeptNodes
from warp_tube.batch.plan import run_choices
from warp_tube.batch.worlds import WorldArrays, build_worlds

SCENES = Path(__file__).resolve().parents[1] / "scenes"


def _variants():
    base = load_scene(SCENES / "default.usda")
    t = base.tubes[0]
    out = []
    for e, d in ((2e4, 0.0), (5e4, 0.2), (2e4, 0.0), (1e5, 0.1), (3e4, 0.0)):  # the third equals the first
        params = dataclasses.replace(t.params, youngs_modulus=e, spring_damping=d, density=900.0 + e / 1e3)
        out.append(dataclasses.replace(base, tubes=(dataclasses.replace(t, params=params),) + base.tubes[1:]))
    return out


def _fields():
    return tuple(f.name for f in dataclasses.fields(WorldArrays))


def test_kept_rows_equal_the_build_of_each_chunk():
    scenes = _variants()
    keep = KeptNodes(len(scenes))
    run_choices(scenes, keep=keep)
    for pick in ((0, 1, 2), (1, 3, 4), (4, 0), (2,)):
        kept = keep.take(pick)
        assert kept is not None, pick
        own = build_worlds([scenes[i] for i in pick], "cpu", surface=False).host
        for f in _fields():
            assert np.array_equal(kept[f], getattr(own, f)), (pick, f)  # bit for bit: the same arithmetic
        w = build_worlds([scenes[i] for i in pick], "cpu", surface=False, per_node=kept)
        assert w.model.features == build_worlds([scenes[i] for i in pick], "cpu", surface=False).model.features


def test_beyond_the_limit_nothing_is_kept():
    scenes = _variants()
    keep = KeptNodes(len(scenes), limit=10)  # fewer nodes than one block
    run_choices(scenes, keep=keep)
    assert keep.take((0, 1)) is None
    assert keep.nodes == 0


def test_a_bad_shape_is_refused():
    scenes = _variants()
    keep = KeptNodes(len(scenes))
    run_choices(scenes, keep=keep)
    try:
        build_worlds(scenes[:2], "cpu", surface=False, per_node=keep.take((0, 1, 2)))
    except ValueError as e:
        assert "expected (2," in str(e)
    else:
        raise AssertionError("three worlds' parameters taken for two")


def test_what_follows_from_a_shared_rest_shape_is_each_world_own():
    """Worlds that share their rest positions (plain variants) have the frame checks' extents and
    the contact test's rest arclengths worked out for one world and repeated: the numbers each
    world's own rest positions give, bit for bit; worlds with rest shapes of their own work them
    out each."""
    from warp_tube.batch.checks import WorldChecks
    from warp_tube.batch.contacts import WorldContacts
    from warp_tube.sim.proximity import rest_arclength

    scenes = _variants()
    t = scenes[0].tubes[0]
    bent = dataclasses.replace(scenes[0], tubes=(dataclasses.replace(t, points=t.points * np.array([1.2, 1.0, 1.0])),) + scenes[0].tubes[1:])
    for group, shared in ((scenes, True), ([scenes[0], bent, scenes[1]], False)):
        w = build_worlds(group, "cpu", surface=False)
        assert w.rest_shared is shared
        rest, starts = w.host.node_rest_q, w.prim_start
        # each world's extent and arclengths from its own rows, as without the shortcut
        extent = np.max([np.ptp(rest[:, a:b], axis=1).max(axis=1) for a, b in zip(starts[:-1], starts[1:])], axis=0)
        arc = rest_arclength(rest, np.asarray(w.model.host.tube_node_start, dtype=np.int64))
        checks, contacts = WorldChecks(w, group[0].settings.gravity, False), WorldContacts(w)
        assert np.array_equal(checks.device_checks.extent[:, 0], extent)
        assert np.array_equal(contacts.monitor.arc, arc.reshape(-1))
