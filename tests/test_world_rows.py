"""Rows of world-major arrays read and written by world index (the batch's assistant-line rule):
the gather and scatter kernels against NumPy indexing, on the CPU and on CUDA where present.
Plain copies, so the comparisons are exact."""

import numpy as np
import pytest
import warp as wp

from warp_tube.batch.rows import WorldRows


def _devices():
    out = [("cpu", False), ("cpu", True)]
    if wp.is_cuda_available():
        out.append(("cuda:0", True))
    return out


@pytest.mark.parametrize("device,kernels", _devices())
def test_take_and_put_rows_equal_numpy_indexing(device, kernels):
    rng = np.random.default_rng(3)
    W, C = 9, 7
    v = rng.normal(size=(W, C, 3)).astype(np.float32)
    f = rng.normal(size=(W, C)).astype(np.float32)
    av = wp.array(v, dtype=wp.vec3, device=device)
    af = wp.array(f, dtype=float, device=device)
    rows = np.array([7, 0, 4])
    c0, c1 = np.int64(2), np.int64(6)  # (column bounds as NumPy integers, as a model's host arrays give them)
    access = WorldRows(device, kernels=kernels)
    (got,) = access.take((av,), rows, c0, c1)
    np.testing.assert_array_equal(got, v[rows, 2:6])
    two = access.take((av, av), np.array([1]), 0, C)  # several arrays share the read-back buffer
    np.testing.assert_array_equal(two[0], v[[1]])
    np.testing.assert_array_equal(two[1], v[[1]])

    nv = rng.normal(size=(3, 5, 3)).astype(np.float32)
    nf = rng.normal(size=(3, 5)).astype(np.float32)
    access.put(rows, [(av, np.int64(1), nv, 0, np.int64(5)), (af, 3, nf, np.int64(1), 4)])
    want_v, want_f = v.copy(), f.copy()
    want_v[rows, 1:6] = nv
    want_f[rows, 3:7] = nf[:, 1:5]
    np.testing.assert_array_equal(av.numpy(), want_v)  # every other entry unchanged
    np.testing.assert_array_equal(af.numpy(), want_f)
