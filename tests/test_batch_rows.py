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


def test_summary_joined_from_chunks_is_the_summary_made_at_once(tmp_path):
    """summary.csv's lines made chunk by chunk as they finish, joined in batch order (chunks of
    consecutive variants; chunks of two groups interleaved; a chunk recorded by an earlier version,
    every field and no lines), equal the lines of every variant made at once; a journal record keeps
    the lines and the fields the batch reads back."""
    from warp_tube.batch.bookkeeping import Bookkeeper
    from warp_tube.batch.journal import Journal
    from warp_tube.batch.outputs import SUMMARY_FIELDS, summary_lines
    from warp_tube.batch.variants import Variant

    variants = [Variant(k, f"variant_{k:05d}", k, (str(1e4 * (k + 1)), "0.5"), (), None) for k in range(7)]

    def record(indices):
        rows = Rows.of([dict(status="ok" if i % 3 else "failed", reason="" if i % 3 else 'numerical failure, at frame 2:\n "x" not finite',
                             frames=3, frames_simulated=2, integrator="semiImplicitEuler", substeps=30, rerun=False,
                             max_displacement_m=0.1 * i + 1e-17, tip=[i, -0.5 * i, 1.0 / (i + 1)], kinetic_energy_J=float("nan") if i == 4 else 2.0 ** -i,
                             work_J=1e-9 * i, contact_frame="" if i % 2 else i) for i in indices])  # fmt: skip
        return {"rows": {"index": list(indices), **rows.columns, "output": [f"variant_{i:05d}.usdc" for i in indices]}}

    for chunks in ([(0, 1, 2), (3, 4, 5), (6,)], [(0, 2, 4, 6), (1, 3, 5)]):
        journal = Journal(str(tmp_path / "j"))
        journal.begin({"version": 1}, resume=False)
        books = Bookkeeper(journal, variants)
        records = {c: record(ix) for c, ix in enumerate(chunks)}
        index, columns = batch_columns(records.values(), ("tip", *SUMMARY_FIELDS))  # every field, for lines made at once
        assert index == list(range(7))
        for c in reversed(range(len(chunks) - 1)):  # finished out of order; the last chunk recorded before (no lines)
            kept = books.record(c, records[c])
            assert json.loads((tmp_path / "j" / ".batch" / "chunks" / f"chunk_{c:05d}.json").read_text()) == dict(kept, chunk=c)
            assert set(kept["rows"]) == {"index", "status", "reason", "contact_frame", "output"}
            records[c] = json.loads(json.dumps(kept))  # as --resume reads it back
        assert books.summary_text(records) == summary_lines(variants, columns)


def test_csv_records_split_rows_not_lines_inside_quotes():
    import csv
    import io

    from warp_tube.batch.bookkeeping import csv_records

    rows = [["a", 1.5], ['two\nlines, "quoted"', 2], ["", "x\r\ny"], ["plain", 'end"']]
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerows(rows)
    out = csv_records(buf.getvalue())
    assert len(out) == len(rows) and "".join(out) == buf.getvalue()
    assert [next(csv.reader(io.StringIO(r))) for r in out] == [[str(x) for x in r] for r in rows]
