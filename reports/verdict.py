"""The verdict: per surface family, which methods to use, which fail and why, at what cost.

Everything here is computed from the summary rows of the run (never from a fixed list of
expected winners), so a report of another run states that run's findings.

Rules (written under the tables, see :data:`ACCEPTABLE_RULE`):

* A variant's map on a configuration is *acceptable* when every seed was measured without
  a self-check failure (status ok, not suspect or failed), the median foldover count is 0
  and its median QC mean is within :data:`QC_BOUND` (10 %) of the lowest QC mean among the
  variants that pass the first two conditions on that configuration.
* A variant is *recommended* on a family when it is acceptable on every configuration of the
  family it ran on and within 1 % of that configuration's best QC.
* The reason a variant fails is the first that applies, in this order: the solver failed
  (error type), the self-check found spinning (boundary turning number off +-1), the boundary
  was missed (candidates off the loops), foldovers (near holes when the surface has holes),
  other self-check failures, QC above the bound.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from .load import parse_json_field
from .tables import ACCEPTABLE_RULE, QC_BOUND, Cell, Table, acceptable_mask, format_number

__all__ = ["FAMILIES", "QC_BOUND", "NEAR_BEST", "ACCEPTABLE_RULE", "family_of", "acceptable_mask",
           "failure_reason", "reason_kind", "family_verdicts", "verdict_table", "verdict_sentences", "REFERENCE_METHOD"]

#: Surface families in the order the verdict lists them.
FAMILIES = ("smooth", "with holes", "narrow gaps", "real", "noisy", "random sampling", "graded sampling")
#: "Within 1 % of the best QC".
NEAR_BEST = 1.01
#: The time baseline.
REFERENCE_METHOD = "scp-igl"
_HOLE_DATASETS = ("holes", "holes-bumped")
_GAP_DATASETS = ("slit", "fold")
#: Kinds of failure reason, by the start of the reason text (see :func:`failure_reason`).
_KINDS = (("solver failure", "solver failure"), ("spinning", "spinning"), ("boundary", "boundary missed"),
          ("foldovers near holes", "foldovers near holes"), ("foldovers", "foldovers"),
          ("self-check", "other self-check failure"), ("QC", f"QC over the {round((QC_BOUND - 1) * 100)} % bound"))


def reason_kind(reason: str) -> str:
    """The kind of a failure reason, e.g. ``"spinning"`` for ``"spinning: turning number 9"``."""
    return next((kind for prefix, kind in _KINDS if reason.startswith(prefix)), reason)


def family_of(dataset: str, sampling: str, noise: float) -> str:
    """The surface family of a configuration.

    Noise comes first, then the sampling (random, graded), then the surface itself: a
    configuration belongs to exactly one family, the one that explains it best.

    Parameters
    ----------
    dataset, sampling : str
    noise : float
        NaN counts as 0.

    Returns
    -------
    str
        One of :data:`FAMILIES`.
    """
    if noise == noise and noise and not math.isclose(noise, 0.0):
        return "noisy"
    if sampling == "random":
        return "random sampling"
    if sampling == "graded":
        return "graded sampling"
    if str(dataset).startswith("real/"):
        return "real"
    if dataset in _HOLE_DATASETS:
        return "with holes"
    if dataset in _GAP_DATASETS:
        return "narrow gaps"
    return "smooth"


def _rows_of(rows: pd.DataFrame, record) -> pd.DataFrame:
    return rows[(rows["config"] == record["config"]) & (rows["variant"] == record["variant"])]


def _turning(row) -> list:
    values = parse_json_field(row["turning_numbers"], []) or []
    return [float(v) for v in values if isinstance(v, (int, float))]


def failure_reason(cells: pd.DataFrame, dataset: str, qc_mean: float, best_qc: float) -> str:
    """Why a variant's map on one configuration is not acceptable, measured.

    Parameters
    ----------
    cells : pandas.DataFrame
        The variant's rows (seeds) on the configuration.
    dataset : str
    qc_mean, best_qc : float
        The variant's median QC mean and the best acceptable QC of the configuration.

    Returns
    -------
    str
        A short phrase, e.g. ``"spinning: turning numbers 9"``.
    """
    failed = cells[~cells["status"].isin(("ok", "suspect"))]
    if len(failed):
        kinds = ", ".join(dict.fromkeys(t or "error" for t in failed["error_type"]))
        return f"solver failure ({kinds})"
    turns = [t for _, r in cells.iterrows() for t in _turning(r)[:1]]
    spinning = [t for t in turns if abs(abs(t) - 1.0) > 0.25]
    if spinning:
        return "spinning: turning number " + ", ".join(f"{t:g}" for t in dict.fromkeys(round(t, 2) for t in spinning))
    checks = [(parse_json_field(d, {}) or {}).get("selfcheck") or {} for d in cells["diagnostics"]]
    for check in checks:
        cov = check.get("coverage") or {}
        if cov and not cov.get("passed", True):
            n_c = cov.get("n_candidates") or 0
            recall = 1.0 - (cov.get("n_uncovered", 0) / n_c if n_c else 0.0)
            return f"boundary: recall {recall:.0%} of candidates"
    folds = cells["foldovers"].fillna(0)
    if (folds > 0).any():
        n = int(folds.median()) if folds.median() > 0 else int(folds.max())
        where = " near holes" if dataset in _HOLE_DATASETS else ""
        return f"foldovers{where} ({n})"
    suspect = cells[cells["status"] == "suspect"]
    if len(suspect):
        text = str(suspect["error"].iloc[0] or "self-check failed")
        return "self-check: " + (text if len(text) <= 60 else text[:59] + "…")
    if qc_mean == qc_mean and best_qc == best_qc and best_qc > 0:
        return f"QC {qc_mean / best_qc - 1:+.0%}"
    return "no measurement"


def family_verdicts(summary: pd.DataFrame, rows: pd.DataFrame) -> pd.DataFrame:
    """One record per (family, variant): recommended, acceptable, or failing with a reason.

    Parameters
    ----------
    summary : pandas.DataFrame
        Output of :func:`parambench.reports.tables.summarise`.
    rows : pandas.DataFrame
        The labelled rows it was computed from (for turning numbers and self-checks).

    Returns
    -------
    pandas.DataFrame
        Columns ``family``, ``variant``, ``n_configs``, ``n_acceptable``, ``n_near_best``,
        ``verdict`` ("recommended", "acceptable", "fails"), ``reason`` (each kind of failure
        reason with the number of configurations it applies to, most frequent first, see
        :func:`_reasons_text`; "" when none), ``time_ratio`` (median over configurations of the
        time over :data:`REFERENCE_METHOD`'s, NaN without a reference) and ``qc_mean``
        (median over the family's configurations).
    """
    s = summary.copy()
    s["family"] = [family_of(d, m, n) for d, m, n in zip(s["dataset"], s["sampling"], s["noise"])]
    s["acceptable"] = acceptable_mask(s)
    best = s["qc_mean"].where(s["acceptable"]).groupby(s["config"]).transform("min")
    s["near_best"] = s["acceptable"] & (s["qc_mean"] <= NEAR_BEST * best)
    ref = s[s["variant"] == REFERENCE_METHOD].set_index("config")["time_total"]
    s["time_ratio"] = s["time_total"] / s["config"].map(ref)
    s["reason"] = ""
    for idx, rec in s[~s["acceptable"]].iterrows():
        s.at[idx, "reason"] = failure_reason(_rows_of(rows, rec), rec["dataset"], rec["qc_mean"], best[idx])
    out = []
    for (family, variant), group in s.groupby(["family", "variant"], sort=False):
        n, n_acc, n_near = len(group), int(group["acceptable"].sum()), int(group["near_best"].sum())
        verdict = "recommended" if n_near == n else "acceptable" if n_acc == n else "fails"
        reason = _reasons_text([r for r in group["reason"] if r], n)
        ratios = group["time_ratio"].dropna()
        out.append({"family": family, "variant": variant, "n_configs": n, "n_acceptable": n_acc,
                    "n_near_best": n_near, "verdict": verdict, "reason": reason,
                    "time_ratio": float(ratios.median()) if len(ratios) else np.nan,
                    "qc_mean": float(group["qc_mean"].median()) if group["qc_mean"].notna().any() else np.nan})
    frame = pd.DataFrame(out, columns=["family", "variant", "n_configs", "n_acceptable", "n_near_best", "verdict",
                                       "reason", "time_ratio", "qc_mean"])
    order = {f: i for i, f in enumerate(FAMILIES)}
    frame["_order"] = frame["family"].map(order)
    return frame.sort_values(["_order", "qc_mean", "variant"], kind="stable").drop(columns="_order") \
        .reset_index(drop=True)


def _reasons_text(reasons: list[str], n: int) -> str:
    """Each kind of failure reason once, most frequent first, with the surfaces it applies to.

    ``"foldovers (3) (on 2 of 6); QC +101% (on 2 of 6)"``: each count belongs to the reason
    printed beside it (a count of every failing surface beside one reason overstated it). A
    kind is shown by its first reason; "(on k of n)" is left out when the family has one surface.
    """
    if not reasons:
        return ""
    kinds = pd.Series([reason_kind(r) for r in reasons], dtype=object)
    counts = kinds.value_counts(sort=False)  # first-seen order breaks ties between equally frequent kinds
    order = sorted(counts.index, key=lambda kind: -counts[kind])
    parts = []
    for kind in order:
        text = next(r for r, k in zip(reasons, kinds) if k == kind)
        parts.append(text + (f" (on {counts[kind]} of {n})" if n > 1 else ""))
    return "; ".join(parts)


def _with_time(record) -> str:
    ratio = record["time_ratio"]
    if ratio != ratio or record["variant"] == REFERENCE_METHOD:
        return str(record["variant"])
    return f"{record['variant']} (×{ratio:.2g} time)"


def verdict_table(verdicts: pd.DataFrame) -> Table:
    """The compact verdict table: one row per family.

    Columns: recommended variants (within 1 % of the best QC, acceptable everywhere), other
    acceptable variants, and failing variants with their measured reason. Time ratios to
    :data:`REFERENCE_METHOD` are given in brackets.
    """
    body = []
    for family in [f for f in FAMILIES if f in set(verdicts["family"])]:
        group = verdicts[verdicts["family"] == family]
        n_configs = int(group["n_configs"].max())
        rec = "; ".join(_with_time(r) for _, r in group[group["verdict"] == "recommended"].iterrows())
        acc = "; ".join(_with_time(r) for _, r in group[group["verdict"] == "acceptable"].iterrows())
        # A variant's reasons are joined by "; ": variants are set apart by " | ".
        fails = " | ".join(f"{r['variant']}: {r['reason']}" for _, r in group[group["verdict"] == "fails"].iterrows())
        body.append([Cell(family, ("key",)), Cell(str(n_configs)), Cell(rec or "—", ("recommended",)),
                     Cell(acc or "—"), Cell(fails or "—", ("fails",))])
    caption = (f"Verdict per surface family: recommended = acceptable on every surface of the family and within "
               f"{round((NEAR_BEST - 1) * 100)} % of its best QC; (×r time) = median time over {REFERENCE_METHOD}'s; "
               f"QC +x % = QC mean above the surface's best acceptable one; (on k of n) = surfaces of the family on "
               f"which the reason beside it applies")
    columns = ["Family", "Surfaces", "Recommended", f"Acceptable (QC within {round((QC_BOUND - 1) * 100)} %)",
               "Not acceptable: measured reason"]
    return Table(columns, body, caption, "verdict", numeric={1})


def verdict_sentences(verdicts: pd.DataFrame) -> list[str]:
    """One or two plain sentences per family, from the same data as :func:`verdict_table`."""
    out = []
    for family in [f for f in FAMILIES if f in set(verdicts["family"])]:
        group = verdicts[verdicts["family"] == family]
        rec = group[group["verdict"] == "recommended"]
        fails = group[group["verdict"] == "fails"]
        n = int(group["n_configs"].max())
        where = f"{n} surface{'s' if n != 1 else ''}"
        if len(rec):
            best = rec.iloc[0]
            text = (f"{family.capitalize()} ({where}): use {', '.join(rec['variant'])} — within 1 % of the best QC "
                    f"(median QC mean {format_number(best['qc_mean'])} for {best['variant']}) with no foldovers")
            fastest = rec.dropna(subset=["time_ratio"]).sort_values("time_ratio")
            if len(fastest) > 1:
                f = fastest.iloc[0]
                text += (f"; the fastest of them is {f['variant']}" + (
                    "" if f["variant"] == REFERENCE_METHOD else
                    f", at {f['time_ratio']:.2g}× the time of {REFERENCE_METHOD}"))
            text += "."
        else:
            text = f"{family.capitalize()} ({where}): no method is acceptable on every surface of this family."
        if len(fails):
            kinds = fails["reason"].map(reason_kind)
            parts = [f"{k} ({', '.join(fails.loc[kinds == k, 'variant'])})" for k in dict.fromkeys(kinds)]
            text += f" {len(fails)} variant(s) are not acceptable: " + "; ".join(parts) + "."
        out.append(text)
    return out

