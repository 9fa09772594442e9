"""The verdict: families, acceptable maps, recommended methods and the measured reason of each failure."""

import json

import numpy as np
import pandas as pd
import pytest

from parambench.reports.labels import add_labels
from parambench.reports.load import normalise_rows
from parambench.reports.tables import summarise
from parambench.reports.verdict import (FAMILIES, family_of, family_verdicts, reason_kind, verdict_sentences,
                             verdict_table)


def _row(method, dataset="bump", seed=0, status="ok", sampling="grid", noise=0.0, **metrics):
    base = {"cell_id": f"{dataset}-{sampling}-{noise}-{method}-{seed}", "dataset": dataset, "size": 100,
            "sampling": sampling, "noise": noise, "seed": seed, "method": method, "params": "{}", "n_points": 100,
            "status": status, "error_type": "", "error": "", "turning_numbers": "[1.0]", "diagnostics": "{}"}
    base.update(metrics)
    return base


def _verdicts(rows):
    rows = add_labels(normalise_rows(pd.DataFrame(rows)))
    summary = summarise(rows)
    return family_verdicts(summary, rows)


@pytest.mark.parametrize("dataset, sampling, noise, family", [
    ("bump", "grid", 0.0, "smooth"), ("holes-bumped", "jittered", 0.0, "with holes"), ("slit", "grid", 0.0,
                                                                                          "narrow gaps"),
    ("real/lilium", "", float("nan"), "real"), ("holes", "grid", 0.1, "noisy"), ("bump", "random", 0.0,
                                                                                  "random sampling"),
    ("fold", "graded", 0.0, "graded sampling")])
def test_family_of(dataset, sampling, noise, family):
    assert family_of(dataset, sampling, noise) == family
    assert family in FAMILIES


def test_recommended_acceptable_and_failing_with_measured_reasons():
    rows = []
    for dataset in ("bump", "holes"):
        rows += [
            _row("scp-igl", dataset, qc_mean=1.010, foldovers=0, time_total=1.0),
            _row("ocp", dataset, qc_mean=1.015, foldovers=0, time_total=2.0),  # within 1 %: recommended
            _row("sdp", dataset, qc_mean=1.08, foldovers=0, time_total=0.5),  # within 10 %: acceptable
            _row("lem", dataset, qc_mean=2.0, foldovers=0, time_total=0.5),  # QC far above the bound
            _row("scp-tan", dataset, status="suspect", qc_mean=9.0, foldovers=50, time_total=0.3,
                 turning_numbers="[9.0]", error="loop 0 turns +9.00"),
            _row("sdp-rl", dataset, qc_mean=1.05, foldovers=3, time_total=0.4),
            _row("broken", dataset, status="failed", error_type="SolverError", error="no convergence"),
            _row("scp-rl", dataset, status="suspect", qc_mean=1.02, foldovers=0, time_total=0.4,
                 error="12 boundary candidates off the loops",
                 diagnostics=json.dumps({"selfcheck": {"coverage": {"passed": False, "n_candidates": 40,
                                                                    "n_uncovered": 10}}})),
        ]
    v = _verdicts(rows)
    by = {(r.family, r.variant): r for r in v.itertuples()}
    assert set(v["family"]) == {"smooth", "with holes"}
    assert by[("smooth", "scp-igl")].verdict == "recommended" and by[("smooth", "ocp")].verdict == "recommended"
    assert by[("smooth", "ocp")].time_ratio == pytest.approx(2.0)
    assert by[("smooth", "sdp")].verdict == "acceptable"
    assert by[("smooth", "lem")].verdict == "fails" and by[("smooth", "lem")].reason.startswith("QC +98%")
    assert by[("smooth", "scp-tan")].reason == "spinning: turning number 9"
    assert by[("smooth", "sdp-rl")].reason == "foldovers (3)"
    assert by[("with holes", "sdp-rl")].reason == "foldovers near holes (3)"
    assert by[("smooth", "broken")].reason == "solver failure (SolverError)"
    assert by[("smooth", "scp-rl")].reason == "boundary: recall 75% of candidates"
    assert reason_kind(by[("smooth", "scp-rl")].reason) == "boundary missed"

    table = verdict_table(v)
    assert [row[0].text for row in table.rows] == ["smooth", "with holes"]
    smooth = {table.columns[i]: c.text for i, c in enumerate(table.rows[0])}
    assert smooth["Recommended"] == "scp-igl; ocp (×2 time)"
    assert "sdp (×0.5 time)" in smooth["Acceptable (QC within 10 %)"]
    assert "scp-tan: spinning: turning number 9" in smooth["Not acceptable: measured reason"]

    sentences = verdict_sentences(v)
    assert len(sentences) == 2
    assert sentences[0].startswith("Smooth (1 surface): use scp-igl, ocp")
    assert "spinning (scp-tan)" in sentences[0] and "solver failure (broken)" in sentences[0]
    assert "foldovers near holes (sdp-rl)" in sentences[1]


