"""The batch's writer processes use the batch's own warp_tube, wherever the batch is started from.

They are forked from a server process (:mod:`warp_tube.batch.writer_pool`), which Python starts with
the current folder first on its path and, before 3.13, without the batch's path: a server that
imported warp_tube could take another copy of it than the batch's (as a checkout's source folder,
run from there with the package installed or on ``PYTHONPATH``), and the processes forked from it
would find nothing of the batch's in it. Here the current folder holds an empty ``warp_tube``
package: the batch must write every file all the same. The batch's warp_tube is a copy on
``PYTHONPATH`` and the interpreter runs without ``site`` (``-S``, the libraries' folders on
``PYTHONPATH`` too), so that an editable install's import hook, which finds warp_tube's modules by
name whatever package object holds the name, cannot mend a wrong one."""

import csv
import os
import shutil
import site
import subprocess
import sys
from pathlib import Path

import pytest

import warp_tube
import warp_tube.kernels

DEFAULT = Path(__file__).resolve().parents[1] / "scenes" / "default.usda"

SCRIPT = """
import sys
from warp_tube.batch import run_batch

if __name__ == "__main__":
    r = run_batch(sys.argv[1], sys.argv[2], sys.argv[3], layout="files", frames=3, device="cpu", writers=2)
    print(r.ok, r.failed)
"""


def test_writer_processes_import_the_batchs_warp_tube_not_the_current_folders(tmp_path):
    here = tmp_path / "elsewhere"
    (here / "warp_tube").mkdir(parents=True)
    (here / "warp_tube" / "__init__.py").write_text('"""Another warp_tube: a package with nothing in it."""\n')
    scripts = tmp_path / "scripts"
    scripts.mkdir()
    (scripts / "run_it.py").write_text(SCRIPT)
    own = tmp_path / "site"
    shutil.copytree(Path(warp_tube.__file__).parent, own / "warp_tube", ignore=shutil.ignore_patterns("__pycache__"))
    if not (own / "warp_tube" / "kernels").exists():  # (an editable install keeps them beside the package)
        shutil.copytree(Path(warp_tube.kernels.__file__).parent, own / "warp_tube" / "kernels",
                        ignore=shutil.ignore_patterns("__pycache__"))  # fmt: skip
    libraries = [p for p in site.getsitepackages() + [site.getusersitepackages()] if os.path.isdir(p)]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(own), *libraries]))
    table = tmp_path / "t.csv"
    table.write_text("/World/Tube.warptube:youngsModulus\n80000\n120000\n")
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-S", str(scripts / "run_it.py"), str(DEFAULT), str(out), str(table)], cwd=here,
                       env=env, capture_output=True, text=True, timeout=600)  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == ["2", "0"], r.stdout
    rows = list(csv.DictReader(open(out / "summary.csv", encoding="utf-8")))
    assert [row["status"] for row in rows] == ["ok", "ok"]
    assert all((out / f"variant_{k:05d}.usdc").stat().st_size > 0 for k in range(2))


def test_a_small_batch_writes_in_its_own_process_and_a_larger_one_starts_writers(tmp_path, monkeypatch):
    """Writer processes cost their start (~0.3 s): a batch of USD files whose writing would take
    less (``inline_write_seconds``, from its size) is written by the simulating process. With the
    threshold at 0 the same batch starts its writers once its size is known, and writes the same
    files."""
    import filecmp

    from warp_tube.batch import run as run_module
    from warp_tube.batch import run_batch
    from warp_tube.batch.writer_pool import Writers, inline_write_seconds

    started = []
    start = Writers.start
    monkeypatch.setattr(Writers, "start", lambda self, count: (started.append(count), start(self, count))[1])
    table = tmp_path / "t.csv"
    table.write_text("/World/Tube.warptube:youngsModulus\n80000\n120000\n")
    # the default scene: 20 points, 16 spokes (about 360 vertices), 3 frames: milliseconds of writing
    assert inline_write_seconds(2, 3, 20, 400) < run_module.INLINE_WRITE_S
    here = run_batch(str(DEFAULT), str(tmp_path / "here"), str(table), frames=3, device="cpu")
    assert here.ok == 2 and not any(started), started
    monkeypatch.setattr(run_module, "INLINE_WRITE_S", 0.0)
    by_writers = run_batch(str(DEFAULT), str(tmp_path / "by_writers"), str(table), frames=3, device="cpu")
    assert by_writers.ok == 2 and any(started), started
    for k in range(2):
        name = f"variant_{k:05d}.usdc"
        assert filecmp.cmp(tmp_path / "here" / name, tmp_path / "by_writers" / name, shallow=False), name


