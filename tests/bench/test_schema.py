"""The results schema: what the sweep writes is what the report reads, column for column."""

import json

import numpy as np
import pytest

from parambench.bench.cells import Cell
from parambench.bench.dataset_diagnostics import store_missing_diagnostics
from parambench.bench.metrics import evaluate, self_scored
from parambench.bench.run_cell import compute_cell, store_cell
from parambench.bench.schema import (JSON_COLUMNS, METRIC_KEYS, NUMERIC_COLUMNS, ROW_COLUMNS, SELFMESH_KEYS, TEXT_COLUMNS,
                          dataset_key, decode_json, decode_loops, encode_json, encode_loops, slug)
from parambench.bench.storage import ResultStore
from parambench.datasets_gen.errors import InputFileError
from parambench.datasets_gen.registry import make_surface
from parambench.reports.load import dataset_key_candidates, load_cell_arrays, load_dataset_arrays, load_results


def test_column_kinds_partition_the_row():
    assert len(set(ROW_COLUMNS)) == len(ROW_COLUMNS)
    kinds = [set(NUMERIC_COLUMNS), set(TEXT_COLUMNS), set(JSON_COLUMNS)]
    assert set().union(*kinds) == set(ROW_COLUMNS)
    assert sum(map(len, kinds)) == len(ROW_COLUMNS)
    assert {"qc_mean", "foldovers", "size", "seed", "selfmesh_qc_mean"} <= set(NUMERIC_COLUMNS)
    assert {"turning_numbers", "angle_hist", "params"} <= set(JSON_COLUMNS)


def test_metric_keys_are_what_the_metrics_return():
    surface = make_surface("holes", 500, seed=0)
    uv = surface.points[:, :2]
    assert tuple(evaluate(surface.points, surface.faces, uv)) == METRIC_KEYS
    assert set(self_scored(surface.points, uv, surface.boundary_loops)) == {f"selfmesh_{k}" for k in SELFMESH_KEYS}


def test_keys_and_slugs():
    assert slug("real/bunny 10k") == "real_bunny_10k"
    assert dataset_key("bump", 144.0, "poisson", 0.0, 1.0) == dataset_key("bump", 144, "poisson", 0, 1)
    assert dataset_key("bump", 144, "poisson", float("nan"), 1) == "bump-144-poisson-n0-s1"
    assert Cell("real/camelhead", 0, "", 0.1, 3, "ocp").dataset_key == "real_camelhead-0--n0.1-s3"


def test_json_columns_round_trip():
    value = {"b": np.float64(0.5), "a": [np.int64(1), 2], "c": np.arange(2)}
    text = encode_json(value)
    assert text == '{"a": [1, 2], "b": 0.5, "c": [0, 1]}'
    assert decode_json(text) == {"a": [1, 2], "b": 0.5, "c": [0, 1]}
    assert decode_json("", default=[]) == [] and decode_json(float("nan")) is None and decode_json("{x") is None


def test_loops_round_trip():
    loops = [np.array([3, 4, 5, 6]), np.array([0, 1, 2])]
    arrays = encode_loops("gt", loops)
    assert arrays["gt_loops_offsets"].tolist() == [0, 4, 7]
    back = decode_loops(arrays, "gt", n_points=7)
    assert [lp.tolist() for lp in back] == [lp.tolist() for lp in loops]
    assert encode_loops("gt", None) == {} and decode_loops({}, "gt") is None
    with pytest.raises(InputFileError, match="lie in"):
        decode_loops(arrays, "gt", n_points=6)


@pytest.mark.parametrize("method", ["scp", "lem"])
def test_a_stored_cell_reads_back_with_every_column(tmp_path, method):
    cell = Cell("holes", 500, "jittered", 0.0, 0, method)
    row, arrays = compute_cell(cell)
    assert row["status"] in ("ok", "suspect"), row["error"]
    # the writer fills exactly the schema's columns (peak_rss_mb only in isolated sweeps)
    assert set(row) == set(ROW_COLUMNS) - {"peak_rss_mb"}
    store = ResultStore(tmp_path)
    store_cell(store, row, arrays)
    assert store_missing_diagnostics(store, [cell]) == []
    back = load_results(tmp_path).rows.iloc[0]
    for col in NUMERIC_COLUMNS:
        expected = row.get(col)
        if expected is None:
            assert np.isnan(back[col]), col
        else:
            assert back[col] == pytest.approx(expected), col
    for col in JSON_COLUMNS:
        assert json.loads(back[col]) == json.loads(row[col]), col
    cell_arrays = load_cell_arrays(tmp_path, back["artifact"])
    assert cell_arrays.flipped.sum() == row["foldovers"]
    true_loops = make_surface("holes", 500, seed=0).boundary_loops
    assert [len(lp) for lp in cell_arrays.gt_loops] == [len(lp) for lp in true_loops]
    # the report finds the surface's diagnostics under the key the sweep wrote them
    keys = dataset_key_candidates(back["dataset"], back["size"], back["sampling"], back["noise"], back["seed"])
    surface = load_dataset_arrays(tmp_path, keys)
    assert surface is not None and len(surface["gt_loops"]) == 4


def test_surface_diagnostics_cotangent_rows_are_normalised():
    from parambench.bench.dataset_diagnostics import surface_diagnostics

    surface = make_surface("holes", 500, seed=2)
    arrays = surface_diagnostics(surface)
    n_boundary = int(surface.boundary_mask.sum())
    # every row of the row-normalised cotangent weights sums to 1
    assert arrays["w_cot_boundary"].sum() == pytest.approx(n_boundary)
    assert arrays["w_cot_interior"].sum() == pytest.approx(surface.n_points - n_boundary)
    assert [len(lp) for lp in decode_loops(arrays, "gt")] == [len(lp) for lp in surface.boundary_loops]
