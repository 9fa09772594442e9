"""The sweep: one row per cell, resumable, failures recorded, deterministic."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest

from bench.cells import Cell
from bench.storage import ResultStore
from bench.suites import Suite, expand_cells, get_suite
from bench.sweep import run_sweep

TINY = Suite(name="tiny", datasets=("plane", "saddle"), sizes=(600,), samplings=("jittered",), seeds=(0,),
             methods=("lscm-igl", "scp-igl"))


def test_expand_cells_is_deterministic_and_complete():
    cells = expand_cells(TINY)
    assert len(cells) == 4 and cells == expand_cells(TINY)
    assert len({c.cell_id for c in cells}) == 4
    real = expand_cells(TINY.with_overrides(datasets=["real/lilium"], sizes=[600, 900]))
    assert len(real) == 2 and all(c.size == 0 for c in real)  # real data ignores sizes


def test_quick_suite_covers_every_registered_method():
    from methods.registry import method_names

    cells = expand_cells(get_suite("quick"))
    assert {c.method for c in cells} == set(method_names())


def test_sweep_rows_metrics_and_resume(tmp_path):
    table = run_sweep(TINY, str(tmp_path), progress=False)
    assert len(table) == 4 and set(table["status"]) == {"ok"}
    assert (tmp_path / "results.parquet").exists() and (tmp_path / "results.csv").exists()
    assert json.loads((tmp_path / "run.json").read_text())["seeds"] == [0]
    plane = table[(table.dataset == "plane")]
    assert (plane["qc_mean"] < 1.0 + 1e-6).all() and (plane["exact_error"] < 1e-6).all()
    assert (table["foldovers"] == 0).all()
    for row in table.itertuples():  # peak memory per stage: the method's own stages, plus "other"
        memory = json.loads(row.stage_memory_mb)
        assert memory and set(memory) <= set(json.loads(row.timings)) | {"other"}
        assert all(v > 0 for v in memory.values())
    mtimes = {p.name: p.stat().st_mtime_ns for p in (tmp_path / "cells").glob("*.json")}
    again = run_sweep(TINY, str(tmp_path), progress=False)
    assert len(again) == 4
    assert mtimes == {p.name: p.stat().st_mtime_ns for p in (tmp_path / "cells").glob("*.json")}
    assert json.loads((tmp_path / "run.json").read_text())["n_skipped"] == 4


def test_failing_cell_is_recorded_and_sweep_goes_on(tmp_path):
    suite = TINY.with_overrides(datasets=["plane", "real/chameleon"], methods=["scp-igl"])
    table = run_sweep(suite, str(tmp_path), progress=False)
    assert len(table) == 2
    failed = table[table.status == "failed"].iloc[0]
    assert failed.dataset == "real/chameleon" and failed.error_type == "MissingFacesError"
    assert "point set" in failed.error and pd.isna(failed.qc_mean)
    assert table[table.dataset == "plane"].iloc[0].status == "ok"


def test_same_command_same_table(tmp_path):
    a = run_sweep(TINY, str(tmp_path / "a"), progress=False)
    b = run_sweep(TINY, str(tmp_path / "b"), progress=False)
    cols = ["cell_id", "qc_mean", "qc_max", "foldovers", "area_distortion", "exact_error"]
    pd.testing.assert_frame_equal(a[cols], b[cols])


def test_killed_run_keeps_finished_cells(tmp_path):
    out = tmp_path / "r"
    argv = [sys.executable, "-m", "bench.cli", "run", "--datasets", "plane", "saddle", "bump", "cap",
            "--sizes", "800", "--methods", "scp-igl", "lscm-igl", "--out", str(out), "--no-report", "--no-progress"]
    proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            cwd=Path(__file__).resolve().parents[2])
    deadline = time.time() + 120
    while time.time() < deadline and len(list((out / "cells").glob("*.json"))) < 2:
        time.sleep(0.05)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    kept = {p.name: p.stat().st_mtime_ns for p in (out / "cells").glob("*.json")}
    assert len(kept) >= 2
    for path in (out / "cells").glob("*.json"):
        assert json.loads(path.read_text())["cell_id"] == path.stem  # no half-written row
    table = run_sweep(get_suite("quick").with_overrides(
        datasets=["plane", "saddle", "bump", "cap"], sizes=[800], methods=["scp-igl", "lscm-igl"]),
        str(out), progress=False)
    assert len(table) == 8 and table.cell_id.is_unique and set(table.status) == {"ok"}
    for name, mtime in kept.items():
        assert (out / "cells" / name).stat().st_mtime_ns == mtime  # not recomputed


def test_isolated_cells_record_their_peak_memory_and_same_values(tmp_path):
    suite = TINY.with_overrides(datasets=["plane"], methods=["scp-igl"])
    isolated = run_sweep(suite, str(tmp_path / "iso"), progress=False, isolate=True)
    serial = run_sweep(suite, str(tmp_path / "serial"), progress=False)
    assert isolated.loc[0, "peak_rss_mb"] > 50  # a whole interpreter with numpy and libigl
    cols = ["cell_id", "qc_mean", "qc_max", "exact_error"]
    pd.testing.assert_frame_equal(isolated[cols], serial[cols])
