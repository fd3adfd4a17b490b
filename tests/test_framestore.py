"""Output frames gathered on the device and copied back in windows (warp_tube.batch.framestore),
against the same arrays computed with NumPy."""

import numpy as np
import warp as wp

import warp_tube.batch.framestore as framestore
from warp_tube.batch.framestore import FrameStore


def frames(seed, F, W, V):
    rng = np.random.default_rng(seed)
    return rng.normal(size=(F, W, V, 3)).astype(np.float32) * 10.0


def run_store(monkeypatch, staged, window_bytes, staging_bytes, wait="flush"):
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
    if wait == "flush":
        store.flush()
    else:  # the copy back runs on its own thread: the future says when every frame is there
        store.finish().result()
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
    # frames of the largest output (each half of the staging buffer, used in turn): every path of
    # the copy (a full window, a short last piece and a short last window, the threads' slices)
    # is taken
    store = run_store(monkeypatch, staged=True, window_bytes=200_000, staging_bytes=120_000)
    assert store.window == 5


def test_windows_handed_over_and_awaited_through_the_future(monkeypatch):
    # the same windows, waited for as a batch's writers do (finish() and its future)
    store = run_store(monkeypatch, staged=True, window_bytes=200_000, staging_bytes=120_000, wait="future")
    assert store.window == 5 and store.pending.done()


def test_a_failed_copy_back_is_reported_once(monkeypatch):
    """A copy back that fails raises from its chunk's future (and so in that chunk's writers), and
    the next chunk's windows (waiting for it to leave the windows in flight) are copied back as
    usual: the failure is not raised again elsewhere."""
    import pytest

    monkeypatch.setattr(framestore, "MAX_WINDOWS_IN_FLIGHT", 1)
    host = {"centerline": np.zeros((4, 2, 5, 3), dtype=np.float32)}
    store = FrameStore(host, "cpu", window_bytes=2 * 2 * 5 * 12, staged=True)  # windows of 2 frames

    def broken(dst, src):
        raise OSError("disk gone")

    monkeypatch.setattr(framestore, "_parallel_copy", broken)
    for f in range(2):
        store.store(f, "centerline", wp.array(np.ones((2, 5, 3), dtype=np.float32), dtype=wp.vec3, device="cpu"))
    with pytest.raises(OSError, match="disk gone"):
        store.finish().result()
    monkeypatch.undo()
    monkeypatch.setattr(framestore, "MAX_WINDOWS_IN_FLIGHT", 1)
    again = FrameStore(host, "cpu", window_bytes=2 * 2 * 5 * 12, staged=True)
    ref = frames(4, 4, 2, 5)
    for f in range(4):
        again.store(f, "centerline", wp.array(ref[f], dtype=wp.vec3, device="cpu"))
    again.finish().result()
    assert np.array_equal(host["centerline"], ref)


def test_windows_copied_back_in_place_where_two_do_not_fit(monkeypatch):
    # a device with room for one window only: each window is copied back before the frames go
    # on, in the same buffers; the same arrays
    monkeypatch.setattr(framestore, "_window_memory", lambda device: 250_000.0)
    store = run_store(monkeypatch, staged=True, window_bytes=200_000, staging_bytes=120_000, wait="future")
    assert store.window == 5 and store.pending.done()


def test_a_source_that_does_not_fit_its_columns_is_refused():
    """A prim's points stored into columns of another width would write beside them: refused."""
    host = {"points": np.zeros((2, 3, 10, 3), dtype=np.float32)}
    store = FrameStore(host, "cpu", staged=True, window_bytes=1 << 20)
    src = wp.zeros((3, 4), dtype=wp.vec3, device="cpu")
    store.store(0, "points", src, 1.0, columns=slice(6, 10))  # fits
    for cols in (slice(0, 5), slice(8, 12)):
        try:
            store.store(0, "points", src, 1.0, columns=cols)
        except ValueError as e:
            assert "does not fit" in str(e)
        else:
            raise AssertionError(f"columns {cols} taken for a source of 4")


def test_windows_buffers_reused_once_copied_back(monkeypatch):
    """A window copied back gives its device buffers to a later window (of this store or the next
    chunk's) instead of new ones; the frames are the same. With one window in flight at a time,
    a window takes the buffers of one copied back: at most two sets for four windows (one, where
    each copy back ends before the next window starts: the copying thread's timing)."""
    monkeypatch.setattr(framestore, "MAX_WINDOWS_IN_FLIGHT", 1)
    monkeypatch.setattr(framestore, "_window_memory", lambda device: 1e9)  # (room for windows in flight)
    monkeypatch.setattr(framestore, "_free_windows", {})
    taken = []
    window_buffers = framestore._window_buffers

    def counted(device, shapes):
        b = window_buffers(device, shapes)
        taken.append(id(b))
        return b

    monkeypatch.setattr(framestore, "_window_buffers", counted)
    host = {"centerline": np.zeros((7, 2, 5, 3), dtype=np.float32)}
    ref = frames(5, 7, 2, 5)
    store = FrameStore(host, "cpu", window_bytes=2 * 2 * 5 * 12, staged=True)  # windows of 2 frames
    for f in range(7):
        store.store(f, "centerline", wp.array(ref[f], dtype=wp.vec3, device="cpu"))
    store.finish().result()
    assert np.array_equal(host["centerline"], ref)
    assert len(taken) == 4 and len(set(taken)) <= 2, taken  # (4 windows: frames 0-1, 2-3, 4-5, 6)
    # the next store of these shapes starts in a kept window, and writes the same frames
    again = FrameStore(host, "cpu", window_bytes=2 * 2 * 5 * 12, staged=True)
    assert id(again.buffers) in taken
    host["centerline"][:] = 0.0
    for f in range(7):
        again.store(f, "centerline", wp.array(ref[f], dtype=wp.vec3, device="cpu"))
    again.finish().result()
    assert np.array_equal(host["centerline"], ref)
    framestore.release_windows()
    assert framestore._free_windows == {}
