"""The paper's claims (Schmidt & Singh) checked against the run: measured value, met or not, where.

Each claim is a small function of the labelled rows that returns a :class:`Claim`; a claim
whose data the run does not hold says "not measured in this run" and what would measure
it. Tolerances are stated in the claim's text, so the reader can judge them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from .load import parse_json_field
from .tables import MEASURED_STATUSES, Cell, Table, format_number

__all__ = ["Claim", "CLAIMS", "check_claims", "claims_table", "sdp_size_curve", "K_TOL", "DNCP_TOL", "OCP_MARGIN",
           "SDP_GROWTH"]

#: |k_opt - 1| below which "k_opt = 1" holds.
K_TOL = 1e-3
#: Relative QC difference below which optimized DNCP "equals" SCP.
DNCP_TOL = 1e-3
#: Relative QC margin of OCP over the best cotangent SCP on the true mesh.
OCP_MARGIN = 0.01
#: Relative QC growth from the smallest to the largest N that still counts as "stable".
SDP_GROWTH = 0.05
_HOLE_DATASETS = ("holes", "holes-bumped")
_NOT_MEASURED = "not measured in this run"

# Defaults of the parameters the claims select on (the run stores only non-default ones).
_DEFAULTS = {"weights": "cotangent", "normalized": False, "energy": "neumann", "b_orthonormal": True}


@dataclass
class Claim:
    """One claim of the paper and what the run says about it.

    Attributes
    ----------
    claim : str
        The claim, with the paper's section and the tolerance used.
    measured : str
        The measured value(s).
    status : str
        "met", "not met", "partly met" or "not measured in this run".
    where : str
        Surfaces it holds on (and, when not met, where it fails and the reason found).
    """

    claim: str
    measured: str
    status: str
    where: str


def _param(row, key: str):
    return (parse_json_field(row["params"], {}) or {}).get(key, _DEFAULTS.get(key))


def _measured(rows: pd.DataFrame, method: str, **params) -> pd.DataFrame:
    sel = rows[(rows["method"] == method) & rows["status"].isin(MEASURED_STATUSES)]
    for key, value in params.items():
        sel = sel[np.array([_param(r, key) == value for _, r in sel.iterrows()], dtype=bool)]
    return sel


def _surface(row) -> str:
    return str(row["config"])


def _list(items, limit: int = 6) -> str:
    items = list(dict.fromkeys(items))
    return ", ".join(items[:limit]) + (f" and {len(items) - limit} more" if len(items) > limit else "")


def _seed_text(seed) -> str:
    return str(int(seed)) if seed == seed else "?"


def _with_seeds(labels, seeds, details=None) -> list[str]:
    """One entry per label naming its seeds, in first-seen order.

    Without ``details``: ``"bump (seed 0)"``, ``"cap (seeds 0, 1)"``; with a detail per item:
    ``"cap (seed 0: +4.8%; seed 1: +4.6%)"``. A surface may hold on one seed and fail on
    another: naming the seeds keeps the holds and fails lists of one claim from reading as a
    contradiction.
    """
    labels, seeds = list(labels), list(seeds)
    details = [None] * len(labels) if details is None else list(details)
    by: dict[str, list[tuple[str, str | None]]] = {}
    for label, seed, detail in zip(labels, seeds, details):
        by.setdefault(str(label), []).append((_seed_text(seed), detail))
    out = []
    for label, items in by.items():
        if all(d is None for _, d in items):
            names = list(dict.fromkeys(sd for sd, _ in items))
            out.append(f"{label} (seed{'s' if len(names) > 1 else ''} {', '.join(names)})")
        else:
            out.append(f"{label} (" + "; ".join(f"seed {sd}: {d}" for sd, d in items) + ")")
    return out


def _variants(cells: pd.DataFrame) -> dict[str, pd.DataFrame]:
    """The rows of each method variant, keyed by its label as elsewhere in the report, in label order.

    Two variants of one method (``ocp`` and ``ocp [refine=mesh]``) are different maps: a claim
    about the method is measured on each, never on a mix of the two.
    """
    return {str(variant): group for variant, group in cells.groupby("variant", sort=True)}


def _status(n_ok: int, n: int) -> str:
    return "met" if n_ok == n else "not met" if n_ok == 0 else "partly met"


def claim_k_opt(rows: pd.DataFrame) -> Claim:
    text = f"k_opt = 1 for cotangent weights (Sec. 5; |k_opt − 1| ≤ {K_TOL:g})"
    cells = pd.concat([_measured(rows, "dncp-opt", weights="cotangent", normalized=False),
                       _measured(rows, "scp", weights="cotangent", normalized=False)])
    # scp at k = 1 without a search reports k = 1 by construction: not a measurement.
    searched = [(r, float(r["k_opt"])) for _, r in cells.iterrows()
                if r["k_opt"] == r["k_opt"]
                and (parse_json_field(r["diagnostics"], {}) or {}).get("k_search", "line") != "none"]
    if not searched:
        return Claim(text, "—", _NOT_MEASURED, "needs dncp-opt (or scp with a k search) with cotangent weights")
    ks = np.array([k for _, k in searched])
    good = [(r, k) for r, k in searched if abs(k - 1.0) <= K_TOL]
    bad = [(r, k) for r, k in searched if abs(k - 1.0) > K_TOL]
    where = "holds on " + _list(f"{_surface(r)}" for r, _ in good) if good else ""
    if bad:
        where += ("; " if where else "") + "fails on " + _list(f"{_surface(r)} ({r['method']}, k_opt {k:.4g})"
                                                               for r, k in bad)
    return Claim(text, f"k_opt {ks.min():.5g} – {ks.max():.5g} ({len(ks)} maps)", _status(len(good), len(ks)), where)


def claim_dncp_equals_scp(rows: pd.DataFrame) -> Claim:
    text = f"Optimized DNCP equals SCP for any pins (Sec. 5, Fig. 10; QC means within {DNCP_TOL:.1%})"
    dncp = _measured(rows, "dncp-opt", weights="cotangent", normalized=False)
    scp = _measured(rows, "scp", weights="cotangent", normalized=False)
    pairs = dncp.merge(scp, on=["config", "seed"], suffixes=("_d", "_s"))
    if pairs.empty:
        return Claim(text, "—", _NOT_MEASURED, "needs dncp-opt and scp (cotangent) on the same surfaces")
    rel = (pairs["qc_mean_d"] - pairs["qc_mean_s"]).abs() / pairs["qc_mean_s"]
    ok = rel <= DNCP_TOL
    where = ("holds on " + _list(pairs.loc[ok, "config"])) if ok.any() else ""
    if (~ok).any():
        where += ("; " if where else "") + "differs on " + _list(
            f"{c} ({d:.4g} vs {s:.4g})" for c, d, s in
            zip(pairs.loc[~ok, "config"], pairs.loc[~ok, "qc_mean_d"], pairs.loc[~ok, "qc_mean_s"]))
    where += " (one pin pair per surface in this run: 'any pins' is not varied)"
    return Claim(text, f"max relative QC difference {rel.max():.2e}", _status(int(ok.sum()), len(ok)), where)


def _ocp_near_scp_text(variant: str) -> str:
    return (f"OCP on the points is within {OCP_MARGIN:.0%} of cotangent SCP on the true mesh "
            f"(Sec. 4.2; QC mean of {variant} over the lower of scp and scp-igl)")


def claim_ocp_near_scp(rows: pd.DataFrame) -> list[Claim]:
    """OCP's QC against the best cotangent SCP, one claim per ocp variant with the default (Neumann) energy.

    Parameters
    ----------
    rows : pandas.DataFrame
        Labelled rows (see :func:`parambench.reports.labels.add_labels`).

    Returns
    -------
    list of Claim
        One per variant, named by its label (``"ocp"``, ``"ocp [refine=mesh]"``); a single
        "not measured" claim when the run lacks ocp or SCP.
    """
    ocp = _measured(rows, "ocp", energy="neumann")
    ref = pd.concat([_measured(rows, "scp", weights="cotangent", normalized=False), _measured(rows, "scp-igl")])
    if ocp.empty or ref.empty:
        return [Claim(_ocp_near_scp_text("ocp"), "—", _NOT_MEASURED,
                      "needs ocp and scp or scp-igl on the same surfaces")]
    best = ref.groupby(["config", "seed"])["qc_mean"].min().rename("qc_ref").reset_index()
    return [_ocp_near_scp(variant, cells, best) for variant, cells in _variants(ocp).items()]


def _ocp_near_scp(variant: str, ocp: pd.DataFrame, best: pd.DataFrame) -> Claim:
    """The claim for one ocp variant against the best SCP QC per surface and seed (``qc_ref``)."""
    text = _ocp_near_scp_text(variant)
    pairs = ocp.merge(best, on=["config", "seed"]).sort_values(["config", "seed"], kind="stable")
    if pairs.empty:
        return Claim(text, "—", _NOT_MEASURED, f"{variant} and SCP never ran on the same surface")
    ratio = pairs["qc_mean"] / pairs["qc_ref"] - 1.0
    ok = ratio <= OCP_MARGIN
    where = ("holds on " + _list(_with_seeds(pairs.loc[ok, "config"], pairs.loc[ok, "seed"]))) if ok.any() else ""
    if (~ok).any():
        where += ("; " if where else "") + "fails on " + _list(_with_seeds(
            pairs.loc[~ok, "config"], pairs.loc[~ok, "seed"],
            [f"{r:+.1%}{', suspect' if s == 'suspect' else ''}" for r, s in zip(ratio[~ok], pairs.loc[~ok, "status"])]))
    return Claim(text, f"QC excess {ratio.min():+.2%} to {ratio.max():+.2%}", _status(int(ok.sum()), len(ok)), where)


def claim_hybrid(rows: pd.DataFrame) -> Claim:
    text = "Hybrid weights remove the foldovers that negative cotangent weights cause (Sec. 5, Fig. 12)"
    cot = _measured(rows, "scp", weights="cotangent", normalized=False)
    hyb = _measured(rows, "scp", weights="hybrid", normalized=False)
    if hyb.empty:
        hyb = _measured(rows, "dncp-opt", weights="hybrid", normalized=False)
    if cot.empty or hyb.empty:
        return Claim(text, "—", _NOT_MEASURED, "needs scp with weights=hybrid beside weights=cotangent")
    pairs = cot.merge(hyb, on=["config", "seed"], suffixes=("_c", "_h"))
    folding = pairs[pairs["foldovers_c"] > 0]
    if folding.empty:
        return Claim(text, f"cotangent SCP folds on none of {len(pairs)} surfaces", _NOT_MEASURED,
                     "no surface of this run has cotangent foldovers to remove")
    fixed = folding["foldovers_h"] == 0
    where = ("removed on " + _list(folding.loc[fixed, "config"])) if fixed.any() else ""
    if (~fixed).any():
        where += ("; " if where else "") + "remain on " + _list(
            f"{c} ({int(a)} → {int(b)})" for c, a, b in
            zip(folding.loc[~fixed, "config"], folding.loc[~fixed, "foldovers_c"], folding.loc[~fixed, "foldovers_h"]))
    measured = ", ".join(f"{int(a)} → {int(b)}" for a, b in zip(folding["foldovers_c"], folding["foldovers_h"]))
    return Claim(text, f"foldovers cotangent → hybrid: {measured}", _status(int(fixed.sum()), len(fixed)), where)


def sdp_size_curve(rows: pd.DataFrame) -> pd.DataFrame:
    """SDP's QC and foldovers against N on surfaces with holes.

    Parameters
    ----------
    rows : pandas.DataFrame
        Labelled rows.

    Returns
    -------
    pandas.DataFrame
        Columns ``family`` (dataset · sampling), ``variant``, ``n`` (points), ``qc_mean``,
        ``foldover_fraction`` (medians over seeds); only families with at least two sizes.
    """
    sdp = rows[rows["method"].isin(("sdp", "sdp-rl")) & rows["status"].isin(MEASURED_STATUSES)
               & rows["dataset"].isin(_HOLE_DATASETS)].copy()
    columns = ["family", "variant", "n", "qc_mean", "foldover_fraction"]
    if sdp.empty:
        return pd.DataFrame(columns=columns)
    sdp["n"] = sdp["n_points"].where(sdp["n_points"] > 0, sdp["size"])
    sdp["family"] = sdp["dataset"] + " · " + sdp["sampling"]
    med = sdp.groupby(["family", "variant", "n"], as_index=False)[["qc_mean", "foldover_fraction"]].median()
    sizes = med.groupby(["family", "variant"])["n"].transform("nunique")
    return med[sizes >= 2][columns].reset_index(drop=True)


def claim_sdp_with_n(rows: pd.DataFrame) -> Claim:
    text = (f"SDP (LEM with the boundary matrix B) is foldover-free and its QC does not grow with N "
            f"(Sec. 4.1; growth ≤ {SDP_GROWTH:.0%} from the smallest to the largest N, on surfaces with holes)")
    curve = sdp_size_curve(rows)
    curve = curve[curve["variant"] == "sdp"] if (curve["variant"] == "sdp").any() else curve
    if curve.empty:
        return Claim(text, "—", _NOT_MEASURED, "needs sdp at two or more sizes on holes or holes-bumped "
                                              "(e.g. the full or scale suite)")
    measured, good, bad = [], [], []
    for (family, variant), g in curve.groupby(["family", "variant"]):
        g = g.sort_values("n")
        growth = g["qc_mean"].iloc[-1] / g["qc_mean"].iloc[0] - 1.0
        folds = g["foldover_fraction"].fillna(0)
        measured.append(f"{family}: QC " + " → ".join(format_number(q) for q in g["qc_mean"])
                        + f" at N = " + ", ".join(str(int(n)) for n in g["n"]))
        if growth <= SDP_GROWTH and (folds == 0).all():
            good.append(family)
        else:
            reason = []
            if growth > SDP_GROWTH:
                reason.append(f"QC grows {growth:+.0%}")
            if (folds > 0).any():
                reason.append(f"folds {folds.max():.1%} of faces (next to holes) at N = {int(g['n'][folds.idxmax()])}")
            bad.append(f"{family} ({', '.join(reason)})")
    where = ("holds on " + _list(good)) if good else ""
    if bad:
        where += ("; " if where else "") + "fails on " + _list(bad)
    return Claim(text, "; ".join(measured), _status(len(good), len(good) + len(bad)), where)


def claim_spinning(rows: pd.DataFrame) -> Claim:
    text = "Raw SCP on W^tan at k = 1 spins: boundary turning number > 1 (Sec. 4.2, Fig. 8)"
    cells = _measured(rows, "scp-tan")
    turns = [(r, (parse_json_field(r["turning_numbers"], []) or [math.nan])[0]) for _, r in cells.iterrows()]
    turns = [(r, float(t)) for r, t in turns if t is not None and t == t]
    if not turns:
        return Claim(text, "—", _NOT_MEASURED, "needs scp-tan with recorded turning numbers")
    spins = [(r, t) for r, t in turns if abs(t) > 1.25]
    flat = [(r, t) for r, t in turns if abs(t) <= 1.25]
    where = ("spins on " + _list(f"{_surface(r)} (t = {t:g})" for r, t in spins)) if spins else ""
    if flat:
        where += ("; " if where else "") + "does not spin on " + _list(_surface(r) for r, _ in flat)
    values = sorted({round(t, 2) for _, t in turns})
    return Claim(text, "turning numbers " + ", ".join(f"{t:g}" for t in values), _status(len(spins), len(turns)),
                 where)


#: The claims in the order the table lists them.
CLAIMS = (claim_k_opt, claim_dncp_equals_scp, claim_ocp_near_scp, claim_hybrid, claim_sdp_with_n, claim_spinning)


def check_claims(rows: pd.DataFrame) -> list[Claim]:
    """Every claim of :data:`CLAIMS` measured on labelled rows.

    A claim function returns one :class:`Claim`, or a list of them when the claim is measured
    per method variant; the result is flat, in the order of :data:`CLAIMS`.
    """
    out: list[Claim] = []
    for claim in CLAIMS:
        measured = claim(rows)
        out.extend(measured if isinstance(measured, list) else [measured])
    return out


def claims_table(claims: list[Claim]) -> Table:
    """The claims as a table: claim, measured value, met or not, where."""
    body = [[Cell(c.claim), Cell(c.measured), Cell(c.status, ("claim", c.status.replace(" ", "-"))), Cell(c.where)]
            for c in claims]
    return Table(["Claim of the paper", "Measured in this run", "Status", "Surfaces"], body,
                 "The paper's claims against this run", "claims")
