"""parambench report A B: cells matched across runs, regressions listed first, the CLI prints them."""

import json
import shutil

import pytest

from parambench.bench.cli import main
from parambench.reports.compare import build_comparison, compare_rows
from parambench.reports.load import load_results


def _edit(root, dataset, size, seed, method, **changes):
    for path in (root / "cells").glob(f"{dataset}-{size}-poisson-s{seed}-{method}-*.json"):
        row = json.loads(path.read_text())
        row.update(changes)
        path.write_text(json.dumps(row))
        return
    raise AssertionError("no such cell")


@pytest.fixture
def two_runs(tmp_path, make_results):
    a = tmp_path / "a"
    make_results(a)
    b = tmp_path / "b"
    shutil.copytree(a, b)
    for name in ("results.parquet", "results.csv"):  # the cell files are the truth; drop the stale tables
        (b / name).unlink()
    rows = {r["cell_id"]: r for r in (json.loads(p.read_text()) for p in (a / "cells").glob("*.json"))}
    bump_scp = next(r for r in rows.values() if r["dataset"] == "bump" and r["size"] == 144 and r["seed"] == 0
                    and r["method"] == "scp")
    _edit(b, "bump", 144, 0, "scp", qc_mean=bump_scp["qc_mean"] * 1.02)  # QC regression
    _edit(b, "bump", 400, 1, "lscm", foldovers=4)  # foldover regression
    _edit(b, "saddle", 144, 0, "lscm", status="failed", error_type="SolverError", error="x")  # status regression
    _edit(b, "saddle", 144, 1, "ocp", status="ok", qc_mean=1.1, foldovers=0, time_total=1.0)  # was failed in A
    (next((b / "cells").glob("bump-400-poisson-s0-ocp-*.json"))).unlink()  # only in A
    return a, b


def test_regressions_come_first_most_severe_first(two_runs):
    a, b = two_runs
    diff = compare_rows(load_results(a).rows, load_results(b).rows)
    changes = list(diff["change"])
    assert changes[:3] == ["regression"] * 3
    assert changes.count("regression") == 3
    assert diff.loc[0, "what"] == "status ok → failed"
    assert diff.loc[1, "what"] == "foldovers 0 → 4"
    assert diff.loc[2, "what"] == "QC +2.00%"
    assert changes[3] == "only in A"
    assert "improvement" in changes and diff[diff["change"] == "improvement"]["what"].iloc[0] == "status failed → ok"
    assert changes.count("unchanged") == len(diff) - 5
    # the first rows name their cells
    assert diff.loc[0, "config"] == "saddle · 144 pts · poisson" and diff.loc[0, "variant"] == "lscm"


def test_comparison_page_and_cli(two_runs, tmp_path, capsys):
    a, b = two_runs
    paths, diff = build_comparison(a, b, out_dir=tmp_path / "cmp")
    page = paths["html"].read_text()
    assert page.count('<table class="comparison"') == 1
    assert page.index("status ok → failed") < page.index("QC +2.00%") < page.index("status failed → ok")
    assert "Regression:" in page  # the rule under the table
    assert main(["report", str(a), str(b), "--out", str(tmp_path / "cli")]) == 0
    out = capsys.readouterr().out
    assert out.splitlines()[0].startswith("3 regression, 1 improvement")
    assert "REGRESSION saddle · 144 pts · poisson / lscm: status ok → failed" in out
    assert (tmp_path / "cli" / "compare.html").is_file()


def test_compare_with_a_missing_folder_is_one_line_and_exit_2(tmp_path, make_results, capsys):
    a = tmp_path / "a"
    make_results(a)
    assert main(["report", str(a), str(tmp_path / "nope")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "EmptyResultsError" in err[0] and "nope" in err[0]


def test_swapping_the_runs_mirrors_the_changes(two_runs):
    """A time of 0.467 -> 0.362 s (x0.775) was "unchanged" one way and a regression the other: the
    improvement threshold was 1 - tol, not 1 / (1 + tol). Times that differ by less than the
    floor (run-to-run noise on sub-second cells) are no change either way."""
    a, b = two_runs
    cells = sorted((b / "cells").glob("bump-144-poisson-s1-scp-*.json"))
    _edit(b, "bump", 144, 1, "scp", time_total=json.loads(cells[0].read_text())["time_total"] * 0.7 + 0.5)
    _edit(a, "bump", 144, 1, "scp", time_total=json.loads(cells[0].read_text())["time_total"] + 0.5)
    _edit(b, "bump", 400, 0, "scp", time_total=0.362)
    _edit(a, "bump", 400, 0, "scp", time_total=0.467)
    rows_a, rows_b = load_results(a).rows, load_results(b).rows
    forward, backward = compare_rows(rows_a, rows_b), compare_rows(rows_b, rows_a)
    key = ["config", "variant", "seed"]
    mirror = {"regression": "improvement", "improvement": "regression", "unchanged": "unchanged",
              "only in A": "only in B", "only in B": "only in A"}
    merged = forward.merge(backward, on=key, suffixes=("_f", "_b"))
    assert len(merged) == len(forward) == len(backward)
    assert (merged["change_f"].map(mirror) == merged["change_b"]).all()
    noisy = merged[(merged["config"] == "bump · 400 pts · poisson") & (merged["variant"] == "scp")
                   & (merged["seed"] == 0)]
    assert noisy["change_f"].tolist() == ["unchanged"]  # 0.105 s apart: under the floor
