"""Subnormals flushed to zero on the threads that run CPU kernels (:mod:`warp_tube.runtime.float_mode`).

The mode, not its speed, is tested here (benchmarks/bench_long_run.py measures the speed). The
oracle is IEEE arithmetic: 1e-30 * 1e-10 = 1e-40 is below float32's smallest normal (1.18e-38), so
it is the subnormal 1e-40 (to float32 rounding) with IEEE subnormals and exactly 0 with
flush-to-zero; a subnormal operand 1e-40 times 1e30 is 1e-10 with IEEE subnormals and 0 with
denormals-are-zero, which must stay off (it crashes SciPy's cKDTree on the same thread).
"""

from __future__ import annotations

import json
import pathlib
import platform
import subprocess
import sys
import threading

import numpy as np
import pytest
import warp as wp

from warp_tube.runtime.float_mode import flush_subnormals_on_this_thread
from warp_tube.runtime.warp_setup import init_warp

ROOT = pathlib.Path(__file__).resolve().parents[1]
_S = np.linspace(-1.0, 1.0, 101)
#: two straight lines of points crossing 0.15 apart, with coordinates at exactly 0
CROSS_POINTS = np.concatenate([np.stack([_S, 0 * _S, 0 * _S], 1), np.stack([0 * _S, _S, 0 * _S + 0.15], 1)])

pytestmark = pytest.mark.skipif(
    platform.machine().lower() not in ("x86_64", "amd64") or not wp.is_cpu_available(),
    reason="flush-to-zero is set on x86-64 CPUs only",
)


@wp.kernel(enable_backward=False)
def product_kernel(a: wp.array[wp.float32], b: wp.array[wp.float32], out: wp.array[wp.float32]):
    i = wp.tid()
    out[i] = a[i] * b[i]


def cpu_products(a, b) -> list[float]:
    """``a[i] * b[i]`` in float32 by a Warp kernel on the CPU, launched from the calling thread."""
    out = wp.zeros(len(a), dtype=wp.float32, device="cpu")
    wp.launch(product_kernel, dim=len(a), inputs=[wp.array(a, dtype=wp.float32, device="cpu"),
              wp.array(b, dtype=wp.float32, device="cpu"), out], device="cpu")  # fmt: skip
    return [float(x) for x in out.numpy()]


def subnormal_probe() -> list[float]:
    """A subnormal result (1e-30 * 1e-10) and a subnormal operand (1e-40 * 1e30), on the CPU.

    The operand 1e-40 = 71362 * 2**-149 is made from its bits: converting 1e-40 to float32 would
    itself be flushed to 0 on a thread with flush-to-zero.
    """
    a = np.array([1e-30, 0.0], dtype=np.float32)
    a[1:] = np.array([71362], dtype=np.uint32).view(np.float32)
    return cpu_products(a, np.array([1e-10, 1e30], dtype=np.float32))


def test_subnormal_results_are_zero_after_init_warp_and_operands_are_kept():
    init_warp()
    assert flush_subnormals_on_this_thread()  # set on this thread, and reports it
    result, operand = subnormal_probe()
    assert result == 0.0
    assert operand == pytest.approx(1e-10, rel=1e-3)  # denormals-are-zero is off (1e-40: ~3 digits)
    # Normal numbers are untouched: 1e-20 * 1e-10 = 1e-30 > 1.18e-38, to float32 rounding.
    (normal,) = cpu_products([1e-20], [1e-10])
    assert normal == pytest.approx(1e-30, rel=1e-6)


def test_the_mode_is_per_thread_and_set_once():
    # A thread started afterwards may inherit the mode (Linux copies it), so each thread is asked
    # in its own right: the call works on a thread of its own and is idempotent there.
    results = []

    def worker():
        results.append((flush_subnormals_on_this_thread(), flush_subnormals_on_this_thread(), subnormal_probe()))

    init_warp()
    t = threading.Thread(target=worker)
    t.start()
    t.join()
    assert [(a, b, c[0]) for a, b, c in results] == [(True, True, 0.0)]


def test_a_fresh_process_keeps_subnormals_until_init_warp():
    # Without the mode the same kernel gives IEEE subnormals, so the zero above comes from the
    # mode and not from the kernel. A fresh process, as this one's main thread is already set;
    # after init_warp it also builds the cKDTree that crashed under denormals-are-zero (points
    # with coordinates at exactly 0, as the contact monitor's straight tubes have).
    code = (
        "import json, numpy as np, warp as wp\n"
        "from scipy.spatial import cKDTree\n"
        "wp.config.log_level = wp.LOG_ERROR\n"
        "wp.config.quiet = True\n"
        "wp.init()\n"
        "from tests.test_float_mode import subnormal_probe\n"
        "from warp_tube.runtime.warp_setup import init_warp\n"
        "before = subnormal_probe()\n"
        "init_warp()\n"
        "s = np.linspace(-1.0, 1.0, 101)\n"
        "pts = np.concatenate([np.stack([s, 0 * s, 0 * s], 1), np.stack([0 * s, s, 0 * s + 0.15], 1)])\n"
        "pairs = len(cKDTree(pts).query_pairs(0.2))\n"
        "print(json.dumps([before, subnormal_probe(), pairs]))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True).stdout
    before, after, pairs = json.loads(out.strip().splitlines()[-1])
    assert before == pytest.approx([1e-40, 1e-10], rel=1e-3)  # 1e-40 subnormal: ~3 digits of precision
    assert after[0] == 0.0 and after[1] == pytest.approx(1e-10, rel=1e-3)
    # pairs within 0.2 of 202 points spaced 0.02 along two lines: counted by brute force
    d = np.linalg.norm(CROSS_POINTS[:, None] - CROSS_POINTS[None], axis=-1)
    assert pairs == int(np.count_nonzero(np.triu(d <= 0.2, 1)))
