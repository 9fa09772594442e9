"""Result storage writes atomically, consolidates from cell files alone and survives unreadable ones."""

import json
import os

import numpy as np
import pytest

from parambench.bench.cells import Cell
from parambench.bench.storage import ResultStore, StoredCells, check_output_dir
from parambench.datasets_gen.errors import InputFileError


def test_rows_and_arrays_round_trip(tmp_path):
    store = ResultStore(tmp_path)
    cell = Cell("plane", 500, "grid", 0.0, 3, "scp-igl", (("b", 1),))
    row = {**cell.address(), "cell_id": cell.cell_id, "status": "ok", "qc_mean": np.float64(1.5)}
    rel = store.write_arrays(cell.cell_id, {"uv": np.arange(6.0).reshape(3, 2)})
    store.write_row(row)
    assert store.finished_ids() == {cell.cell_id}
    table = store.consolidate()
    assert table.loc[0, "qc_mean"] == 1.5 and table.loc[0, "params"] == '{"b": 1}'
    np.testing.assert_array_equal(np.load(tmp_path / rel)["uv"], np.arange(6.0).reshape(3, 2))
    assert not list(tmp_path.glob("cells/.*"))  # no temporary files left behind


def test_cell_ids_differ_by_any_field():
    base = Cell("plane", 500, "grid", 0.0, 0, "m", ())
    variants = [Cell("plane", 501, "grid", 0.0, 0, "m", ()), Cell("plane", 500, "random", 0.0, 0, "m", ()),
                Cell("plane", 500, "grid", 0.1, 0, "m", ()), Cell("plane", 500, "grid", 0.0, 1, "m", ()),
                Cell("plane", 500, "grid", 0.0, 0, "m", (("k", 2),))]
    ids = {base.cell_id, *(v.cell_id for v in variants)}
    assert len(ids) == 6


def _row(cell, status="ok"):
    return {**cell.address(), "cell_id": cell.cell_id, "status": status}


def test_scan_sorts_rows_by_status_and_names_unreadable_files(tmp_path):
    store = ResultStore(tmp_path)
    cells = [Cell("plane", 500, "grid", 0.0, seed, "scp", ()) for seed in range(6)]
    for cell, status in zip(cells, ("ok", "suspect", "failed")):
        store.write_row(_row(cell, status))
    full = store.write_row(_row(cells[3]))
    full.write_bytes(full.read_bytes()[:40])  # truncated mid-write
    (store.cells_dir / f"{cells[4].cell_id}.json").write_text("[1, 2]")
    (store.cells_dir / f"{cells[5].cell_id}.json").write_text(json.dumps(_row(cells[0])))  # wrong id

    stored = store.scan()
    assert stored.status == {cells[0].cell_id: "ok", cells[1].cell_id: "suspect", cells[2].cell_id: "failed"}
    assert set(stored.unreadable) == {cells[3].cell_id, cells[4].cell_id, cells[5].cell_id}
    assert "JSON" in stored.unreadable[cells[3].cell_id] and "list" in stored.unreadable[cells[4].cell_id]
    assert cells[0].cell_id in stored.unreadable[cells[5].cell_id]
    # Any status but "failed" is finished; unreadable files are neither finished nor rows.
    assert store.finished_ids() == {cells[0].cell_id, cells[1].cell_id}
    assert sorted(store.consolidate()["cell_id"]) == sorted(c.cell_id for c in cells[:3])


def test_quarantine_moves_the_bytes_aside(tmp_path):
    store = ResultStore(tmp_path)
    cell = Cell("plane", 500, "grid", 0.0, 0, "scp", ())
    path = store.write_row(_row(cell))
    path.write_text('{"cell_id": ')
    moved = store.quarantine(cell.cell_id)
    assert not path.exists() and moved.read_text() == '{"cell_id": '
    assert store.scan() == StoredCells()
    # The same cell unreadable again: the earlier evidence is kept beside the new one.
    path.write_text("garbage")
    again = store.quarantine(cell.cell_id)
    assert again != moved and again.read_text() == "garbage" and moved.read_text() == '{"cell_id": '


def test_a_number_field_edited_into_text_makes_the_row_unreadable(tmp_path):
    """ "qc_mean": "abc" made results.parquet unwritable (pyarrow) and the report count a NaN
    as a failure; such a row is now unreadable, so its cell is recomputed."""
    store = ResultStore(tmp_path)
    cell = Cell("plane", 500, "grid", 0.0, 0, "scp", ())
    path = store.write_row(_row(cell))
    row = json.loads(path.read_text())
    row["qc_mean"] = "abc"
    path.write_text(json.dumps(row))
    assert "qc_mean" in store.scan().unreadable[cell.cell_id]
    assert store.consolidate().empty
    row["qc_mean"], row["status"] = 1.0, "bogus"  # an unknown status counted as finished forever
    path.write_text(json.dumps(row))
    assert "status" in store.scan().unreadable[cell.cell_id] and not store.finished_ids()


def test_stale_temporaries_are_removed_and_results_kept(tmp_path):
    store = ResultStore(tmp_path)
    cell = Cell("plane", 500, "grid", 0.0, 0, "scp", ())
    store.write_row(_row(cell))
    (store.cells_dir / f".{cell.cell_id}.json.abc.tmp").write_text("{")
    (store.datasets_dir / ".key.xyz.npz").write_bytes(b"PK")
    assert store.remove_stale_temporaries() == 2
    assert [p.name for p in tmp_path.rglob("*") if p.is_file()] == [f"{cell.cell_id}.json"]


def test_output_dir_check_creates_nothing(tmp_path):
    target = tmp_path / "a" / "b"
    assert check_output_dir(target) == target and not (tmp_path / "a").exists()
    blocker = tmp_path / "file.txt"
    blocker.write_text("x")
    for bad in (blocker, blocker / "sub"):
        with pytest.raises(InputFileError, match="--out"):
            check_output_dir(bad)
    assert not (blocker.parent / "file.txt" / "sub").exists() and blocker.read_text() == "x"


@pytest.mark.skipif(os.geteuid() == 0, reason="root may write anywhere")
def test_output_dir_check_refuses_a_read_only_folder(tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        with pytest.raises(InputFileError, match="not writable"):
            check_output_dir(ro / "results")
    finally:
        ro.chmod(0o755)


def test_written_files_follow_the_umask_not_owner_only(tmp_path):
    """mkstemp's files are 0600 and the rename kept that: reports, run.json and cell files were
    unreadable to the group under umask 022 while results.csv (pandas) was not."""
    from parambench.bench.storage import FILE_MODE, atomic_write_bytes

    mask = os.umask(0o022)
    os.umask(mask)
    assert FILE_MODE == 0o666 & ~mask
    store = ResultStore(tmp_path / "out")
    atomic_write_bytes(tmp_path / "report.html", b"<html></html>")
    row = store.write_row({"cell_id": "c1", "status": "ok"})
    arrays = tmp_path / "out" / store.write_arrays("c1", {"uv": np.zeros((3, 2))})
    plain = tmp_path / "plain.txt"
    plain.write_text("x")
    for path in (tmp_path / "report.html", row, arrays):
        assert path.stat().st_mode & 0o777 == plain.stat().st_mode & 0o777
