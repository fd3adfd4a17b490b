"""Ctrl-C at the edges of a batch: while its complete result is saved, while its writer
processes start, and what it then says and leaves in its folder. Each interrupt is a real SIGINT
sent to this process at the exact point (or the pool's error that follows one), not a timing."""

from __future__ import annotations

import os
import signal
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path

import pytest

from warp_tube.batch import journal as journal_module
from warp_tube.batch import run as run_module
from warp_tube.batch import writer_pool
from warp_tube.batch.lock import LOCK_NAME
from warp_tube.cli import main as cli

DEFAULT = Path(__file__).resolve().parents[1] / "scenes" / "default.usda"


def table(tmp_path) -> Path:
    path = tmp_path / "t.csv"
    path.write_text("/World/Tube.warptube:youngsModulus\n100000\n200000\n")
    return path


def batch(tmp_path, out, layout, *args):
    return cli(["batch", str(DEFAULT), "--variants", str(table(tmp_path)), "-o", str(out), "--frames", "2", "--layout",
                layout, "--chunk", "1", "--quiet", *args])  # fmt: skip


def files_of(folder: Path) -> dict:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file() and p.name != ".batch-finished.json"}  # fmt: skip


def ctrl_c() -> None:
    os.kill(os.getpid(), signal.SIGINT)


@pytest.mark.parametrize("layout", ["grid", "arrays"])
@pytest.mark.parametrize("where", ["journal", "writers"])
def test_ctrl_c_while_the_complete_result_is_saved_keeps_it_and_leaves_nothing_half_done(tmp_path, capsys, monkeypatch,
                                                                                           layout, where):  # fmt: skip
    """Before: exit 130 "nothing was written" with the outputs complete, `.batch/` or the lock
    left, and the batch refused when run again as the message advised."""
    whole = tmp_path / "whole"
    assert batch(tmp_path, whole, layout) == 0
    if where == "journal":  # the record removed as the finished signature is written
        finish = journal_module.Journal.finish

        def interrupted_finish(self):
            self._atomic(self.finished_path, self.signature)
            ctrl_c()
            finish(self)

        monkeypatch.setattr(journal_module.Journal, "finish", interrupted_finish)
    else:  # the writers' end, before the lock is given back
        shutdown = writer_pool.Writers.shutdown

        def interrupted_shutdown(self):
            ctrl_c()
            shutdown(self)

        monkeypatch.setattr(writer_pool.Writers, "shutdown", interrupted_shutdown)
    out = tmp_path / "out"
    capsys.readouterr()
    assert batch(tmp_path, out, layout) == 0
    err = capsys.readouterr().err
    assert "interrupted while the batch's complete result was being saved: the save was finished" in err, err
    assert not (out / ".batch").exists() and not (out / LOCK_NAME).exists()
    assert (out / ".batch-finished.json").exists()
    assert files_of(out) == files_of(whole)
    monkeypatch.undo()
    assert batch(tmp_path, out, layout, "--resume") == 0


def test_resume_of_a_finished_batch_removes_what_is_left_of_its_record(tmp_path):
    """A batch stopped (killed) while removing its record left `.batch/` without `state.json`:
    --resume said the batch was finished but left it, and the folder stayed refused."""
    out = tmp_path / "out"
    assert batch(tmp_path, out, "grid") == 0
    (out / ".batch" / "chunks").mkdir(parents=True)
    (out / ".batch" / "chunks" / "chunk_00000.json").write_text("{}")
    assert batch(tmp_path, out, "grid", "--resume") == 0
    assert not (out / ".batch").exists() and not (out / LOCK_NAME).exists()


def test_an_interrupt_before_a_resumed_batch_runs_says_what_the_folder_holds(tmp_path, capsys, monkeypatch):
    """Before: "nothing was written" of a folder holding a batch's outputs."""
    out = tmp_path / "out"

    def stop(chunk_id):
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_module.run_batch(str(DEFAULT), str(out), str(table(tmp_path)), layout="grid", frames=2, chunk=1, on_chunk=stop)

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(run_module, "prepare_batch", interrupted)
    capsys.readouterr()
    assert batch(tmp_path, out, "grid", "--resume") == 130
    err = capsys.readouterr().err.strip()
    assert err == f"warp-tube: interrupted; {out} holds an unfinished batch, its finished variants kept: --resume goes on", err


