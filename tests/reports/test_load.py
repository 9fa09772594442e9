"""Reading a results directory: rows, union with the consolidated table, arrays, bad files."""

import json

import numpy as np
import pandas as pd
import pytest

from parambench.bench.cells import Cell
from parambench.datasets_gen.errors import InputFileError, ParambenchError
from parambench.reports.errors import EmptyResultsError
from parambench.reports.load import (NUMERIC_COLUMNS, ROW_COLUMNS, dataset_key_candidates, load_cell_arrays,
                          load_dataset_arrays, load_results, loops_from_flat, normalise_rows, parse_json_field)


def test_reads_every_cell_with_contract_columns_and_dtypes(results_dir, make_results):
    results = load_results(results_dir)
    rows = results.rows
    # 3 surfaces (bump 144, bump 400, saddle 144) x 2 seeds x 3 methods
    assert len(rows) == 18
    assert set(ROW_COLUMNS) <= set(rows.columns)
    for col in NUMERIC_COLUMNS:
        assert rows[col].dtype == np.float64, col
    assert set(rows["status"]) == {"ok", "failed"}
    failed = rows[rows["status"] == "failed"]
    assert len(failed) == 1
    assert failed["qc_mean"].isna().all()
    assert failed["error_type"].iloc[0] == "ConvergenceError"
    assert results.run["git_commit"].startswith("0123456789")
    assert rows["cell_id"].is_monotonic_increasing
    assert results.warnings == []


def test_rows_only_in_parquet_are_kept_and_cell_files_win(results_dir):
    cells = sorted((results_dir / "cells").glob("*.json"))
    gone = json.loads(cells[0].read_text())["cell_id"]
    cells[0].unlink()  # the parquet still has it
    changed = json.loads(cells[1].read_text())
    changed["time_total"] = 123.0  # newer than the consolidated table
    cells[1].write_text(json.dumps(changed))
    rows = load_results(results_dir).rows
    assert len(rows) == 18
    assert gone in set(rows["cell_id"])
    assert rows.loc[rows["cell_id"] == changed["cell_id"], "time_total"].item() == 123.0


def test_parquet_alone_is_enough(results_dir):
    for path in (results_dir / "cells").glob("*.json"):
        path.unlink()
    assert len(load_results(results_dir).rows) == 18


def test_csv_is_read_when_there_is_no_parquet(results_dir):
    for path in (results_dir / "cells").glob("*.json"):
        path.unlink()
    (results_dir / "results.parquet").unlink()
    rows = load_results(results_dir).rows
    assert len(rows) == 18
    assert rows["params"].map(lambda p: isinstance(json.loads(p), dict)).all()


def test_corrupt_cell_file_is_skipped_with_a_warning(results_dir):
    (results_dir / "results.parquet").unlink()
    (results_dir / "results.csv").unlink()
    (results_dir / "cells" / "zz-broken.json").write_text('{"cell_id": "zz", "status": ')
    results = load_results(results_dir)
    assert len(results.rows) == 18
    assert any("zz-broken.json" in w for w in results.warnings)


def test_missing_run_json_is_a_warning_not_an_error(results_dir):
    (results_dir / "run.json").unlink()
    results = load_results(results_dir)
    assert results.run == {}
    assert any("run.json" in w for w in results.warnings)


@pytest.mark.parametrize("make", ["missing", "empty", "empty_cells"])
def test_no_results_raises_a_clear_error(tmp_path, make):
    root = tmp_path / "results"
    if make != "missing":
        root.mkdir()
    if make == "empty_cells":
        (root / "cells").mkdir()
    with pytest.raises(EmptyResultsError, match="parambench run"):
        load_results(root)
    assert issubclass(EmptyResultsError, ParambenchError)


def test_normalise_rows_fills_missing_columns_and_canonicalises_json():
    raw = pd.DataFrame([{"cell_id": "b", "status": "OK ", "params": {"k": 8}, "qc_mean": "1.5"},
                        {"cell_id": "a", "status": None, "params": '{"k":  9}', "qc_mean": None}])
    rows = normalise_rows(raw)
    assert list(rows["cell_id"]) == ["a", "b"]
    assert list(rows["status"]) == ["failed", "ok"]
    assert list(rows["params"]) == ['{"k": 9}', '{"k": 8}']
    assert rows["qc_mean"].iloc[1] == 1.5 and np.isnan(rows["qc_mean"].iloc[0])
    assert list(rows["error"]) == ["", ""]
    assert list(rows["turning_numbers"]) == ["[]", "[]"]


