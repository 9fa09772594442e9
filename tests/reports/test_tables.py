"""Summary tables: medians over seeds, best-value marks, failures kept with their text."""

import numpy as np
import pandas as pd
import pytest

from parambench.reports.labels import add_labels
from parambench.reports.load import normalise_rows
from parambench.reports.tables import (ACCEPTABLE_RULE, SUMMARY_METRICS, acceptable_mask, benchmark_table, best_mask,
                            exponent_table, failures_table, format_number, metadata_table, overview_table,
                            stage_memory_table, summarise,
                            summary_tables)


def _row(method, seed, dataset="bump", status="ok", **metrics):
    base = {"cell_id": f"{dataset}-{method}-{seed}", "dataset": dataset, "size": 100, "sampling": "grid",
            "noise": 0.0, "seed": seed, "method": method, "params": "{}", "n_points": 100, "status": status,
            "error_type": "", "error": ""}
    base.update(metrics)
    return base


@pytest.fixture
def hand_rows():
    rows = [
        _row("a", 0, qc_mean=1.10, qc_p95=1.3, qc_max=2.0, foldovers=0, area_distortion=1.2, time_total=1.0),
        _row("a", 1, qc_mean=1.20, qc_p95=1.5, qc_max=4.0, foldovers=2, area_distortion=1.4, time_total=3.0),
        _row("a", 2, status="failed", error_type="SolverError", error="eigensolver did not converge"),
        _row("b", 0, qc_mean=1.05, qc_p95=1.4, qc_max=3.0, foldovers=0, area_distortion=1.1, time_total=0.5),
        _row("d", 0, qc_mean=1.12, qc_p95=1.2, qc_max=2.5, foldovers=0, area_distortion=1.3, time_total=0.2),
        _row("e", 0, qc_mean=3.94, qc_p95=4.0, qc_max=5.0, foldovers=0, area_distortion=1e-12, time_total=0.1),
        _row("c", 0, status="failed", error_type="NotADiskError", error="mesh has 2 components"),
        _row("a", 0, dataset="disk", qc_mean=1.0, qc_p95=1.0, qc_max=1.0, foldovers=0, time_total=0.1,
             exact_error=0.002),
    ]
    return add_labels(normalise_rows(pd.DataFrame(rows)))


def test_summarise_takes_medians_over_ok_seeds_and_keeps_failures(hand_rows):
    summary = summarise(hand_rows)
    assert len(summary) == 6  # bump: a, b, c, d, e; disk: a
    a = summary[(summary["dataset"] == "bump") & (summary["variant"] == "a")].iloc[0]
    assert a["n_cells"] == 3 and a["n_ok"] == 2
    assert a["qc_mean"] == pytest.approx(1.15)
    assert a["qc_max"] == pytest.approx(3.0)
    assert a["foldovers"] == pytest.approx(1.0)
    assert a["time_total"] == pytest.approx(2.0)
    assert a["has_failure"]
    assert a["status"] == "1 of 3 seeds failed: SolverError: eigensolver did not converge"
    c = summary[summary["variant"] == "c"].iloc[0]
    assert c["n_ok"] == 0 and np.isnan(c["qc_mean"])
    assert c["status"] == "failed: NotADiskError: mesh has 2 components"
    b = summary[summary["variant"] == "b"].iloc[0]
    assert b["status"] == "ok" and not b["has_failure"]


def test_best_mask_marks_minimum_among_acceptable_maps_only(hand_rows):
    summary = summarise(hand_rows)
    mask = best_mask(summary)
    bump = summary["dataset"] == "bump"
    by_variant = {v: i for v, i in zip(summary.loc[bump, "variant"], summary.index[bump])}
    # a has the lowest QC max among all, but a failed seed and foldovers: not acceptable, never shaded
    assert not mask.loc[by_variant["a"]].any()
    # e (QC 3.94, an affine stretch) has the lowest area distortion and time, but QC is far above the
    # 10 % bound: not shaded; among b and d (QC 1.12 <= 1.1 * 1.05, acceptable) the lower values are
    assert not mask.loc[by_variant["e"]].any()
    assert mask.at[by_variant["b"], "area_distortion"] and mask.at[by_variant["d"], "time_total"]
    assert mask.at[by_variant["b"], "qc_mean"] and not mask.at[by_variant["d"], "qc_mean"]
    assert mask.at[by_variant["d"], "qc_p95"] and not mask.at[by_variant["b"], "qc_p95"]
    assert not mask.loc[by_variant["c"]].any()  # failed: nothing to mark
    disk = summary.index[summary["dataset"] == "disk"][0]
    assert not mask.loc[disk].any()  # one method alone is not "best"
    assert not mask.loc[bump, "exact_error"].any()  # no value in the bump table