def _children(pid: int) -> list[int]:
    """The processes whose parent is ``pid`` (from /proc)."""
    out = []
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open(f"/proc/{entry}/stat") as f:
                    fields = f.read().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[1]) == pid:
                out.append(int(entry))
    return out


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="finds the writer processes through /proc")
def test_a_writer_killed_from_outside_is_reported_as_such_and_the_batch_resumes(tmp_path):
    """A writer process killed by the system (short of memory, say) is not a bug: the batch says
    what happened, exits with status 2, and ``--resume`` finishes it."""
    import signal
    import time

    table = tmp_path / "t.csv"
    table.write_text("/World/Tube.warptube:youngsModulus\n" + "".join(f"{80000 + 100 * k}\n" for k in range(200)))
    out = tmp_path / "out"
    args = [sys.executable, "-m", "warp_tube", "batch", str(DEFAULT), "--variants", str(table), "-o", str(out),
            "--writers", "1", "--chunk", "20", "--quiet"]  # fmt: skip
    batch = subprocess.Popen(args, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 120
    writers = []
    while batch.poll() is None and time.time() < deadline:
        if (out / "variant_00001.usdc").exists():  # a chunk written: the writer process is up
            writers = [w for s in _children(batch.pid) for w in _children(s)]  # (forked by the batch's server)
            if writers:
                break
        time.sleep(0.02)
    assert writers, "no writer process found while the batch ran"
    os.kill(writers[0], signal.SIGKILL)
    err = batch.communicate(timeout=300)[1]
    assert batch.returncode == 2, err
    assert "a writer or worker process stopped unexpectedly" in err and "--resume goes on" in err, err
    assert "internal error" not in err
    again = subprocess.run(args + ["--resume"], capture_output=True, text=True, timeout=300)
    assert again.returncode == 0, again.stderr
    rows = list(csv.DictReader(open(out / "summary.csv", encoding="utf-8")))
    assert len(rows) == 200 and all(r["status"] == "ok" for r in rows)
    assert all((out / f"variant_{k:05d}.usdc").exists() for k in range(200))


def test_an_interrupted_stage_writer_leaves_no_temporary_file(tmp_path, monkeypatch):
    """A Ctrl-C while a USD output's prims are being defined (the temporary file already made):
    the writer removes it, as it does when interrupted later."""
    from warp_tube.io.writer import StageWriter

    scene = warp_tube.load_scene(str(DEFAULT))

    def interrupted(self, *args):
        raise KeyboardInterrupt

    monkeypatch.setattr(StageWriter, "_define", interrupted)
    with pytest.raises(KeyboardInterrupt):
        StageWriter(str(tmp_path / "out.usdc"), scene)
    assert os.listdir(tmp_path) == []


def test_resume_removes_the_temporary_files_an_interrupted_batch_left(tmp_path):
    """An interrupted batch writing in its own process can leave a hidden ``.NAME.tmp-PID.usdc``
    (killed mid-write, say): ``--resume`` removes it, and ends with the same files as a whole run."""
    import filecmp

    from warp_tube.batch import BatchInterrupted, run_batch

    table = tmp_path / "t.csv"
    table.write_text("/World/Tube.warptube:youngsModulus\n" + "".join(f"{80000 + 10000 * k}\n" for k in range(4)))
    whole, part = tmp_path / "whole", tmp_path / "part"
    run_batch(str(DEFAULT), str(whole), str(table), frames=4, chunk=2, writers=0)

    def stop(chunk_id):
        raise KeyboardInterrupt

    with pytest.raises(BatchInterrupted):
        run_batch(str(DEFAULT), str(part), str(table), frames=4, chunk=2, writers=0, on_chunk=stop)
    (part / ".variant_00003.tmp-99999.usdc").write_bytes(b"half a file")
    assert run_batch(str(DEFAULT), str(part), str(table), frames=4, writers=0, resume=True).ok == 4
    names = sorted(p.name for p in whole.iterdir())
    assert sorted(p.name for p in part.iterdir()) == names
    for n in names:
        assert filecmp.cmp(whole / n, part / n, shallow=False), n


def test_where_the_platform_has_no_fork_server_the_writers_are_spawned(tmp_path, monkeypatch):
    """Windows has no ``forkserver``: the writer processes start by ``spawn`` and write the same
    files."""
    import filecmp

    from warp_tube.batch import run_batch, writer_pool

    monkeypatch.setattr(writer_pool.multiprocessing, "get_all_start_methods", lambda: ["spawn"])
    assert writer_pool.writer_context().get_start_method() == "spawn"
    table = tmp_path / "t.csv"
    table.write_text("/World/Tube.warptube:youngsModulus\n80000\n120000\n")
    spawned = run_batch(str(DEFAULT), str(tmp_path / "spawned"), str(table), frames=3, device="cpu", writers=2)
    here = run_batch(str(DEFAULT), str(tmp_path / "here"), str(table), frames=3, device="cpu", writers=0)
    assert spawned.ok == here.ok == 2
    for k in range(2):
        name = f"variant_{k:05d}.usdc"
        assert filecmp.cmp(tmp_path / "spawned" / name, tmp_path / "here" / name, shallow=False), name


def _descendants(pid: int) -> list[int]:
    """Every process below ``pid`` (from /proc)."""
    out, todo = [], [pid]
    while todo:
        kids = _children(todo.pop())
        out += kids
        todo += kids
    return out


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="finds the batch's processes through /proc")
def test_a_batch_killed_with_sigkill_leaves_no_process_behind(tmp_path):
    """A batch killed outright (SIGKILL: no handler runs) leaves none of its processes running:
    its writer processes wait on queues they hold both ends of and never saw it go, and kept their
    fork server and the resource tracker alive for ever; now each ends with the batch."""
    import signal
    import time

    table = tmp_path / "t.csv"
    table.write_text("/World/Tube.warptube:youngsModulus\n" + "".join(f"{80000 + 100 * k}\n" for k in range(300)))
    out = tmp_path / "out"
    args = [sys.executable, "-m", "warp_tube", "batch", str(DEFAULT), "--variants", str(table), "-o", str(out),
            "--writers", "1", "--chunk", "20", "--frames", "200", "--quiet"]  # fmt: skip
    batch = subprocess.Popen(args, stderr=subprocess.DEVNULL)
    deadline = time.time() + 120
    below = []
    while batch.poll() is None and time.time() < deadline:
        if (out / "variant_00001.usdc").exists():  # a chunk written: the writer process is up
            below = _descendants(batch.pid)
            if any(_children(p) for p in below):  # (the writer, forked by the batch's server)
                break
        time.sleep(0.02)
    assert below, "no process of the batch found while it ran"
    os.kill(batch.pid, signal.SIGKILL)
    batch.wait(timeout=30)
    deadline = time.time() + 20
    while time.time() < deadline and any(os.path.exists(f"/proc/{p}") for p in below):
        time.sleep(0.1)
    left = [p for p in below if os.path.exists(f"/proc/{p}")]
    for p in left:  # (not to leave them to the other tests)
        os.kill(p, signal.SIGKILL)
    assert not left, f"{len(left)} of the batch's {len(below)} processes outlived it"