def test_a_suspect_cell_is_never_acceptable():
    rows = [_row("a", qc_mean=1.0, foldovers=0, time_total=1.0),
            _row("b", qc_mean=1.0, foldovers=0, time_total=1.0, status="suspect", error="3 flipped triangle(s)",
                 diagnostics=json.dumps({"selfcheck": {"failed": ["flipped"]}}))]
    v = _verdicts(rows).set_index("variant")
    assert v.at["a", "verdict"] == "recommended"
    assert v.at["b", "verdict"] == "fails" and v.at["b", "reason"] == "self-check: 3 flipped triangle(s)"


def test_no_acceptable_method_is_said_plainly():
    v = _verdicts([_row("a", qc_mean=1.2, foldovers=2), _row("b", status="failed", error_type="E", error="x")])
    assert (v["verdict"] == "fails").all()
    assert "no method is acceptable" in verdict_sentences(v)[0]
    assert np.isnan(v["time_ratio"]).all()  # no scp-igl in the run: no ratio is made up


def test_each_reason_is_printed_with_the_number_of_surfaces_it_applies_to():
    # lem on three smooth surfaces: it folds on bump and cap and is only far above the QC bound on saddle.
    rows = []
    for dataset, folds in (("bump", 3), ("cap", 3), ("saddle", 0)):
        rows += [_row("scp-igl", dataset, qc_mean=1.01, foldovers=0, time_total=1.0),
                 _row("lem", dataset, qc_mean=2.0, foldovers=folds, time_total=0.5)]
    v = _verdicts(rows).set_index("variant")
    assert v.at["lem", "n_configs"] == 3
    assert v.at["lem", "reason"] == f"foldovers (3) (on 2 of 3); QC {2.0 / 1.01 - 1:+.0%} (on 1 of 3)"
    fails = verdict_table(v.reset_index()).rows[0][4].text
    assert fails == "lem: " + v.at["lem", "reason"]
    assert "foldovers (lem)" in verdict_sentences(v.reset_index())[0]  # the most frequent reason leads


def test_variants_in_the_not_acceptable_column_are_set_apart_from_their_reasons():
    rows = []
    for dataset in ("bump", "cap"):
        rows += [_row("scp-igl", dataset, qc_mean=1.01, foldovers=0, time_total=1.0),
                 _row("lem", dataset, qc_mean=2.0, foldovers=0 if dataset == "bump" else 2, time_total=0.5),
                 _row("sdp", dataset, qc_mean=1.5, foldovers=0, time_total=0.5)]
    fails = verdict_table(_verdicts(rows)).rows[0][4].text
    qc_lem, qc_sdp = f"QC {2.0 / 1.01 - 1:+.0%}", f"QC {1.5 / 1.01 - 1:+.0%}"
    assert sorted(fails.split(" | ")) == [f"lem: {qc_lem} (on 1 of 2); foldovers (2) (on 1 of 2)",
                                          f"sdp: {qc_sdp} (on 2 of 2)"]