def test_acceptable_mask_states_the_rule(hand_rows):
    summary = summarise(hand_rows)
    accepted = dict(zip(summary["variant"] + "/" + summary["dataset"], acceptable_mask(summary)))
    assert accepted == {"a/bump": False, "b/bump": True, "c/bump": False, "d/bump": True, "e/bump": False,
                        "a/disk": True}
    assert "10 %" in ACCEPTABLE_RULE and "foldovers" in ACCEPTABLE_RULE


def test_summary_tables_render_rows_best_cells_and_error_text(hand_rows):
    tables = summary_tables(summarise(hand_rows))
    assert list(tables) == ["bump · 100 pts · grid", "disk · 100 pts · grid"]
    bump = tables["bump · 100 pts · grid"]
    assert len(bump.rows) == 5
    assert len(bump.columns) == 3 + len(SUMMARY_METRICS)
    texts = {row[0].text: row for row in bump.rows}
    qc_col = bump.columns.index("QC mean")
    assert texts["b"][qc_col].text == "1.05" and "best" in texts["b"][qc_col].classes
    assert "best" not in texts["a"][qc_col].classes
    assert len(bump.rows) == len(bump.row_keys) and bump.row_keys[0]["config"] == "bump · 100 pts · grid"
    assert texts["c"][qc_col].text == "—"
    assert "NotADiskError: mesh has 2 components" in texts["c"][-1].text
    assert "failed" in texts["c"][-1].classes
    assert texts["a"][1].text == "2/3"


def test_failures_table_lists_each_message_once_with_its_cells(hand_rows):
    table = failures_table(hand_rows)
    assert len(table.rows) == 2
    errors = sorted(row[0].text for row in table.rows)
    assert errors == ["NotADiskError: mesh has 2 components", "SolverError: eigensolver did not converge"]
    extra = hand_rows.iloc[[0]].assign(cell_id="x", seed=5.0, status="failed", error_type="SolverError",
                                       error="eigensolver did not converge")
    grouped = failures_table(pd.concat([hand_rows, extra], ignore_index=True))
    solver = next(r for r in grouped.rows if r[0].text.startswith("SolverError"))
    assert solver[1].text == "2" and "seed 2" in solver[2].text and "seed 5" in solver[2].text
    assert len(grouped.rows) == 2  # one row per distinct message, not per cell


def test_overview_is_method_by_dataset_with_failures_counted(hand_rows):
    table = overview_table(summarise(hand_rows))
    assert table.columns == ["Method", "bump", "disk"]
    cells = {row[0].text: row[1:] for row in table.rows}
    assert [c.text for c in cells["a"]] == ["1.15 (1 of 3 failed)", "1"]
    assert [c.text for c in cells["c"]] == ["failed", "·"]
    assert "NotADiskError" in cells["c"][0].title
    assert [c.text for c in cells["b"]] == ["1.05", "·"]
    assert "best" in cells["b"][0].classes and "best" not in cells["a"][0].classes
    assert [c.text for c in cells["e"]] == ["3.94", "·"] and "best" not in cells["e"][0].classes
    assert "best" not in cells["a"][1].classes  # alone on disk


def test_overview_takes_the_median_over_configurations():
    rows = [_row("a", 0, qc_mean=q) | {"size": size, "cell_id": f"a{size}"} for q, size in
            ((1.1, 100), (1.3, 200), (1.2, 400))]
    table = overview_table(summarise(add_labels(normalise_rows(pd.DataFrame(rows)))))
    assert [c.text for c in table.rows[0]] == ["a", "1.2"]


