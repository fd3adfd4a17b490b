"""run_batch from a script: one that calls it outside ``if __name__ == "__main__":`` is refused
with one message before any process starts (before: each process ran the script again, failed,
and the batch raised a bare BrokenProcessPool, its folder left behind); a script read from stdin,
which processes cannot import, has its work done in the batch's own process; ``python -m
warp_tube`` and a guarded script start their processes as ever."""

from __future__ import annotations

import subprocess
import sys

import numpy as np

from tests.conftest import SCENES

DEFAULT = SCENES / "default.usda"
E = "/World/Tube.warptube:youngsModulus"


def _table(tmp_path):
    table = tmp_path / "t.csv"
    table.write_text(f"{E}\n" + "".join(f"{1e5 + 1e4 * k}\n" for k in range(4)))
    return table


def _python(args, tmp_path, script=None):
    return subprocess.run([sys.executable, *args], input=script, capture_output=True, text=True, timeout=300, cwd=tmp_path)


def _call(out, table, **kw) -> str:
    extra = "".join(f", {k}={v!r}" for k, v in kw.items())
    return f"run_batch({str(DEFAULT)!r}, {str(out)!r}, {str(table)!r}, frames=3, device='cpu'{extra})"


def test_a_script_calling_the_batch_unguarded_is_refused_with_one_message(tmp_path):
    table = _table(tmp_path)
    for name, kw in (("workers", dict(layout="arrays", workers=2)), ("writers", dict(writers=2))):
        out = tmp_path / f"out_{name}"
        script = tmp_path / f"{name}.py"
        script.write_text(f"import os\nfrom warp_tube.batch import run_batch\n\nr = {_call(out, table, **kw)}\nprint('ok', r.ok)\n")
        p = _python([str(script)], tmp_path)
        assert p.returncode != 0 and "ok" not in p.stdout
        said = (f'{script}, line 4: run_batch is called outside if __name__ == "__main__": the batch\'s '
                f"{name[:-1]} processes import this script and would run the batch again")  # fmt: skip
        assert said in p.stderr, p.stderr[-3000:]
        assert p.stderr.count("Traceback") == 1 and "BrokenProcessPool" not in p.stderr, p.stderr[-3000:]
        assert not out.exists()  # nothing written, no .batch left


def test_an_unguarded_script_is_refused_whatever_its_batch_size(tmp_path):
    """A batch too small to start processes is refused all the same from an unguarded script (a
    script that worked on a small table would otherwise be refused on a larger one); with
    workers=1 and writers=0 it runs."""
    table = tmp_path / "two.csv"
    table.write_text(f"{E}\n100000\n120000\n")
    out = tmp_path / "out"
    script = tmp_path / "small.py"
    script.write_text(f"from warp_tube.batch import run_batch\nr = {_call(out, table)}\nprint('ok', r.ok)\n")
    p = _python([str(script)], tmp_path)
    assert p.returncode != 0 and f'{script}, line 2: run_batch is called outside if __name__ == "__main__"' in p.stderr, p.stderr[-3000:]
    assert not out.exists()
    script.write_text(f"from warp_tube.batch import run_batch\nr = {_call(out, table, workers=1, writers=0)}\nprint('ok', r.ok)\n")
    p = _python([str(script)], tmp_path)
    assert p.returncode == 0 and "ok 2" in p.stdout, p.stderr[-3000:]


def test_an_unguarded_call_inside_a_function_is_found_and_a_guarded_one_runs(tmp_path):
    table = _table(tmp_path)
    out = tmp_path / "out"
    body = f"from warp_tube.batch import run_batch\n\n\ndef main():\n    return {_call(out, table, layout='arrays', workers=2)}\n\n\n"
    script = tmp_path / "fn.py"
    script.write_text(body + "with open(__file__):\n    r = main()\n")
    p = _python([str(script)], tmp_path)
    assert f"{script}, line 9: run_batch is called outside" in p.stderr and not out.exists(), p.stderr[-3000:]
    script.write_text(body + 'if __name__ == "__main__":\n    r = main()\n    print("ok", r.ok, r.devices)\n')
    p = _python([str(script)], tmp_path)
    assert p.returncode == 0 and "ok 4 ['cpu', 'cpu']" in p.stdout, p.stderr[-3000:]


def test_a_script_on_stdin_does_the_work_in_the_batch_process(tmp_path):
    """Worker and writer processes asked for: a warning says they are not started, and the batch
    gives what it gives in one process."""
    table = _table(tmp_path)
    piped, alone = tmp_path / "piped", tmp_path / "alone"
    script = (f"from warp_tube.batch import run_batch\nr = {_call(piped, table, layout='arrays', workers=2)}\n"
              f"print('ok', r.ok, r.devices)\nr = {_call(piped / 'files', table, writers=2)}\nprint('ok', r.ok)\n")  # fmt: skip
    p = _python(["-"], tmp_path, script)
    assert p.returncode == 0 and "ok 4 ['cpu']" in p.stdout and "ok 4" in p.stdout.splitlines()[1], p.stderr[-3000:]
    assert "Traceback" not in p.stderr and "FileNotFoundError" not in p.stderr, p.stderr[-3000:]
    for what in ("worker", "writer"):
        assert f"the script is read from stdin (<stdin>), which the batch's {what} processes cannot import: their work is done in this process" in p.stderr
    from warp_tube.batch import run_batch

    run_batch(str(DEFAULT), str(alone), str(table), frames=3, device="cpu", layout="arrays", writers=0)
    assert np.array_equal(np.load(piped / "centerline.npy"), np.load(alone / "centerline.npy"))


def test_python_m_warp_tube_starts_its_worker_processes(tmp_path):
    """A package's ``__main__`` is not imported again by the processes: not an unguarded call."""
    table = _table(tmp_path)
    p = _python(["-m", "warp_tube", "batch", str(DEFAULT), "--variants", str(table), "-o", str(tmp_path / "out"), "--frames", "3",
                 "--layout", "arrays", "--workers", "2", "--device", "cpu"], tmp_path)  # fmt: skip
    assert p.returncode == 0 and "cpu x 2" in p.stdout, p.stderr[-3000:]
