"""A result that cannot be saved (disk full, read-only or quota): one line naming the file and
the operating system's reason, exit status 2, no partial or temporary file, an existing output
left as it was; and a run whose output cannot fit in memory refused before it starts."""

import errno

import pytest

from warp_tube.cli import main
from warp_tube.io.writer import StageWriter, save_error

from .bad_inputs import KEEP, scene
from .layer_proxy import LayerProxy

#: what usd-core's exception says when the disk fills while a crate file is saved
DISK_FULL = ("Error in 'pxrInternal::ArFilesystemWritableAsset::Write' at line 78: 'Error occurred writing file: "
             "No space left on device'")  # fmt: skip


class _FullDisk(LayerProxy):
    """An Sdf.Layer whose Save fails as usd-core's does on a full disk."""

    def Save(self):
        raise RuntimeError(DISK_FULL)


@pytest.fixture
def full_disk(monkeypatch):
    close = StageWriter.close

    def failing_close(self):
        self.layer = _FullDisk(self.layer)
        return close(self)

    monkeypatch.setattr(StageWriter, "close", failing_close)


def test_save_error_names_the_reason_and_pickles():
    import pickle

    e = save_error("out.usdc", RuntimeError(DISK_FULL))
    assert (e.errno, e.strerror, e.filename) == (errno.ENOSPC, "No space left on device", "out.usdc")
    assert pickle.loads(pickle.dumps(e)).errno == errno.ENOSPC  # crosses from a writer process
    other = save_error("out.usdc", RuntimeError("something usd-core says"))
    assert other.errno == errno.EIO and "usd-core could not save" in other.strerror


def test_run_that_cannot_save_exits_2_and_says_the_frames_were_lost(tmp_cwd, capsys, full_disk):
    (tmp_cwd / "scene.usda").write_text(scene())
    (tmp_cwd / "keep.usdc").write_bytes(KEEP)
    assert main(["run", "scene.usda", "-o", "keep.usdc"]) == 2
    err = capsys.readouterr().err
    assert "cannot write " in err and "keep.usdc: No space left on device; " in err
    assert "(3 frames) could not be saved: nothing kept; " in err and "keep.usdc was left as it was" in err
    # one line: no summary saying the frames were written
    assert err.startswith("warp-tube: cannot write ") and err.count("\n") == 1 and "written" not in err, err
    assert "Traceback" not in err and "internal error" not in err
    assert (tmp_cwd / "keep.usdc").read_bytes() == KEEP
    assert sorted(p.name for p in tmp_cwd.iterdir()) == ["keep.usdc", "scene.usda"]  # no temporary left


def test_a_run_that_cannot_save_has_a_summary_that_says_so(tmp_cwd, full_disk):
    import warp_tube

    (tmp_cwd / "scene.usda").write_text(scene())
    sim = warp_tube.Simulation(warp_tube.load_scene("scene.usda"), device="cpu")
    with pytest.raises(OSError, match="No space left on device"):
        sim.run(output="out.usdc")
    s = sim.last_summary
    assert s.output is None and s.partial is None and s.stopped == "cannot write out.usdc: No space left on device"
    assert "frames       none saved (2 simulated; 3 could not be saved)" in s.text() and "written" not in s.text()


def test_batch_files_that_cannot_be_saved_exit_2_naming_the_file(tmp_cwd, capsys, full_disk):
    (tmp_cwd / "scene.usda").write_text(scene())
    (tmp_cwd / "t.csv").write_text("/World/Tube.warptube:youngsModulus\n20000\n30000\n")
    assert main(["batch", "scene.usda", "--variants", "t.csv", "-o", "out", "--writers", "0", "--workers", "1"]) == 2
    err = capsys.readouterr().err
    assert "/out/variant_00000.usdc: No space left on device" in err.replace("\\", "/") and "cannot write " in err
    assert "--resume goes on" in err and "internal error" not in err
    assert not (tmp_cwd / "out" / "variant_00000.usdc").exists()


def test_run_whose_output_cannot_fit_in_memory_is_refused_before_it_starts(tmp_cwd, capsys, monkeypatch):
    import warp_tube.runtime.memory as memory

    (tmp_cwd / "scene.usda").write_text(scene())
    monkeypatch.setattr(memory, "available_memory", lambda: 10_000)  # bytes: less than 3 frames of the scene
    assert main(["run", "scene.usda", "-o", "out.usdc"]) == 2
    err = capsys.readouterr().err
    assert "more than the 10.0 kB of memory available" in err and "x that while usd-core keeps it" in err and "--every K" in err
    assert sorted(p.name for p in tmp_cwd.iterdir()) == ["scene.usda"]