def test_long_error_is_shortened_in_the_summary_but_not_in_the_failures_table():
    long_error = "x" * 1000
    rows = add_labels(normalise_rows(pd.DataFrame([_row("a", 0, status="failed", error_type="E",
                                                        error=long_error)])))
    status = summary_tables(summarise(rows))["bump · 100 pts · grid"].rows[0][-1].text
    assert len(status) < 400 and status.endswith("…")
    assert failures_table(rows).rows[0][0].text == "E: " + long_error


def test_format_number():
    assert format_number(None) == "—"
    assert format_number(float("nan")) == "—"
    assert format_number(1.234567) == "1.235"
    assert format_number(3.0, "count") == "3"
    assert format_number(2.5, "count") == "2.5"
    assert format_number(0.000123456, "small") == "0.000123"
    assert format_number(12.3456, "time") == "12.3"


def test_metadata_table_shows_every_recorded_item():
    run = {"package_version": "0.1.0", "git_commit": "abc123", "date": "2024-01-01", "command": "parambench run",
           "suite": "quick", "machine": {"hostname": "h", "cpu_count": 2}, "parameters": {"sizes": [1, 2]},
           "seeds": [0, 1, 2], "extra_field": "kept"}
    table = metadata_table(run)
    values = {row[0].text: row[1].text for row in table.rows}
    assert values["Git commit"] == "abc123"
    assert values["Seeds"] == "0, 1, 2"
    assert values["Machine"] == "hostname: h, cpu_count: 2"
    assert values["Parameters"] == "sizes=1, 2"  # one line, not one token per line
    assert values["Extra field"] == "kept"
    assert {row[0].text: row[1].text for row in metadata_table({}).rows}["Git commit"] == "—"


def test_benchmark_and_exponent_tables():
    stats = pd.DataFrame([{"source": "b.json", "group": "g", "name": "t1", "min": 0.1, "max": 0.3, "mean": 0.2,
                           "stddev": 0.05, "median": 0.19, "rounds": 5.0, "extra": "{}"}])
    table = benchmark_table(stats)
    assert [c.text for c in table.rows[0]][:4] == ["g", "t1", "0.1", "0.19"]
    fits = pd.DataFrame([{"dataset": "bump", "sampling": "grid", "noise": 0.0, "variant": "a", "exponent": 1.234,
                          "coefficient": 1e-6, "n_sizes": 3, "n_min": 100.0, "n_max": 10000.0}])
    row = [c.text for c in exponent_table(fits).rows[0]]
    assert row == ["bump · grid", "a", "1.23", "3", "100–10000"]


def test_values_that_print_alike_are_both_best():
    rows = [_row("a", 0, qc_mean=1.061041, foldovers=0), _row("b", 0, qc_mean=1.060962, foldovers=0),
            _row("c", 0, qc_mean=1.0625, foldovers=0)]
    summary = summarise(add_labels(normalise_rows(pd.DataFrame(rows))))
    marked = summary.loc[best_mask(summary)["qc_mean"], "variant"]
    assert list(marked) == ["a", "b"]  # both print as 1.061


def test_stage_memory_table_shows_the_largest_size_per_method():
    rows = [_row("a", 0, size=100, n_points=100, stage_memory_mb='{"knn": 50.0, "solve": 80.0}'),
            _row("a", 0, size=1000, n_points=1000, stage_memory_mb='{"knn": 60.0, "other": 40.0, "solve": 120.4}'),
            _row("b", 0, size=1000, n_points=1000, stage_memory_mb='{"topology": 70.0, "solve": 90.0}'),
            _row("c", 0, size=1000, n_points=1000, status="failed", error="x")]
    rows[1]["cell_id"] += "-big"
    rows[2]["cell_id"] += "-big"
    table = stage_memory_table(add_labels(normalise_rows(pd.DataFrame(rows))))
    assert table.columns == ["Surface", "Method", "Points", "knn", "topology", "solve", "other", "Peak"]
    body = [[c.text for c in r] for r in table.rows]
    assert body == [["bump · grid", "a", "1000", "60", "—", "120", "40", "120"],
                    ["bump · grid", "b", "1000", "—", "70", "90", "—", "90"]]


def test_stage_memory_table_is_none_without_records(hand_rows):
    assert stage_memory_table(hand_rows) is None
