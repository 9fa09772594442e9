"""A sweep cell whose point-set map fails its self-check is stored as 'suspect', with metrics."""

from __future__ import annotations

import json

from parambench.bench.cells import Cell
from parambench.bench.run_cell import compute_cell


def test_spinning_map_is_stored_as_suspect_with_its_metrics():
    row, arrays = compute_cell(Cell("bump", 900, "jittered", 0.0, 0, "scp-tan"))
    assert row["status"] == "suspect"
    assert row["error_type"] == "SelfCheck" and "turns" in row["error"]
    check = json.loads(row["diagnostics"])["selfcheck"]
    assert check["passed"] is False and "turning" in check["failed"]
    # Metrics are computed on the ground-truth mesh as for an ok cell, and show the spin.
    assert row["qc_mean"] is not None and row["qc_mean"] > 1.0
    assert max(json.loads(row["turning_numbers"])) > 1.5
    assert arrays is not None and "uv" in arrays


def test_a_good_map_stays_ok():
    row, _ = compute_cell(Cell("bump", 900, "jittered", 0.0, 0, "sdp"))
    assert row["status"] == "ok" and row["error"] == ""
    assert json.loads(row["diagnostics"])["selfcheck"]["passed"] is True