def test_parse_json_field():
    assert parse_json_field('{"a": 1}') == {"a": 1}
    assert parse_json_field([1, 2]) == [1, 2]
    assert parse_json_field(float("nan"), {}) == {}
    assert parse_json_field("not json", "d") == "d"


def test_loops_round_trip_and_bad_offsets():
    loops = [np.array([0, 1, 2, 3]), np.array([7, 6, 5])]
    flat = np.concatenate(loops)
    out = loops_from_flat(flat, [0, 4, 7], n_points=8)
    assert [list(x) for x in out] == [[0, 1, 2, 3], [7, 6, 5]]
    with pytest.raises(InputFileError):
        loops_from_flat(flat, [0, 4, 6])
    with pytest.raises(InputFileError):
        loops_from_flat(flat, [0, 4, 7], n_points=7)


def test_cell_arrays_are_read_with_optional_parts(results_dir):
    rows = load_results(results_dir).rows
    ocp = rows[(rows["method"] == "ocp") & (rows["status"] == "ok")].iloc[0]
    arrays = load_cell_arrays(results_dir, ocp["artifact"])
    assert arrays.points.shape[1] == 3 and arrays.uv.shape == (len(arrays.points), 2)
    assert arrays.qc.shape == arrays.flipped.shape == (len(arrays.faces),)
    assert arrays.flipped.sum() == ocp["foldovers"]
    assert len(arrays.gt_loops) == 1 and len(arrays.det_loops) == 1
    assert set(arrays.landscape) == {"k", "E", "t"}
    lscm = rows[(rows["method"] == "lscm")].iloc[0]
    assert load_cell_arrays(results_dir, lscm["artifact"]).landscape is None
    assert load_cell_arrays(results_dir, "") is None
    assert load_cell_arrays(results_dir, "cells/not-there.npz") is None


def test_inconsistent_cell_arrays_raise(tmp_path):
    np.savez(tmp_path / "bad.npz", points=np.zeros((4, 3)), faces=np.array([[0, 1, 2]]), uv=np.zeros((3, 2)),
             qc=np.ones(1), flipped=np.zeros(1, bool))
    with pytest.raises(InputFileError, match="shapes"):
        load_cell_arrays(tmp_path, "bad.npz")
    np.savez(tmp_path / "bad2.npz", points=np.zeros((3, 3)), faces=np.array([[0, 1, 5]]), uv=np.zeros((3, 2)),
             qc=np.ones(1), flipped=np.zeros(1, bool))
    with pytest.raises(InputFileError, match="out of range"):
        load_cell_arrays(tmp_path, "bad2.npz")
    (tmp_path / "bad3.npz").write_bytes(b"not an npz")
    with pytest.raises(InputFileError):
        load_cell_arrays(tmp_path, "bad3.npz")


def test_dataset_arrays_found_by_contract_key(results_dir):
    # sizes and seeds come back from the table as floats; the key is the one the sweep writes
    keys = dataset_key_candidates("bump", 144.0, "poisson", 0.0, 1.0)
    assert keys == ["bump-144-poisson-n0-s1"] == [Cell("bump", 144, "poisson", 0.0, 1, "ocp").dataset_key]
    data = load_dataset_arrays(results_dir, keys)
    assert {"w_tan_interior", "w_cot_boundary", "det_boundary_mask"} <= set(data)
    assert len(data["gt_loops"]) == 1
    assert load_dataset_arrays(results_dir, ["nothing-here"]) is None
    assert dataset_key_candidates("real/bunny", 0, "", 0.0, 0) == ["real_bunny-0--n0-s0"]
    assert dataset_key_candidates("bump", 144, "poisson", 0.05, 2) == ["bump-144-poisson-n0.05-s2"]


def _tiny_npz(path, **extra):
    np.savez(path, points=np.zeros((3, 3)), faces=np.array([[0, 1, 2]]), uv=np.zeros((3, 2)), qc=np.ones(1),
             flipped=np.zeros(1, bool), **extra)


