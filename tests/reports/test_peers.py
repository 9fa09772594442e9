"""ocp against fbcp-pc: per-surface verdicts, ties, failed and suspect cells, the goal's claim line."""

import json

import pandas as pd

from parambench.reports.labels import add_labels
from parambench.reports.load import normalise_rows
from parambench.reports.peers import PEER_TIE, claim_ocp_vs_fbcp, ocp_vs_fbcp, ocp_vs_fbcp_table


def _row(method, dataset="bump", params=None, status="ok", **metrics):
    base = {"cell_id": f"{dataset}-{method}-{json.dumps(params)}", "dataset": dataset, "size": 2000,
            "sampling": "jittered", "noise": 0.0, "seed": 0, "method": method, "params": json.dumps(params or {}),
            "n_points": 2000, "status": status, "diagnostics": "{}"}
    base.update(metrics)
    return base


def _rows(rows):
    return add_labels(normalise_rows(pd.DataFrame(rows)))


GIVEN = {"boundary": "given"}


def test_each_pair_says_whether_ocp_is_at_or_below_and_why_not():
    rows = _rows([
        _row("ocp", mu_mean=0.020, foldovers=0), _row("fbcp-pc", mu_mean=0.021, foldovers=0),
        _row("fbcp-pc", params=GIVEN, mu_mean=0.019, foldovers=0),  # ocp 5 % above the true-boundary peer
        _row("ocp", "cap", mu_mean=0.010, foldovers=2), _row("fbcp-pc", "cap", mu_mean=0.012, foldovers=0),
    ])
    pairs = ocp_vs_fbcp(rows)
    bump = ocp_vs_fbcp(rows)
    bump = bump[bump["config"].str.startswith("bump")].set_index("peer")
    assert bump.loc["detected", "holds"] == True  # noqa: E712 (numpy bool)
    assert bump.loc["given", "holds"] == False  # noqa: E712
    assert bump.loc["given", "reason"] == "|mu| +5.3%"
    cap = ocp_vs_fbcp(rows)
    cap = cap[cap["config"].str.startswith("cap")].iloc[0]
    assert cap["holds"] == False and cap["reason"] == "foldovers 2 vs 0"  # noqa: E712
    assert len(pairs) == 3  # cap has no true-boundary fbcp-pc cell: no pair


def test_a_tie_within_the_stated_margin_counts_as_at_or_below():
    inside = 0.02 * (1 + 0.9 * PEER_TIE)
    outside = 0.02 * (1 + 1.1 * PEER_TIE)
    rows = _rows([_row("ocp", mu_mean=inside, foldovers=0), _row("fbcp-pc", mu_mean=0.02, foldovers=0),
                  _row("ocp", "cap", mu_mean=outside, foldovers=0), _row("fbcp-pc", "cap", mu_mean=0.02, foldovers=0)])
    holds = ocp_vs_fbcp(rows).set_index("config")["holds"]
    assert [bool(holds[c]) for c in sorted(holds.index)] == [True, False]  # bump inside the tie, cap outside


def test_failed_cells_lose_the_pair_and_suspect_ones_count_but_are_marked():
    rows = _rows([_row("ocp", status="failed"), _row("fbcp-pc", mu_mean=0.03, foldovers=0),
                  _row("ocp", "cap", mu_mean=0.01, foldovers=0), _row("fbcp-pc", "cap", status="failed"),
                  _row("ocp", "saddle", status="failed"), _row("fbcp-pc", "saddle", status="failed"),
                  _row("ocp", "plane", status="suspect", mu_mean=0.01, foldovers=0),
                  _row("fbcp-pc", "plane", mu_mean=0.02, foldovers=0)])
    pairs = ocp_vs_fbcp(rows)
    by = {c.split(" ")[0]: r for c, r in zip(pairs["config"], pairs.to_dict("records"))}
    assert by["bump"]["holds"] is False and by["bump"]["reason"] == "ocp failed"
    assert by["cap"]["holds"] is True and by["cap"]["reason"] == "fbcp-pc failed"
    assert by["saddle"]["holds"] is None
    assert by["plane"]["holds"] is True
    table = ocp_vs_fbcp_table(rows)
    texts = [[c.text for c in row] for row in table.rows]
    column = {name: i for i, name in enumerate(table.columns)}
    plane = next(t for t in texts if t[column["Surface"]].startswith("plane"))
    assert plane[column["ocp: mean |mu| / foldovers"]] == "0.01 / 0 (suspect)"
    assert plane[column["ocp at or below"]] == "yes"
    saddle = next(t for t in texts if t[column["Surface"]].startswith("saddle"))
    assert saddle[column["ocp at or below"]] == "—"