def test_a_hangup_to_the_batchs_process_group_stops_it_as_ctrl_c_does(tmp_path):
    """A closed terminal hangs up the whole process group: the batch stops (exit status 129), its
    finished variants kept, and prints no traceback (before: multiprocessing's resource tracker,
    hung up with it, was started again and printed one for every semaphore the first had
    registered); --resume then ends with the files an uninterrupted batch writes."""
    import filecmp
    import signal
    import time

    table = tmp_path / "t.csv"
    table.write_text("/World/Tube.warptube:youngsModulus\n" + "".join(f"{80000 + 100 * k}\n" for k in range(120)))
    out, whole = tmp_path / "out", tmp_path / "whole"
    args = [sys.executable, "-m", "warp_tube", "batch", str(DEFAULT), "--variants", str(table), "--writers", "1", "--chunk", "20",
            "--frames", "40", "--quiet"]  # fmt: skip
    # (SIGHUP's default in the new session, as under a terminal, also where the tests run under nohup)
    batch = subprocess.Popen(args + ["-o", str(out)], stderr=subprocess.PIPE, text=True, start_new_session=True,
                             preexec_fn=lambda: signal.signal(signal.SIGHUP, signal.SIG_DFL))  # fmt: skip
    deadline = time.time() + 120
    while batch.poll() is None and time.time() < deadline and not (out / "variant_00001.usdc").exists():
        time.sleep(0.02)
    os.killpg(batch.pid, signal.SIGHUP)
    err = batch.communicate(timeout=60)[1]
    assert batch.returncode == 128 + signal.SIGHUP, err
    assert "terminated (SIGHUP)" in err and "Traceback" not in err and "resource_tracker" not in err, err
    done = subprocess.run(args + ["-o", str(out), "--resume"], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    assert subprocess.run(args + ["-o", str(whole)], capture_output=True, text=True, timeout=600).returncode == 0
    names = sorted(p.name for p in whole.iterdir())
    assert sorted(p.name for p in out.iterdir()) == names
    assert all(filecmp.cmp(out / n, whole / n, shallow=False) for n in names if n.endswith((".usdc", ".csv")))


def test_buffer_folders_in_memory_left_by_killed_batches_are_removed(tmp_path):
    """A batch killed outright leaves its chunks' buffers in /dev/shm (memory, until the machine
    restarts): the next batch's buffers are named with its process id, and those of processes that
    no longer run are removed (never a live one's, nor folders named otherwise)."""
    from warp_tube.batch.folder import SHM_PREFIX, buffer_folder

    shm = tmp_path / "shm"
    shm.mkdir()
    gone = subprocess.Popen([sys.executable, "-c", "pass"])
    gone.wait()
    dead = shm / f"{SHM_PREFIX}{gone.pid}-abc"
    live = shm / f"{SHM_PREFIX}{os.getppid()}-def"
    other = shm / "warp-tube-batch-unnamed"
    for d in (dead, live, other):
        d.mkdir()
        (d / "chunk.npy").write_bytes(b"0" * 64)
    made = buffer_folder(1024, str(tmp_path / "work"), shm=str(shm))
    assert os.path.dirname(made) == str(shm) and os.path.basename(made).startswith(f"{SHM_PREFIX}{os.getpid()}-")
    assert not dead.exists() and live.exists() and other.exists()
