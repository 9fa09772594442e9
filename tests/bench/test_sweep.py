"""The sweep: one row per cell, resumable (failed cells retried, unreadable ones recomputed), one per folder,
validated before any work, failures recorded, deterministic."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import pandas as pd
import pytest

from parambench.bench.cells import Cell
from parambench.datasets_gen.errors import InvalidInputError
from parambench.bench.storage import ResultStore
from parambench.bench.suites import Suite, expand_cells, get_suite
from parambench.bench.sweep import run_sweep

TINY = Suite(name="tiny", datasets=("plane", "saddle"), sizes=(600,), samplings=("jittered",), seeds=(0,),
             methods=("lscm-igl", "scp-igl"))


def test_expand_cells_is_deterministic_and_complete():
    cells = expand_cells(TINY)
    assert len(cells) == 4 and cells == expand_cells(TINY)
    assert len({c.cell_id for c in cells}) == 4
    real = expand_cells(TINY.with_overrides(datasets=["real/lilium"], sizes=[600, 900]))
    assert len(real) == 2 and all(c.size == 0 for c in real)  # real data ignores sizes


def test_a_value_given_twice_is_one_cell():
    """--seeds 0 0 0 computed one cell three times; --noise -0 got a cell id of its own (n-0)."""
    twice = TINY.with_overrides(methods=["scp-igl", "scp-igl"], seeds=[0, 0, 0], noise=[-0.0, 0.0])
    cells = expand_cells(twice)
    assert cells == expand_cells(TINY.with_overrides(methods=["scp-igl"]))
    assert all(str(c.noise) == "0.0" for c in cells)


def test_a_surface_that_cannot_be_rebuilt_for_its_pictures_does_not_stop_the_sweep(monkeypatch, tmp_path):
    """Its cells already failed and say why; the pass that stores the surfaces' diagnostics
    rebuilt it and died with a traceback (a MemoryError, an overflow), before the table and
    the report were written, on every run."""
    import parambench.bench.dataset_diagnostics as diagnostics
    from parambench.bench.dataset_diagnostics import store_missing_diagnostics

    def broken(*args, **kwargs):
        raise MemoryError("cannot allocate")

    monkeypatch.setattr(diagnostics, "surface_for", broken)
    problems = store_missing_diagnostics(ResultStore(tmp_path), expand_cells(TINY))
    assert len(problems) == 2 and all("MemoryError: cannot allocate" in p for p in problems)


def test_scattered_sampling_reaches_real_meshes_only_and_their_cells_run(tmp_path):
    suite = TINY.with_overrides(datasets=["real/lilium", "plane", "real/bunny10k"], sizes=[800],
                                samplings=["jittered", "scattered"], methods=["scp-igl", "ocp"])
    cells = expand_cells(suite)
    assert {(c.dataset, c.size, c.sampling) for c in cells} == {
        ("real/lilium", 800, "scattered"), ("plane", 800, "jittered"), ("real/bunny10k", 800, "scattered")}
    table = run_sweep(suite, str(tmp_path), progress=False)
    lilium = table[table.dataset == "real/lilium"].set_index("method")
    assert set(lilium["status"]) == {"ok"} and (lilium["n_points"] == 800).all()
    assert lilium.loc["ocp", "qc_mean"] < 1.03 * lilium.loc["scp-igl", "qc_mean"]
    with pytest.raises(InvalidInputError, match="real meshes only"):  # nothing to scatter
        expand_cells(suite.with_overrides(datasets=["plane"], samplings=["scattered"]))
    # bunny10k cannot be scattered (libigl's map of its five holes folds): recorded, not fatal
    bunny = table[table.dataset == "real/bunny10k"]
    assert set(bunny["status"]) == {"failed"} and bunny["error"].str.contains("folds").all()


def test_quick_suite_covers_every_registered_method():
    from parambench.methods.registry import method_names

    cells = expand_cells(get_suite("quick"))
    assert {c.method for c in cells} == set(method_names())


def test_full_suite_has_at_least_five_real_meshes():
    from parambench.datasets_gen.real import REAL_DATASETS

    full = get_suite("full").datasets
    real_meshes = [name for name in full if name in REAL_DATASETS and not REAL_DATASETS[name].points_only]
    assert len(real_meshes) >= 5
    # Every shipped mesh is in the full suite, and the quick one keeps two real meshes.
    shipped = [name for name, spec in REAL_DATASETS.items() if spec.location == "package"]
    assert set(shipped) <= set(full) and {"real/meg-helmet", "real/spot-top", "real/cortex-lh"} <= set(shipped)
    quick = get_suite("quick").datasets
    assert [name for name in quick if name in REAL_DATASETS] == ["real/lilium", "real/spot-top"]
    # Each real cell runs once, at the file's own size.
    real_cells = [c for c in expand_cells(get_suite("full")) if c.dataset in REAL_DATASETS]
    assert real_cells and {c.size for c in real_cells} == {0}


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
    # chameleon's file normals point both ways (46 of 4594): ocp refuses them
    suite = TINY.with_overrides(datasets=["plane", "real/chameleon"], methods=["ocp"])
    table = run_sweep(suite, str(tmp_path), progress=False)
    assert len(table) == 2
    failed = table[table.status == "failed"].iloc[0]
    assert failed.dataset == "real/chameleon" and failed.error_type == "InconsistentNormalsError"
    assert "other side of the surface" in failed.error and pd.isna(failed.qc_mean)
    assert table[table.dataset == "plane"].iloc[0].status == "ok"


def test_same_command_same_table(tmp_path):
    a = run_sweep(TINY, str(tmp_path / "a"), progress=False)
    b = run_sweep(TINY, str(tmp_path / "b"), progress=False)
    cols = ["cell_id", "qc_mean", "qc_max", "foldovers", "area_distortion", "exact_error"]
    pd.testing.assert_frame_equal(a[cols], b[cols])


def test_killed_run_keeps_finished_cells(tmp_path):
    out = tmp_path / "r"
    argv = [sys.executable, "-m", "parambench.bench.cli", "run", "--datasets", "plane", "saddle", "bump", "cap",
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


# Cheap cells for the resume tests: our own SCP on a 500-point plane.
PLANE = Suite(name="plane", datasets=("plane",), sizes=(500,), samplings=("jittered",), seeds=(0, 1),
              methods=("scp",))


def _mtimes(folder: Path) -> dict:
    return {p.name: p.stat().st_mtime_ns for p in (folder / "cells").glob("*.json")}


def _plan_line(err: str) -> str:
    return next(line for line in err.splitlines() if " done, " in line)


def test_failed_cells_are_retried_unless_kept(tmp_path, capsys):
    from parambench.bench.run_cell import failed_row

    first, second = expand_cells(PLANE)
    store = ResultStore(tmp_path)
    store.write_row(failed_row(first, "InputFileError", "data path missing"))  # the earlier run's failure
    store.write_row({**failed_row(second, "", ""), "status": "suspect"})  # finished, though doubtful
    before = _mtimes(tmp_path)

    kept = run_sweep(PLANE, str(tmp_path), progress=False, diagnostics=False, retry_failed=False)
    assert _plan_line(capsys.readouterr().err) == \
        "parambench: 1 done, 0 to run (0 new), 1 failed before and kept (--keep-failed; drop it to retry them)"
    assert _mtimes(tmp_path) == before and sorted(kept.status) == ["failed", "suspect"]

    table = run_sweep(PLANE, str(tmp_path), progress=False, diagnostics=False)
    assert _plan_line(capsys.readouterr().err) == "parambench: 1 done, 1 to run (0 new, 1 failed before and retried)"
    by_id = table.set_index("cell_id")
    assert by_id.loc[first.cell_id, "status"] == "ok" and by_id.loc[first.cell_id, "qc_mean"] < 1 + 1e-6
    assert by_id.loc[second.cell_id, "status"] == "suspect"  # not recomputed
    assert _mtimes(tmp_path)[f"{second.cell_id}.json"] == before[f"{second.cell_id}.json"]


def test_truncated_cell_file_is_reported_and_recomputed(tmp_path, capsys):
    reference = run_sweep(PLANE, str(tmp_path), progress=False, diagnostics=False)
    capsys.readouterr()
    broken, intact = (tmp_path / "cells" / f"{c.cell_id}.json" for c in expand_cells(PLANE))
    broken.write_bytes(broken.read_bytes()[:57])
    intact_mtime = intact.stat().st_mtime_ns

    table = run_sweep(PLANE, str(tmp_path), progress=False, diagnostics=False)
    err = capsys.readouterr().err
    notes = [line for line in err.splitlines() if broken.name in line]
    assert len(notes) == 1 and "not valid JSON" in notes[0] and "recomputed" in notes[0]
    assert _plan_line(err) == "parambench: 1 done, 1 to run (0 new, 1 unreadable and recomputed)"
    assert json.loads(broken.read_text())["status"] == "ok" and intact.stat().st_mtime_ns == intact_mtime
    assert broken.with_name(broken.name + ".unreadable").stat().st_size == 57  # the evidence is kept
    cols = ["cell_id", "qc_mean", "exact_error"]
    pd.testing.assert_frame_equal(table[cols], reference[cols])


def test_sweep_refuses_a_folder_in_use_and_computes_nothing(tmp_path):
    from parambench.bench.folder_lock import hold_folder
    from parambench.datasets_gen.errors import ResultsInUseError

    (tmp_path / "r").mkdir()
    with hold_folder(tmp_path / "r"):  # stands in for another sweep on the same folder
        with pytest.raises(ResultsInUseError, match="--wait"):
            run_sweep(PLANE, str(tmp_path / "r"), progress=False)
    assert not list((tmp_path / "r").glob("cells/*.json")) and not (tmp_path / "r" / "run.json").exists()


@pytest.mark.parametrize("field, value, error", [
    ("methods", ("magic",), "UnknownNameError"), ("datasets", ("nowhere",), "UnknownNameError"),
    ("sizes", (0,), "TooFewPointsError"), ("sizes", (99,), "TooFewPointsError"),
    ("sizes", (500.5,), "InvalidInputError"),
    ("seeds", (-1,), "InvalidInputError"), ("samplings", ("poisson",), "UnknownNameError"),
    ("noise", (-0.1,), "InvalidInputError"), ("noise", (float("inf"),), "InvalidInputError"),
    ("seeds", (), "InvalidInputError"),
])
def test_bad_suite_is_refused_before_any_folder(tmp_path, field, value, error):
    out = tmp_path / "r"
    with pytest.raises(Exception) as exc:
        run_sweep(replace(PLANE, **{field: value}), str(out), progress=False)
    assert type(exc.value).__name__ == error and f"--{field}:" in str(exc.value)
    assert not out.exists()


def test_bad_workers_refused_before_any_folder(tmp_path):
    from parambench.datasets_gen.errors import InvalidInputError

    with pytest.raises(InvalidInputError, match="--workers"):
        run_sweep(PLANE, str(tmp_path / "r"), workers=0, progress=False)
    assert not (tmp_path / "r").exists()


def test_progress_and_summary_label_variants_as_the_report(tmp_path, capsys):
    from parambench.bench.sweep import summary_table

    suite = replace(PLANE, seeds=(0,), variants=(("scp", (("b_matrix", "mass"),)),))
    table = run_sweep(suite, str(tmp_path), progress=True, diagnostics=False)
    err = capsys.readouterr().err
    assert "plane scp [b_matrix=mass] ok" in err  # the progress bar's last postfix
    text = summary_table(table)
    assert "scp [b_matrix=mass]" in text and "2 ok, 0 failed of 2 cells" in text
    rows = table.assign(status=["suspect", "failed"], error_type=["", "SolverError"], error=["", "boom"])
    text = summary_table(rows)
    assert "0 ok, 1 suspect, 1 failed of 2 cells" in text
    # Each line names the cell's surface: lines of different seeds or samplings looked the same.
    assert "SUSPECT plane · 500 pts · jittered · seed 0 / scp" in text
    assert "FAILED plane · 500 pts · jittered · seed 0 / scp [b_matrix=mass]: SolverError: boom" in text


def test_summary_shows_suspect_cells_figures_marked():
    """A suspect cell has a map and metrics: the summary shows its QC (marked), not NaN."""
    import pandas as pd

    from parambench.bench.sweep import SUSPECT_MARK, summary_table

    rows = pd.DataFrame({
        "method": ["ocp", "ocp", "scp-tan", "lem"],
        "params": ["{}", "{}", "{}", "{}"],
        "dataset": ["bump", "holes", "bump", "bump"],
        "status": ["ok", "suspect", "suspect", "failed"],
        "qc_mean": [1.0123, 1.4567, 2.25, None],
        "foldovers": [0, 3, 17, None],
        "time_total": [1.0, 2.0, 0.5, None],
        "error_type": ["", "SelfCheck", "SelfCheck", "SolverError"],
        "error": ["", "4 flipped triangle(s) of 3711", "loop 0 turns +2.00 (expected +1)", "boom"],
    })
    text = summary_table(rows)
    assert "nan" not in text.lower()
    qc_block = text.split("\n\n")[0]
    ocp_line = next(line for line in qc_block.splitlines() if line.startswith("ocp"))
    # ok figure unmarked, suspect figure marked; both present
    assert "1.012" in ocp_line and f"1.012{SUSPECT_MARK}" not in ocp_line
    assert f"1.457{SUSPECT_MARK}" in ocp_line
    # a variant whose only cells are suspect still has a row; no map on holes: "-"
    tan_line = next(line for line in qc_block.splitlines() if line.startswith("scp-tan"))
    assert f"2.250{SUSPECT_MARK}" in tan_line and tan_line.split()[-1] == "-"
    # a failed cell has no map: lem has no QC row
    assert not any(line.startswith("lem") for line in qc_block.splitlines())
    counts = text.split("\n\n")[1]
    ocp_counts = next(line for line in counts.splitlines() if line.startswith("ocp")).split()
    assert ocp_counts[1:] == ["3", "1.5", "1"]  # foldovers over ok + suspect, median time, 1 suspect cell
    assert "1 ok, 2 suspect, 1 failed of 4 cells" in text


def test_the_report_step_runs_while_the_folder_is_still_held(tmp_path):
    """The command line built the report after the lock was released, so a sweep waiting on
    the folder (--wait) ran alongside it and wrote the same report files."""
    from parambench.bench.folder_lock import hold_folder
    from parambench.datasets_gen.errors import ResultsInUseError

    held = []

    def then(table):
        with pytest.raises(ResultsInUseError):
            with hold_folder(Path(tmp_path)):
                pass
        held.append(len(table))

    run_sweep(replace(TINY, datasets=("plane",)), str(tmp_path), progress=False, diagnostics=False, then=then)
    assert held == [2]


def test_summary_says_how_many_suspect_cells_it_left_unlisted():
    """Twelve suspect cells printed ten lines and nothing more (failed cells had "... and N more")."""
    import pandas as pd

    from parambench.bench.sweep import summary_table

    rows = pd.DataFrame({"method": ["lem"] * 12, "params": ["{}"] * 12, "dataset": ["bump"] * 12,
                         "n_points": [500] * 12, "sampling": ["jittered"] * 12, "noise": [0.0] * 12,
                         "seed": list(range(12)), "status": ["suspect"] * 12, "qc_mean": [1.5] * 12,
                         "foldovers": [2] * 12, "time_total": [1.0] * 12, "error_type": ["SelfCheck"] * 12,
                         "error": ["2 flipped triangle(s)"] * 12})
    text = summary_table(rows)
    assert text.count("  SUSPECT ") == 10 and "  ... and 2 more (see results.csv)" in text


def test_real_datasets_say_they_ignore_the_noise(tmp_path, capsys):
    """``--datasets real/lilium --noise 0.5`` ran the clean file and stored it with noise 0, silently."""
    from parambench.bench.suites import real_dataset_note

    noisy = replace(PLANE, datasets=("plane", "real/lilium"), noise=(0.0, 0.5), samplings=("random",))
    note = real_dataset_note(noisy)
    assert note is not None and "real/lilium run on the file's own points, without noise (0.5)" in note
    assert real_dataset_note(replace(noisy, noise=(0.0,))) is None
    assert real_dataset_note(replace(noisy, samplings=("random", "scattered"))) is None
    assert real_dataset_note(replace(noisy, datasets=("plane",))) is None


def test_mesh_methods_get_no_cells_on_a_point_set_without_faces():
    """``real/chameleon`` (points and normals, no faces) gave every mesh method a failed cell."""
    from parambench.bench.suites import expand_cells

    suite = replace(PLANE, datasets=("plane", "real/chameleon"), methods=("ocp", "scp-igl"), seeds=(0,))
    cells = expand_cells(suite)
    assert {(c.dataset, c.method) for c in cells} == {("plane", "ocp"), ("plane", "scp-igl"),
                                                      ("real/chameleon", "ocp")}
    with pytest.raises(InvalidInputError, match="hold\\(s\\) points without faces"):
        expand_cells(replace(suite, datasets=("real/chameleon",), methods=("scp-igl",)))