def test_the_claim_line_counts_pairs_and_names_where_the_goal_fails():
    rows = _rows([_row("ocp", mu_mean=0.020, foldovers=0), _row("fbcp-pc", mu_mean=0.040, foldovers=0),
                  _row("ocp", "cap", mu_mean=0.030, foldovers=0), _row("fbcp-pc", "cap", mu_mean=0.020, foldovers=0)])
    [claim] = claim_ocp_vs_fbcp(rows)
    assert claim.status == "partly met"
    assert claim.measured.startswith("ocp at or below on 1 of 2 pairs")
    assert "0.5 – 1.5" in claim.measured
    assert "holds on bump" in claim.where and "fails on cap" in claim.where and "|mu| +50.0%" in claim.where
    [alone] = claim_ocp_vs_fbcp(_rows([_row("ocp", mu_mean=0.02, foldovers=0)]))
    assert alone.status == "not measured in this run"
    assert ocp_vs_fbcp_table(_rows([_row("ocp", mu_mean=0.02, foldovers=0)])) is None


def test_two_exact_maps_tie_at_rounding_level():
    rows = _rows([_row("ocp", "plane", mu_mean=1.2e-8, foldovers=0), _row("fbcp-pc", "plane", mu_mean=6e-14, foldovers=0),
                  _row("ocp", mu_mean=0.02, foldovers=0), _row("fbcp-pc", mu_mean=0.01, foldovers=0)])
    pairs = ocp_vs_fbcp(rows).set_index("config")["holds"]
    assert [bool(pairs[c]) for c in sorted(pairs.index)] == [False, True]  # bump loses, plane ties
    [claim] = claim_ocp_vs_fbcp(rows)
    assert "median 2" in claim.measured  # the plane's 2e5 ratio of rounding errors is left out


REFINE = {"refine": "mesh"}


def _seeded(method, seed, params=None, **metrics):
    row = _row(method, params=params, seed=seed, **metrics)
    row["cell_id"] += f"-s{seed}"
    return row


def test_each_ocp_variant_is_compared_on_its_own():
    # The quick suite runs ocp and ocp [refine=mesh] on every surface and seed: both use the default
    # energy. The default is 50 % above fbcp-pc on both seeds, refine=mesh 5 % below.
    rows = _rows([cell for seed in (0, 1) for cell in (
        _seeded("ocp", seed, mu_mean=0.030, foldovers=0), _seeded("ocp", seed, REFINE, mu_mean=0.019, foldovers=0),
        _seeded("fbcp-pc", seed, mu_mean=0.020, foldovers=0))])
    pairs = ocp_vs_fbcp(rows)
    assert sorted(pairs["variant"]) == ["ocp", "ocp", "ocp [refine=mesh]", "ocp [refine=mesh]"]
    by_variant = pairs.groupby("variant")
    assert by_variant["mu_ocp"].unique().map(list).to_dict() == {"ocp": [0.030], "ocp [refine=mesh]": [0.019]}
    assert by_variant["holds"].sum().to_dict() == {"ocp": 0, "ocp [refine=mesh]": 2}

    default, refined = claim_ocp_vs_fbcp(rows)
    assert default.claim.startswith("Goal of this suite: ocp at or below") and default.status == "not met"
    assert default.measured.startswith("ocp at or below on 0 of 2 pairs")
    assert refined.claim.startswith("Goal of this suite: ocp [refine=mesh] at or below") and refined.status == "met"
    assert refined.measured.startswith("ocp [refine=mesh] at or below on 2 of 2 pairs")
    assert "(seed 0: |mu| +50.0%; seed 1: |mu| +50.0%)" in default.where and "holds" not in default.where
    assert "(seeds 0, 1)" in refined.where and "fails" not in refined.where

    table = ocp_vs_fbcp_table(rows)
    column = {name: i for i, name in enumerate(table.columns)}
    shown = {(r[column["ocp variant"]].text, r[column["Seed"]].text): r[column["ocp: mean |mu| / foldovers"]].text
             for r in table.rows}
    assert shown == {("ocp", "0"): "0.03 / 0", ("ocp", "1"): "0.03 / 0", ("ocp [refine=mesh]", "0"): "0.019 / 0",
                     ("ocp [refine=mesh]", "1"): "0.019 / 0"}


def test_two_fbcp_pc_variants_on_one_boundary_are_named_apart():
    rows = _rows([_row("ocp", mu_mean=0.020, foldovers=0), _row("fbcp-pc", params={"k": 8}, mu_mean=0.030, foldovers=0),
                  _row("fbcp-pc", params={"k": 16}, mu_mean=0.010, foldovers=0)])
    pairs = ocp_vs_fbcp(rows).set_index("peer_name")["holds"]
    assert pairs.to_dict() == {"fbcp-pc (detected boundary): fbcp-pc [k=8]": True,
                               "fbcp-pc (detected boundary): fbcp-pc [k=16]": False}
