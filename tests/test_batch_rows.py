"""A chunk's summary rows as columns (warp_tube.batch.rows): the dict view, slices, and the
batch's columns merged in batch order from chunks recorded in any order."""

import json

from warp_tube.batch.rows import Rows, batch_columns, record_count


def _rows(n, base=0):
    return Rows.of([dict(status="ok" if k % 2 == 0 else "failed", frames=base + k, tip=[base + k, 0.0, 1.0]) for k in range(n)])


def test_rows_as_dicts_and_slices():
    rows = _rows(5)
    assert len(rows) == 5
    assert rows[3] == {"status": "failed", "frames": 3, "tip": [3, 0.0, 1.0]}
    assert [r["frames"] for r in rows] == [0, 1, 2, 3, 4]
    assert rows.take(range(1, 4)).columns["frames"] == [1, 2, 3]  # a run: one slice
    assert rows.take((4, 0)).columns["frames"] == [4, 0]  # not a run: picked one by one
    rows.put(2, {"status": "failed", "frames": 9, "tip": [0.0, 0.0, 0.0]})
    assert rows[2]["frames"] == 9 and rows.columns["status"][2] == "failed"


def test_batch_columns_in_batch_order():
    # two groups interleaved: chunk 0 holds variants 0, 2, 4 and chunk 1 holds 1, 3; recorded
    # second first, through JSON as the journal keeps them (older journals held the indices as strings)
    a = {"rows": {"index": [0, 2, 4], **_rows(3, base=10).columns, "output": ["a0", "a2", "a4"]}}
    b = {"rows": {"index": ["1", "3"], **_rows(2, base=20).columns, "output": ["b1", "b3"]}}
    records = [json.loads(json.dumps(r)) for r in (b, a)]
    assert [record_count(r) for r in records] == [2, 3]
    index, cols = batch_columns(records, ("frames", "output", "missing"))
    assert index == [0, 1, 2, 3, 4]
    assert cols["frames"] == [10, 20, 11, 21, 12]
    assert cols["output"] == ["a0", "b1", "a2", "b3", "a4"]
    assert cols["missing"] == [""] * 5  # a field no record has reads as empty, as in the summary
