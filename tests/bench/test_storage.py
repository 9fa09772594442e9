"""Result storage writes atomically and consolidates from cell files alone."""

import numpy as np

from bench.cells import Cell
from bench.storage import ResultStore


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
