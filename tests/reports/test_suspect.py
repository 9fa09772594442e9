"""The report shows suspect cells: status text, counts, their own list; their metrics count."""

import pandas as pd

# The terminal summary's mark: the report marks suspect figures alike.
from parambench.bench.sweep import SUSPECT_MARK
from parambench.reports.labels import add_labels
from parambench.reports.load import normalise_rows
from parambench.reports.tables import (failures_table, format_number, overview_table, summarise, summary_tables,
                                      suspect_table)


def _row(method, seed, status="ok", error="", **metrics):
    base = {"cell_id": f"bump-{method}-{seed}", "dataset": "bump", "size": 100, "sampling": "grid",
            "noise": 0.0, "seed": seed, "method": method, "params": "{}", "n_points": 100, "status": status,
            "error_type": "SelfCheck" if status == "suspect" else "", "error": error}
    base.update(metrics)
    return base


def _rows():
    return add_labels(normalise_rows(pd.DataFrame([
        _row("a", 0, qc_mean=1.1, foldovers=0),
        _row("a", 1, status="suspect", error="loop 0 turns +2.00 (expected +1)", qc_mean=1.9, foldovers=3),
        _row("b", 0, qc_mean=1.2, foldovers=0),
        _row("c", 0, status="failed", error="boom"),
    ])))


def test_suspect_seeds_count_in_medians_and_are_named_in_the_status():
    summary = summarise(_rows())
    a = summary[summary["variant"] == "a"].iloc[0]
    assert a["n_ok"] == 1 and a["n_suspect"] == 1 and a["qc_mean"] == 1.5  # median of 1.1 and 1.9
    assert not a["has_failure"] and a["has_suspect"]
    assert a["status"] == "suspect: 1 of 2 seeds fail the self-check: loop 0 turns +2.00 (expected +1)"
    b = summary[summary["variant"] == "b"].iloc[0]
    assert b["status"] == "ok" and not b["has_suspect"]
    cell = next(r[-1] for r in summary_tables(summary)["bump · 100 pts · grid"].rows if r[0].text == "a")
    assert cell.classes == ("status", "suspect")


def test_suspect_cells_are_listed_apart_from_failures():
    rows = _rows()
    suspects = suspect_table(rows)
    assert len(suspects.rows) == 1 and suspects.rows[0][1].text == "1"
    assert suspects.rows[0][2].text.startswith("a on bump") and "turns" in suspects.rows[0][2].text
    failures = failures_table(rows)
    assert len(failures.rows) == 1 and "/ c" in failures.rows[0][2].text and failures.rows[0][0].text == "boom"
    overview = overview_table(summarise(rows))
    a_row = next(r for r in overview.rows if r[0].text == "a")
    assert "failed" not in a_row[1].text  # a suspect seed is not a failure


def test_the_overview_marks_figures_that_include_suspect_cells():
    rows = _rows()
    summary = summarise(rows)
    overview = overview_table(summary)
    cells = {r[0].text: r[1] for r in overview.rows}
    a = summary[summary["variant"] == "a"].iloc[0]
    # a's median includes its suspect seed: marked as the terminal summary marks it, and said why
    assert cells["a"].text == format_number(a["qc_mean"]) + SUSPECT_MARK
    assert "suspect" in cells["a"].classes and "1 of 2 cells suspect" in cells["a"].title
    assert "self-check" in cells["a"].title
    assert cells["b"].text == format_number(1.2) and "suspect" not in cells["b"].classes
    assert f"{SUSPECT_MARK} = includes suspect cells" in overview.caption


def test_a_figure_with_suspect_and_failed_cells_carries_both_marks():
    rows = add_labels(normalise_rows(pd.DataFrame([
        _row("a", 0, status="suspect", error="loop 0 turns +2.00", qc_mean=1.9, foldovers=3),
        _row("a", 1, status="failed", error="boom"), _row("a", 2, qc_mean=1.1, foldovers=0)])))
    cell = overview_table(summarise(rows)).rows[0][1]
    assert cell.text == f"{format_number(1.5)}{SUSPECT_MARK} (1 of 3 failed)"
    assert {"suspect", "partial"} <= set(cell.classes) and "boom" in cell.title
    clean = overview_table(summarise(add_labels(normalise_rows(pd.DataFrame([_row("b", 0, qc_mean=1.2)])))))
    assert SUSPECT_MARK not in clean.rows[0][1].text and SUSPECT_MARK not in clean.caption
