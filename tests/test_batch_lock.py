"""One batch at a time in an output folder (``DIR/.batch.lock``)."""

import json
import os
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from warp_tube.batch import run_batch
from warp_tube.batch.lock import LOCK_NAME
from warp_tube.scene.spec import SceneError

DEFAULT = Path(__file__).resolve().parents[1] / "scenes" / "default.usda"


def table(tmp_path):
    path = tmp_path / "t.csv"
    path.write_text("/World/Tube.warptube:youngsModulus\n100000\n200000\n")
    return str(path)


def lock_file(folder: Path, pid: int):
    folder.mkdir(exist_ok=True)
    (folder / LOCK_NAME).write_text(json.dumps({"pid": pid, "host": socket.gethostname(), "since": 0.0}))


def test_a_folder_another_running_batch_holds_is_refused_and_left_as_it_is(tmp_path):
    """A second batch (or --resume) into a folder whose lock a running process holds is refused
    before anything is written, naming that process."""
    other = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        out = tmp_path / "out"
        lock_file(out, other.pid)
        before = sorted(os.listdir(out))
        for resume in (False, True):
            with pytest.raises(SceneError, match=rf"another batch is writing there \(process {other.pid} on "):
                run_batch(str(DEFAULT), str(out), table(tmp_path), layout="arrays", frames=2, resume=resume)
            assert sorted(os.listdir(out)) == before
        assert json.loads((out / LOCK_NAME).read_text())["pid"] == other.pid  # (not taken over)
    finally:
        other.kill()
        other.wait()


def test_a_lock_left_by_a_batch_that_died_is_taken_over_and_given_back(tmp_path):
    gone = subprocess.Popen([sys.executable, "-c", "pass"])
    gone.wait()  # its pid no longer runs: the lock is stale
    out = tmp_path / "out"
    lock_file(out, gone.pid)
    assert run_batch(str(DEFAULT), str(out), table(tmp_path), layout="arrays", frames=2).ok == 2
    assert not (out / LOCK_NAME).exists()


def test_the_lock_is_given_back_when_a_batch_is_interrupted(tmp_path):
    out = tmp_path / "out"

    def stop(chunk_id):
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_batch(str(DEFAULT), str(out), table(tmp_path), layout="arrays", frames=2, chunk=1, on_chunk=stop)
    assert (out / ".batch").is_dir() and not (out / LOCK_NAME).exists()
    assert run_batch(str(DEFAULT), str(out), table(tmp_path), layout="arrays", frames=2, chunk=1, resume=True).ok == 2
