"""The paper's claims table: measured values, met / not met with the reason, 'not measured' without data."""

import json

import pandas as pd

from parambench.reports.claims import (check_claims, claim_dncp_equals_scp, claim_hybrid, claim_k_opt, claim_ocp_near_scp,
                            claim_sdp_with_n, claim_spinning, claims_table, sdp_size_curve)
from parambench.reports.labels import add_labels
from parambench.reports.load import normalise_rows

NOT_MEASURED = "not measured in this run"


def _row(method, dataset="bump", size=100, seed=0, params=None, **metrics):
    base = {"cell_id": f"{dataset}-{size}-{method}-{json.dumps(params)}-{seed}", "dataset": dataset, "size": size,
            "sampling": "grid", "noise": 0.0, "seed": seed, "method": method, "params": json.dumps(params or {}),
            "n_points": size, "status": "ok", "diagnostics": json.dumps({"k_search": "line"})}
    base.update(metrics)
    return base


def _rows(rows):
    return add_labels(normalise_rows(pd.DataFrame(rows)))


def test_every_claim_says_not_measured_without_its_data():
    claims = check_claims(_rows([_row("lem", qc_mean=2.0)]))
    assert len(claims) == 6
    assert all(c.status == NOT_MEASURED for c in claims)
    assert all(c.where for c in claims)  # each says what would measure it
    table = claims_table(claims)
    assert table.columns[:3] == ["Claim of the paper", "Measured in this run", "Status"]
    assert all(row[2].text == NOT_MEASURED for row in table.rows)


def test_k_opt_is_one_for_cotangent_weights_or_not():
    rows = _rows([_row("dncp-opt", k_opt=0.9999, qc_mean=1.01), _row("dncp-opt", "saddle", k_opt=1.2, qc_mean=1.02),
                  _row("dncp-opt", "cap", params={"weights": "uniform"}, k_opt=3.0, qc_mean=1.1),
                  _row("scp", "cap", k_opt=1.0, qc_mean=1.0, diagnostics=json.dumps({"k_search": "none"}))])
    claim = claim_k_opt(rows)
    assert claim.status == "partly met"  # bump holds, saddle does not; uniform weights and unsearched scp ignored
    assert "holds on bump" in claim.where and "saddle" in claim.where and "k_opt 1.2" in claim.where
    assert claim.measured == "k_opt 0.9999 – 1.2 (2 maps)"


def test_dncp_equals_scp_within_the_stated_tolerance():
    rows = _rows([_row("dncp-opt", qc_mean=1.01001), _row("scp", qc_mean=1.01),
                  _row("dncp-opt", "saddle", qc_mean=1.05), _row("scp", "saddle", qc_mean=1.02)])
    claim = claim_dncp_equals_scp(rows)
    assert claim.status == "partly met"
    assert "holds on bump" in claim.where and "differs on saddle" in claim.where and "1.05 vs 1.02" in claim.where


def test_ocp_margin_against_the_best_cotangent_scp():
    rows = _rows([_row("ocp", qc_mean=1.0150), _row("scp", qc_mean=1.0100), _row("scp-igl", qc_mean=1.0101),
                  _row("ocp", params={"energy": "paper"}, qc_mean=1.5)])  # the paper variant is not the claim
    [claim] = claim_ocp_near_scp(rows)
    assert claim.status == "met" and claim.measured == "QC excess +0.50% to +0.50%"
    worse = _rows([_row("ocp", qc_mean=1.05, status="suspect"), _row("scp", qc_mean=1.0)])
    [claim] = claim_ocp_near_scp(worse)
    assert claim.status == "not met" and "+5.0%, suspect" in claim.where


def test_hybrid_removes_cotangent_foldovers_or_says_where_they_remain():
    rows = _rows([_row("scp", foldovers=12, qc_mean=1.1), _row("scp", params={"weights": "hybrid"}, foldovers=0,
                                                               qc_mean=1.11),
                  _row("scp", "saddle", foldovers=3, qc_mean=1.1),
                  _row("scp", "saddle", params={"weights": "hybrid"}, foldovers=1, qc_mean=1.1)])
    claim = claim_hybrid(rows)
    assert claim.status == "partly met" and claim.measured == "foldovers cotangent → hybrid: 12 → 0, 3 → 1"
    assert "removed on bump" in claim.where and "remain on saddle" in claim.where
    none_fold = _rows([_row("scp", foldovers=0), _row("scp", params={"weights": "hybrid"}, foldovers=0)])
    assert claim_hybrid(none_fold).status == NOT_MEASURED


def test_sdp_curve_against_n_on_surfaces_with_holes():
    rows = _rows([_row("sdp", "holes", size=n, qc_mean=q, foldover_fraction=f)
                  for n, q, f in ((1000, 1.10, 0.0), (10000, 1.20, 0.0), (100000, 1.40, 0.038))]
                 + [_row("sdp", "bump", size=1000, qc_mean=1.0), _row("sdp", "bump", size=10000, qc_mean=1.0)])
    curve = sdp_size_curve(rows)
    assert list(curve["n"]) == [1000, 10000, 100000]  # bump is not a surface with holes
    claim = claim_sdp_with_n(rows)
    assert claim.status == "not met"
    assert "QC grows +27%" in claim.where and "folds 3.8% of faces" in claim.where and "N = 100000" in claim.where
    assert claim.measured.startswith("holes · grid: QC 1.1 → 1.2 → 1.4")


def test_spinning_of_raw_scp_on_w_tan():
    rows = _rows([_row("scp-tan", turning_numbers="[9.0]", status="suspect"),
                  _row("scp-tan", "saddle", turning_numbers="[1.0]")])
    claim = claim_spinning(rows)
    assert claim.status == "partly met" and "spins on bump" in claim.where and "(t = 9)" in claim.where
    assert "does not spin on saddle" in claim.where


def test_ocp_margin_is_checked_per_variant_and_names_the_seeds():
    refine = {"refine": "mesh"}
    rows = _rows([_row("scp", seed=0, qc_mean=1.0), _row("scp", seed=1, qc_mean=1.0),
                  _row("ocp", seed=0, qc_mean=1.05), _row("ocp", seed=1, qc_mean=1.005),  # fails on seed 0 only
                  _row("ocp", seed=0, params=refine, qc_mean=1.001), _row("ocp", seed=1, params=refine, qc_mean=1.002)])
    default, refined = claim_ocp_near_scp(rows)
    assert "QC mean of ocp over" in default.claim and "QC mean of ocp [refine=mesh] over" in refined.claim
    assert default.status == "partly met" and default.measured == "QC excess +0.50% to +5.00%"
    surface = "bump · 100 pts · grid"
    assert default.where == f"holds on {surface} (seed 1); fails on {surface} (seed 0: +5.0%)"
    assert refined.status == "met" and refined.measured == "QC excess +0.10% to +0.20%"
    assert refined.where == "holds on bump · 100 pts · grid (seeds 0, 1)"
    assert [c.claim for c in check_claims(rows)].count(default.claim) == 1 and len(check_claims(rows)) == 7