def test_landscape_with_one_turning_number_per_loop_keeps_the_outer_loop(tmp_path):
    k = np.array([1.0, 2.0, 3.0])
    t = np.array([[3.0, -1.0], [2.0, -1.0], [1.0, -1.0]])
    _tiny_npz(tmp_path / "a.npz", landscape_k=k, landscape_E=k**2, landscape_t=t)
    arrays = load_cell_arrays(tmp_path, "a.npz")
    assert list(arrays.landscape["t"]) == [3.0, 2.0, 1.0]
    assert arrays.problems == []


def test_mismatched_landscape_is_left_out_but_the_map_is_kept(tmp_path):
    _tiny_npz(tmp_path / "b.npz", landscape_k=np.ones(3), landscape_E=np.ones(4), landscape_t=np.ones(3))
    arrays = load_cell_arrays(tmp_path, "b.npz")
    assert arrays.landscape is None
    assert arrays.uv.shape == (3, 2)
    assert len(arrays.problems) == 1 and "landscape left out" in arrays.problems[0]


def _table_only(root, keep):
    """Leave one consolidated table and nothing else to read: no cell file, no other table."""
    for path in (root / "cells").glob("*.json"):
        path.unlink()
    for name in ("results.parquet", "results.csv"):
        if name != keep:
            (root / name).unlink()
    return root / keep


def _cut_at(path, marker, extra=0):
    """Cut the table in its fifth line, ``extra`` characters after ``marker``: a copy stopped mid-row."""
    lines = path.read_text().splitlines(keepends=True)
    path.write_text("".join(lines[:4]) + lines[4][:lines[4].index(marker) + extra])


def _cut_in_a_quoted_field(path):
    _cut_at(path, '""solve""')  # inside the quoted JSON of the timings


def _cut_in_a_number(path):
    _cut_at(path, ",ok,,,", 8)  # in qc_mean: the parser reads the short row without a word
    assert len(pd.read_csv(path)) == 4


def _without_cell_id(path):
    pd.read_csv(path).drop(columns="cell_id").to_csv(path, index=False)


def _header_only(path):
    path.write_text(path.read_text().splitlines(keepends=True)[0])


@pytest.mark.parametrize("keep, damage, fault", [
    ("results.csv", _cut_in_a_quoted_field, "EOF inside string"),
    ("results.csv", _cut_in_a_number, "cut off mid-row"),
    ("results.csv", _without_cell_id, "no cell_id column (columns: dataset, size,"),
    ("results.csv", _header_only, "no row"),
    ("results.csv", lambda p: p.write_bytes(b""), "empty file (0 bytes)"),
    ("results.parquet", lambda p: p.write_text("garbage\n"), "unreadable (ArrowInvalid"),
])
def test_a_table_that_cannot_be_used_is_named_with_its_fault(results_dir, keep, damage, fault):
    damage(_table_only(results_dir, keep))
    with pytest.raises(EmptyResultsError) as info:
        load_results(results_dir)
    message = str(info.value)
    assert f"skipped {keep}: " in message and fault in message
    assert "\n" not in message and "no results.parquet or results.csv" not in message


def test_a_table_without_cell_id_beside_cell_files_is_a_warning(results_dir):
    (results_dir / "results.parquet").unlink()
    _without_cell_id(results_dir / "results.csv")
    results = load_results(results_dir)
    assert len(results.rows) == len(list((results_dir / "cells").glob("*.json")))
    assert any(w.startswith("skipped results.csv: no cell_id column") for w in results.warnings)


def test_a_file_given_for_the_folder_is_said_to_be_a_file(results_dir):
    with pytest.raises(EmptyResultsError) as info:
        load_results(results_dir / "results.csv")
    message = str(info.value)
    assert "is a file" in message and str(results_dir) in message and "does not exist" not in message


def test_the_command_line_names_the_bad_table_in_one_line_and_exits_2(results_dir, capsys):
    from parambench.bench.cli import main

    _without_cell_id(_table_only(results_dir, "results.csv"))
    assert main(["report", str(results_dir)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "results.csv: no cell_id column" in err[0] and "Traceback" not in err[0]
    assert main(["report", str(results_dir / "results.csv")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "results.csv is a file" in err[0]
