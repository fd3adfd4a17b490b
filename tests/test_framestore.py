"""Output frames gathered on the device and copied back in windows (warp_tube.batch.framestore),
against the same arrays computed with NumPy."""

import numpy as np
import pytest
import warp as wp

import warp_tube.batch.framestore as framestore
from warp_tube.batch.framestore import FrameStore


def frames(seed, F, W, V):
    rng = np.random.default_rng(seed)
    return rng.normal(size=(F, W, V, 3)).astype(np.float32) * 10.0


def run_store(monkeypatch, staged, window_bytes, staging_bytes):
    monkeypatch.setattr(framestore, "STAGING_BYTES", staging_bytes)
    monkeypatch.setattr(framestore, "COPY_THREADS", 3)
    monkeypatch.setattr(framestore, "PARALLEL_COPY_MIN", 1000)
    F, W, V, P = 7, 5, 300, 2
    pts, nrm = frames(0, F, W, V), frames(1, F, W, V)
    ext = frames(2, F, W, P * 2).reshape(F, W, P, 2, 3)
    cl = frames(3, F, W, 11)
    host = {"centerline": np.zeros_like(cl), "points": np.zeros_like(pts), "normals": np.zeros_like(nrm), "extent": np.zeros_like(ext)}
    store = FrameStore(host, "cpu", window_bytes=window_bytes, staged=staged)
    unit = 0.01
    for f in range(F):
        store.store(f, "centerline", wp.array(cl[f] * unit, dtype=wp.vec3, device="cpu"), unit)
        for p, cols in enumerate((slice(0, 120), slice(120, V))):
            store.store(f, "points", wp.array(np.ascontiguousarray(pts[f][:, cols]) * unit, dtype=wp.vec3, device="cpu"), unit, columns=cols)
            store.store(f, "normals", wp.array(np.ascontiguousarray(nrm[f][:, cols]), dtype=wp.vec3, device="cpu"), 1.0, columns=cols)
            store.store(f, "extent", wp.array(ext[f, :, p] * unit, dtype=wp.vec3, device="cpu"), unit, prim=p)
    store.flush()
    # The stored frames are src / unit in float32, as NumPy divides: exactly those values.
    for name, ref in (("centerline", cl), ("points", pts), ("extent", ext)):
        np.testing.assert_array_equal(host[name], (ref * np.float32(unit)) / unit)
    np.testing.assert_array_equal(host["normals"], nrm)
    return store


def test_frames_straight_into_the_host_arrays(monkeypatch):
    store = run_store(monkeypatch, staged=False, window_bytes=1 << 30, staging_bytes=1 << 20)
    assert store.window == 7


def test_windows_copied_back_through_a_small_staging_buffer(monkeypatch):
    # windows of 5 frames (one frame of all four outputs is 36.9 kB) and staging pieces of 3
    # frames of the largest output: every path of the copy (a full window, a short last piece and
    # a short last window, the threads' slices) is taken
    store = run_store(monkeypatch, staged=True, window_bytes=200_000, staging_bytes=60_000)
    assert store.window == 5


def test_windows_copied_straight_into_page_locked_arrays(monkeypatch):
    # host arrays in page-locked memory take each window in one copy from the device buffer; no
    # page-locked memory without a CUDA driver here, so the arrays are only taken for such
    copied_through_staging = []
    monkeypatch.setattr(framestore, "is_pinned", lambda a: True)
    monkeypatch.setattr(framestore, "_parallel_copy", lambda dst, src: copied_through_staging.append(dst.shape))
    store = run_store(monkeypatch, staged=True, window_bytes=200_000, staging_bytes=60_000)
    assert store.window == 5 and not copied_through_staging


@pytest.mark.gpu
@pytest.mark.skipif(not wp.get_cuda_device_count(), reason="page-locked host memory needs a CUDA driver")
def test_page_locked_arrays_are_known_by_address():
    a = framestore.pinned_empty((4, 6, 3))
    assert a.shape == (4, 6, 3) and a.dtype == np.float32
    assert framestore.is_pinned(a) and framestore.is_pinned(a[1:3]) and not framestore.is_pinned(np.zeros((4, 6, 3), np.float32))
    framestore.release_pinned(a)
    assert not framestore.is_pinned(a)
