"""The process that makes a large batch's records (warp_tube.batch.recorder): calls answered in
it, errors named, and, where it stops, the records it had not made made in the batch's process
(the same journal records and summary lines)."""

import json
import math

from warp_tube.batch.bookkeeping import Bookkeeper
from warp_tube.batch.journal import Journal
from warp_tube.batch.outputs import summary_lines
from warp_tube.batch.recorder import Recorder
from warp_tube.batch.variants import Variant


def test_calls_come_back_with_their_results_and_errors():
    r = Recorder()
    try:
        for k in range(4):
            r.submit(k, math.sqrt, float(k * k))
        r.submit("bad", math.sqrt, -1.0)
        assert [r.result(k) for k in reversed(range(4))] == [3.0, 2.0, 1.0, 0.0]
        try:
            r.result("bad")
            raise AssertionError("no error")
        except RuntimeError as e:
            assert "ValueError" in str(e) and "math domain error" in str(e)
    finally:
        r.close()
    assert r.proc.returncode == 0


def _records():
    variants = [Variant(k, f"variant_{k:05d}", k, (str(1e4 * (k + 1)),), (), None) for k in range(6)]
    recs = {}
    for c, idx in enumerate(((0, 1, 2), (3, 4, 5))):
        recs[c] = {"rows": {"index": list(idx), "status": ["ok"] * 3, "reason": [""] * 3, "frames": [3] * 3,
                            "max_displacement_m": [0.1 * i for i in idx], "tip": [[i, 0.5, -1.0] for i in idx],
                            "contact_frame": [""] * 3, "output": [f"variant_{i:05d}.usdc" for i in idx]}, "layer": ""}  # fmt: skip
    return variants, recs


def test_records_made_by_the_process_or_here_when_it_stopped(tmp_path):
    variants, recs = _records()
    expected = None
    for how in ("here", "process", "stopped"):
        journal = Journal(str(tmp_path / how))
        journal.begin({"version": 1}, resume=False)
        recorder = None if how == "here" else Recorder()
        if how == "stopped":
            recorder.proc.kill()
            recorder.proc.wait()
        books = Bookkeeper(journal, variants, recorder)
        records = {c: books.record(c, rec) for c, rec in recs.items()}
        books.drain()
        if recorder is not None:
            recorder.close()
        text = books.summary_text(records)
        on_disk = {c: json.loads((tmp_path / how / ".batch" / "chunks" / f"chunk_{c:05d}.json").read_text()) for c in recs}
        assert all(on_disk[c]["summary"] == records[c]["summary"] for c in recs)
        if expected is None:
            expected = text
            # the lines of every variant made at once, from all the fields
            cols = {f: [v for c in recs for v in recs[c]["rows"].get(f, [""] * 3)] for f in recs[0]["rows"]}
            assert text == summary_lines(variants, cols)
        assert text == expected, how


def test_a_recorder_that_cannot_start_leaves_the_records_to_the_batch(tmp_path, monkeypatch):
    """No Python to start (an embedded interpreter): the recorder is broken from the start and the
    records are made in the batch's process, the same as without it."""
    import sys

    variants, recs = _records()
    monkeypatch.setattr(sys, "executable", "")
    recorder = Recorder()
    assert recorder.broken is not None and recorder.proc is None
    journal = Journal(str(tmp_path / "j"))
    journal.begin({"version": 1}, resume=False)
    books = Bookkeeper(journal, variants, recorder)
    records = {c: books.record(c, rec) for c, rec in recs.items()}
    books.drain()
    recorder.close()
    journal_here = Journal(str(tmp_path / "here"))
    journal_here.begin({"version": 1}, resume=False)
    here = Bookkeeper(journal_here, variants)
    assert books.summary_text(records) == here.summary_text({c: here.record(c, rec) for c, rec in recs.items()})
