"""A scene's tube prims of one kind rebuilt by one shared builder (warp_tube.surface.prims): each
prim's points, normals and bounds are what a builder of that prim alone gives, bit for bit, and
its topology is the one a builder of its own makes."""

import numpy as np
import pytest
import warp as wp

from tests.conftest import check_output_problems, needs_shared
from warp_tube import Simulation
from warp_tube.scene.spec import Scene, SimulationSettings, StageInfo, TubeParams, TubeSpec
from warp_tube.surface.builder import SurfaceBuilder
from warp_tube.surface.prims import PrimSurface
from warp_tube.surface.topology import build_topology, split_topology, tube_topology


def _prim(rng, path, spokes, caps, measured, normal):
    counts = rng.integers(3, 12, rng.integers(1, 4))
    pts = []
    for c in counts:  # arcs of random bend, scattered
        th = np.linspace(0.0, rng.uniform(0.5, 2.5), c)
        pts.append(0.1 * np.stack([np.sin(th), 1 - np.cos(th), 0.2 * th], 1) + rng.normal(0.0, 0.5, 3))
    pts = np.concatenate(pts)
    radius = 0.01 * (1 + 0.3 * rng.random(len(pts)))
    lengths = radius[:, None] * (1 + 0.2 * rng.random((len(pts), spokes))) if measured else None
    params = TubeParams(density=1000.0, youngs_modulus=1e5, damping=2.0, spokes=spokes, caps=caps, reference_normal=normal)
    pinned = np.r_[0, np.cumsum(counts)[:-1]]
    return TubeSpec(path, pts, counts, radius, params, pinned=pinned, spoke_lengths=lengths)


def _scene(seed):
    rng = np.random.default_rng(seed)
    kinds = [(8, True, True, None), (8, True, False, (0.0, 0.0, 1.0)), (8, True, True, None), (6, False, False, None),
             (6, False, True, None), (8, True, False, None), (8, True, True, (1.0, 0.0, 0.0))]  # fmt: skip
    tubes = tuple(_prim(rng, f"/World/T{k}", *kind) for k, kind in enumerate(kinds))
    stage = StageInfo(meters_per_unit=0.01, up_axis="Z", time_codes_per_second=60.0, start_time_code=0.0, end_time_code=4.0)
    return Scene(tubes, settings=SimulationSettings(gravity=(0.0, 0.0, -9.81)), stage=stage)


DEVICES = ["cpu", pytest.param("cuda:0", marks=[pytest.mark.gpu, pytest.mark.skipif(wp.get_cuda_device_count() == 0,
                                                                                   reason="needs a CUDA device")])]  # fmt: skip


@pytest.mark.parametrize("device", DEVICES)
def test_prims_of_one_kind_share_a_builder_and_each_gets_its_own_surface(device):
    scene = _scene(4)
    sim = Simulation(scene, device=device)
    # runs of prims of one kind: (T0 T1 T2) (T3 T4) (T5 T6): three builders for seven prims
    assert len(sim._surface_builders) == 3 and all(isinstance(s, PrimSurface) for s in sim.surfaces)
    for _ in range(4):
        sim.step()
    got = sim.surface()
    q = sim.state.node_q
    mpu = scene.stage.meters_per_unit
    starts = sim._prim_start
    for k, t in enumerate(scene.tubes):  # each prim by a builder of its own, as before prims shared one
        lengths = t.spoke_lengths if t.spoke_lengths is not None else np.repeat(t.radius[:, None], t.params.spokes, axis=1)
        b = SurfaceBuilder(starts[k] + np.r_[0, np.cumsum(t.curve_counts)], t.points, t.params.spokes, lengths,
                           t.params.reference_normal, frames=t.params.frames, caps=t.params.caps, device=device)  # fmt: skip
        pts, nrm = b.compute(q)
        assert np.array_equal(got[k][0], pts.numpy()[0] / mpu) and np.array_equal(got[k][1], nrm.numpy()[0])
        assert np.array_equal(got[k][2], b.extent().numpy()[0] / mpu)
        for f in ("vertex_count", "face_vertex_indices", "st"):
            assert np.array_equal(getattr(sim.surfaces[k], f), getattr(b.topology, f))
    p, n = sim.surfaces[1].compute(q)  # a prim's own compute, as a builder's
    assert np.array_equal(p.numpy()[0] / mpu, got[1][0]) and np.array_equal(sim.surfaces[1].extent().numpy()[0] / mpu, got[1][2])


@pytest.mark.parametrize("caps", [False, True])
def test_split_topology_is_each_prims_own(caps):
    rng = np.random.default_rng(3)
    prims = []
    for _ in range(7):
        counts = rng.integers(2, 12, rng.integers(1, 4))
        prims.append((counts, rng.normal(0.0, 1.0, (counts.sum(), 3)).cumsum(0), 0.1 + 0.1 * rng.random((counts.sum(), 5))))
    starts = np.r_[0, np.cumsum(np.concatenate([c for c, _, _ in prims]))]
    lengths = np.concatenate([x for _, _, x in prims])
    mean = lengths.mean(axis=1)
    cap_radius = np.stack([mean[starts[:-1]], mean[starts[1:] - 1]], axis=1) if caps else None
    topo = build_topology(starts, 5, caps=caps, rest_q=np.concatenate([p for _, p, _ in prims]), cap_radius=cap_radius)
    parts = split_topology(topo, starts, np.r_[0, np.cumsum([len(c) for c, _, _ in prims])])
    for (counts, pts, lengths), (sub, body, cap) in zip(prims, parts):
        own = tube_topology(np.r_[0, np.cumsum(counts)], 5, lengths, caps, pts)
        for f in ("spokes", "caps", "hub_count", "vertex_count", "st_interpolation"):
            assert getattr(own, f) == getattr(sub, f)
        for f in ("face_vertex_counts", "face_vertex_indices", "st", "ring_hub", "ring_kind", "ring_cos", "ring_sin", "ring_vertex"):
            a, b = getattr(own, f), getattr(sub, f)
            assert a.dtype == b.dtype and np.array_equal(a, b), f
        assert (body.stop - body.start) + (cap.stop - cap.start) == own.vertex_count


@needs_shared
def test_a_run_of_many_prims_writes_a_valid_stage(tmp_path):
    from pxr import Usd, UsdGeom

    scene = _scene(7)
    out = tmp_path / "many.usdc"
    Simulation(scene, device="cpu").run(output=str(out))
    assert check_output_problems(out, require_surface=True) == []
    stage = Usd.Stage.Open(str(out))
    for t in scene.tubes:  # each prim's own Surface mesh, capped or not as its prim says
        mesh = UsdGeom.Mesh(stage.GetPrimAtPath(f"{t.path}/Surface"))
        assert len(mesh.GetPointsAttr().Get(4.0)) == len(mesh.GetNormalsAttr().Get(4.0))


def test_surface_arrays_are_the_callers_on_the_cpu():
    # what surface() returns is the caller's: not rewritten by the next frame (on the CPU Warp's
    # numpy() views the builder's own arrays)
    from tests.conftest import SCENES
    from warp_tube import load_scene

    sim = Simulation(load_scene(str(SCENES / "default.usda")), device="cpu")
    sim.step()
    first = sim.surface()
    kept = [tuple(np.array(a) for a in part) for part in first]
    for _ in range(3):
        sim.step()
        sim.surface()
    for part, copy in zip(first, kept):
        for a, b in zip(part, copy):
            assert np.array_equal(a, b)
