"""warp-tube batch on CUDA: variant k of a batch against the same variant run alone on the GPU."""

from __future__ import annotations

import time

import numpy as np
import pytest
import warp as wp

from tests.test_batch import DEFAULT, E, FORCE, failing_world_among_others, near_axis_batches, stage_samples, variant_scene, write_table
from warp_tube.batch import run_batch
from warp_tube.cli import main as cli

pytestmark = [
    pytest.mark.gpu,
    pytest.mark.skipif(wp.get_cuda_device_count() == 0, reason="needs a CUDA device"),
]


def test_batch_on_cuda_equals_the_variant_run_alone(tmp_path):
    from pxr import Gf

    rows = [("100000", "(0, 0.02, 0)"), ("100000", "(0, 0.03, 0.01)"), ("60000", "(0.01, 0, 0.02)"), ("100000", "(0, -0.02, 0)")]
    table = write_table(tmp_path / "t.csv", [E, FORCE], rows)
    out = tmp_path / "out"
    result = run_batch(str(DEFAULT), str(out), str(table), frames=12, device="cuda:0", writers=1)
    assert result.ok == 4
    for k in (1, 3):
        e, f = rows[k]
        scene = variant_scene(tmp_path, f"v{k}", {E: float(e), FORCE: Gf.Vec3f(*eval(f))})
        alone = tmp_path / f"alone{k}.usdc"
        assert cli(["run", str(scene), "-o", str(alone), "--frames", "12", "--device", "cuda:0", "--quiet"]) == 0
        a, b = stage_samples(alone), stage_samples(out / f"variant_{k:05d}.usdc")
        assert a.keys() == b.keys()
        for name in a:
            # The same kernels on the same float32 inputs per world (the GPU's fast-math surface
            # kernels alike in both): float32 round-off, 1e-6 of the 20-unit tube (~16 ulps).
            assert max(np.abs(x - y).max() for x, y in zip(a[name][1], b[name][1])) <= 2e-5, name


def test_batch_on_cuda_arrays_match_files(tmp_path):
    rows = [(str(80000 + 5000 * k), f"(0, {0.01 + 0.001 * k}, 0)") for k in range(8)]
    table = write_table(tmp_path / "t.csv", [E, FORCE], rows)
    files = tmp_path / "files"
    arrays = tmp_path / "arrays"
    run_batch(str(DEFAULT), str(files), str(table), frames=6, device="cuda:0", chunk=3)
    run_batch(str(DEFAULT), str(arrays), str(table), frames=6, device="cuda:0", layout="arrays", surface=True)
    cl = np.load(arrays / "centerline.npy")
    for k in (0, 4, 7):
        s = stage_samples(files / f"variant_{k:05d}.usdc")["/World/Tube/Centerline.points"][1]
        # chunks of 3 against one chunk of 8: each world computes the same either way
        assert np.abs(cl[k] - np.stack(s)).max() <= 2e-5


def test_batch_on_cuda_lines_built_late_per_world(tmp_path):
    """Assistant lines built after the first frame: one chunk of eight against chunks of one, on
    CUDA."""
    _, _, together, apart, late = near_axis_batches(tmp_path, "cuda:0")
    assert late.sum() >= 2, late
    for k in range(8):
        a, b = stage_samples(together / f"variant_{k:05d}.usdc"), stage_samples(apart / f"variant_{k:05d}.usdc")
        for name in a:
            # each world computes the same in either chunk; 2e-5 as above (float32 round-off)
            assert max(np.abs(x - y).max() for x, y in zip(a[name][1], b[name][1])) <= 2e-5, (k, name)


def test_batch_on_cuda_frames_copied_back_in_many_windows(tmp_path, monkeypatch):
    """Windows of two frames and staging pieces of a few kB, each piece held back a little: every
    frame of every chunk comes back through several windows handed over while the simulation goes
    on (the windows in flight held to their limit, the copies still running while the next chunk
    captures its graphs), on the copying thread's own stream; the arrays equal those of one
    window a chunk, element for element (the same kernels: only the copy differs)."""
    import warp_tube.batch.framestore as framestore

    rows = [(str(80000 + 5000 * k), f"(0, {0.01 + 0.001 * k}, 0.002)") for k in range(7)]
    table = write_table(tmp_path / "t.csv", [E, FORCE], rows)
    one = tmp_path / "one"
    run_batch(str(DEFAULT), str(one), str(table), frames=11, device="cuda:0", layout="arrays", surface=True, chunk=3)
    per_frame = 3 * 12 * (21 + 2 * 400)  # about one frame of a 3-world chunk's outputs [bytes]
    monkeypatch.setattr(framestore, "WINDOW_BYTES", 2 * per_frame)
    monkeypatch.setattr(framestore, "STAGING_BYTES", 8192)
    monkeypatch.setattr(framestore, "MAX_WINDOWS_IN_FLIGHT", 2)
    copy = framestore._parallel_copy

    def slow_copy(dst, src):  # copies back still running when the next chunk captures its graphs
        time.sleep(0.01)
        copy(dst, src)

    monkeypatch.setattr(framestore, "_parallel_copy", slow_copy)
    many = tmp_path / "many"
    run_batch(str(DEFAULT), str(many), str(table), frames=11, device="cuda:0", layout="arrays", surface=True, chunk=3)
    for name in ("centerline.npy", "surface.npy"):
        a, b = np.load(one / name), np.load(many / name)
        assert a.shape == b.shape and np.isfinite(a).all()
        assert np.array_equal(a, b), name


@pytest.mark.skipif(wp.get_cuda_device_count() < 2, reason="needs two CUDA devices")
def test_batch_on_two_gpus_equals_one(tmp_path):
    """Chunks spread over two GPUs (a simulating process each, frames copied back on each
    process's own thread and stream) give the bytes one GPU gives, both layouts."""
    import filecmp

    rows = [(str(80000 + 5000 * k), f"(0, {0.01 + 0.001 * k}, 0.002)") for k in range(6)]
    table = write_table(tmp_path / "t.csv", [E, FORCE], rows)
    for layout, names in (("arrays", ["centerline.npy", "surface.npy", "summary.csv"]),
                          ("files", [f"variant_{k:05d}.usdc" for k in range(6)] + ["summary.csv"])):  # fmt: skip
        one, two = tmp_path / f"{layout}1", tmp_path / f"{layout}2"
        run_batch(str(DEFAULT), str(one), str(table), frames=8, layout=layout, surface=True, workers=1, chunk=2)
        result = run_batch(str(DEFAULT), str(two), str(table), frames=8, layout=layout, surface=True, workers=2, chunk=2)
        assert result.devices == ["cuda:0", "cuda:1"] and result.ok == 6
        for n in names:
            assert filecmp.cmp(one / n, two / n, shallow=False), (layout, n)



@pytest.mark.parametrize("scene, tube", [(DEFAULT, "/World/Tube"), (DEFAULT.parent / "intestine.usda", "/World/Bowel")])
def test_batch_on_cuda_a_failing_world_among_others(tmp_path, scene, tube):
    """One forced substep for all, beyond the stiff variant's stability bound: its world blows up
    while the frames of the others are queued and read one behind the other; the others give
    what they give alone. The default tube (21 points) tests its contact pairs, the intestine
    (41 points) the contact grid, which then holds the failed world's blown-up points."""
    failing_world_among_others(tmp_path, scene, tube, "cuda:0")