@pytest.mark.parametrize("error", [BrokenProcessPool("A process in the process pool was terminated abruptly"),
                                   ConnectionRefusedError(111, "Connection refused"), EOFError("unexpected EOF")])  # fmt: skip
@pytest.mark.parametrize("where", ["reading", "running"])
def test_a_pool_that_breaks_after_ctrl_c_is_the_users_stop(tmp_path, capsys, monkeypatch, error, where):
    """The signal reaches the writer processes and their fork server too; the pool's error that
    follows it was reported as a process killed from outside or a write failure (exit 2)."""

    def broken(*args, **kwargs):
        try:
            ctrl_c()  # (taken, as a thread of the pool would have it, before the pool's error)
        except KeyboardInterrupt:
            pass
        raise error

    monkeypatch.setattr(run_module, "prepare_batch" if where == "reading" else "run_here", broken)
    out = tmp_path / "out"
    assert batch(tmp_path, out, "grid") == 130
    err = capsys.readouterr().err.strip()
    assert err.startswith("warp-tube: interrupted; ") and "\n" not in err, err
    assert not (out / LOCK_NAME).exists()


def test_a_pool_that_breaks_without_an_interrupt_is_still_reported_as_such(tmp_path, capsys, monkeypatch):
    def broken(*args, **kwargs):
        raise BrokenProcessPool("A process in the process pool was terminated abruptly")

    monkeypatch.setattr(run_module, "run_here", broken)
    assert batch(tmp_path, tmp_path / "out", "grid") == 2
    assert "a writer or worker process stopped unexpectedly" in capsys.readouterr().err


@pytest.mark.parametrize("error", [EOFError("unexpected EOF"), ConnectionRefusedError(111, "Connection refused")])
def test_the_writer_start_thread_takes_a_fork_server_gone(error):
    """Before: "Exception in thread batch-writer-start ... EOFError" printed after Ctrl-C."""

    class Pool:
        def submit(self, fn):
            raise error

    writer_pool._start(Pool(), 2)  # (nothing raised: the writes report a pool that cannot start)


def test_the_fork_server_starts_deaf_to_ctrl_c(monkeypatch):
    """A Ctrl-C to the process group while the fork server imported usd-core killed it with a
    traceback; it starts with SIGINT blocked (as SIGHUP), which its processes inherit."""
    from multiprocessing import forkserver, resource_tracker

    masks = []
    # (as Python's does when it starts the tracker: SIGINT and SIGTERM unblocked after)
    monkeypatch.setattr(resource_tracker, "ensure_running", lambda: signal.pthread_sigmask(signal.SIG_UNBLOCK, [signal.SIGINT]))
    monkeypatch.setattr(forkserver, "ensure_running", lambda: masks.append(signal.pthread_sigmask(signal.SIG_BLOCK, [])))

    class Context:
        def get_start_method(self):
            return "forkserver"

    writer_pool._helpers_deaf_to_hangup(Context())
    assert masks and signal.SIGINT in masks[0] and signal.SIGHUP in masks[0]
    assert signal.SIGINT not in signal.pthread_sigmask(signal.SIG_BLOCK, [])


def test_a_terminated_pool_has_closed_its_wakeup_pipe_when_terminate_returns(monkeypatch):
    """Python's exit writes to a process pool's wake-up pipe without its lock (3.11); a pool whose
    manager thread was still closing it then printed "Exception ignored ... Bad file descriptor"."""
    import concurrent.futures as cf
    import time
    from concurrent.futures import process

    close = process._ThreadWakeup.close

    def slow_close(self):
        time.sleep(0.3)
        close(self)

    monkeypatch.setattr(process._ThreadWakeup, "close", slow_close)
    pool = cf.ProcessPoolExecutor(1, mp_context=writer_pool.spawn_context())
    pool.submit(int, 1).result()
    wakeup = pool._executor_manager_thread_wakeup
    writer_pool.terminate_pool(pool)
    assert wakeup._closed
