"""``ocp`` against ``fbcp-pc``, the point-cloud state of the art, surface by surface.

The suite's goal (issue #13): ``ocp`` at or below ``fbcp-pc`` (Choi, Liu & Lui 2022) on mean
|mu| and on foldovers on every surface, with ``fbcp-pc`` on the boundary ``ocp`` detects and on
the true one (``boundary=given``). This module pairs the two per surface and seed, says for
each pair whether the goal holds and why not, and sums it up as lines of the claims table.

Each ``ocp`` variant with the default (Neumann) energy is compared on its own, named by its
label as elsewhere in the report (``ocp``, ``ocp [refine=mesh]``): the quick suite runs both on
every surface and seed, and they are different maps.

"At or below" allows a tie: ocp's mean |mu| at most ``1 + PEER_TIE`` times fbcp-pc's or at most
``MU_FLOOR`` above it (on a plane both maps are exact up to rounding: 1e-8 against 1e-14 is no
difference), and no more foldovers. A method whose cell failed has no map: the other wins the pair; a ``suspect``
cell (its map failed the self-check) counts with its figures, and the table marks it.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from .claims import Claim, _list, _param, _status, _with_seeds
from .tables import MEASURED_STATUSES, Cell, Table, format_number

__all__ = ["PEER_TIE", "MU_FLOOR", "PEER_VARIANTS", "ocp_vs_fbcp", "claim_ocp_vs_fbcp", "ocp_vs_fbcp_table"]

#: Relative |mu| margin within which ocp still counts as "at or below" fbcp-pc.
PEER_TIE = 0.005
#: Absolute |mu| difference below which two maps tie (rounding of exactly conformal maps).
MU_FLOOR = 1e-6
#: fbcp-pc's boundary settings compared, with the column label of each.
PEER_VARIANTS = {"detected": "fbcp-pc (detected boundary)", "given": "fbcp-pc (true boundary)"}
_NOT_MEASURED = "not measured in this run"
_KEY = ["config", "seed"]


def _cells(rows: pd.DataFrame, method: str, **params) -> pd.DataFrame:
    """Rows of one method's variants that match ``params`` (any status), one per variant, surface and seed.

    ``variant`` is kept: two variants may match the same ``params`` (``ocp`` and ``ocp
    [refine=mesh]`` both use the default energy) and must not stand in for each other.
    """
    sel = rows[rows["method"] == method]
    for key, value in params.items():
        sel = sel[np.array([(_param(r, key) if key != "boundary" else _boundary(r)) == value
                            for _, r in sel.iterrows()], dtype=bool)]
    return sel[["variant", *_KEY, "status", "mu_mean", "foldovers"]].drop_duplicates(["variant", *_KEY])


def _boundary(row) -> str:
    # fbcp-pc's default is the detected boundary; the run stores only non-default params.
    value = _param(row, "boundary")
    return "detected" if value is None else str(value)


def _verdict(ocp: pd.Series, peer: pd.Series) -> tuple[bool | None, str]:
    """(goal holds?, reason) for one pair; None when neither method has a map."""
    ocp_ok = ocp["status"] in MEASURED_STATUSES and ocp["mu_mean"] == ocp["mu_mean"]
    peer_ok = peer["status"] in MEASURED_STATUSES and peer["mu_mean"] == peer["mu_mean"]
    if not ocp_ok and not peer_ok:
        return None, "both failed"
    if not ocp_ok:
        return False, f"ocp {ocp['status']}"
    if not peer_ok:
        return True, f"fbcp-pc {peer['status']}"
    f_ocp, f_peer = _count(ocp["foldovers"]), _count(peer["foldovers"])
    reasons = []
    if ocp["mu_mean"] > (1.0 + PEER_TIE) * peer["mu_mean"] and ocp["mu_mean"] - peer["mu_mean"] > MU_FLOOR:
        reasons.append(f"|mu| {ocp['mu_mean'] / peer['mu_mean'] - 1.0:+.1%}")
    if f_ocp > f_peer:
        reasons.append(f"foldovers {f_ocp} vs {f_peer}")
    return not reasons, ", ".join(reasons)


def _count(value) -> int:
    return 0 if value is None or (isinstance(value, float) and math.isnan(value)) else int(value)


def ocp_vs_fbcp(rows: pd.DataFrame) -> pd.DataFrame:
    """Pairs of each ``ocp`` variant (default energy) and each ``fbcp-pc`` boundary variant per surface and seed.

    Parameters
    ----------
    rows : pandas.DataFrame
        Labelled rows (``config``, ``variant``, ``method``, ``params``, ``status``, ``mu_mean``,
        ``foldovers``).

    Returns
    -------
    pandas.DataFrame
        One row per (ocp variant, config, seed, fbcp-pc variant) where both methods ran:
        ``variant`` (the ocp variant's label), ``config``, ``seed``, ``peer`` (a key of
        :data:`PEER_VARIANTS`), ``peer_name`` (its label, with the fbcp-pc variant's when two
        share that boundary), ``status_ocp``, ``mu_ocp``, ``folds_ocp``, ``status_peer``,
        ``mu_peer``, ``folds_peer``, ``holds`` (True, False or None when neither has a map)
        and ``reason``.
    """
    columns = ["variant", *_KEY, "peer", "peer_name", "status_ocp", "mu_ocp", "folds_ocp", "status_peer", "mu_peer",
               "folds_peer", "holds", "reason"]
    ocp = _cells(rows, "ocp", energy="neumann")
    out = []
    for peer, label in PEER_VARIANTS.items():
        peers = _cells(rows, "fbcp-pc", boundary=peer)
        several = peers["variant"].nunique() > 1
        pairs = ocp.merge(peers, on=_KEY, suffixes=("_o", "_p"))
        for _, r in pairs.iterrows():
            a = pd.Series({"status": r["status_o"], "mu_mean": r["mu_mean_o"], "foldovers": r["foldovers_o"]})
            b = pd.Series({"status": r["status_p"], "mu_mean": r["mu_mean_p"], "foldovers": r["foldovers_p"]})
            holds, reason = _verdict(a, b)
            name = f"{label}: {r['variant_p']}" if several else label
            out.append([r["variant_o"], r["config"], r["seed"], peer, name, r["status_o"], r["mu_mean_o"],
                        r["foldovers_o"], r["status_p"], r["mu_mean_p"], r["foldovers_p"], holds, reason])
    return pd.DataFrame(out, columns=columns)


def _goal_text(variant: str) -> str:
    return (f"Goal of this suite: {variant} at or below fbcp-pc (Choi, Liu & Lui 2022) on mean |mu| and foldovers, "
            f"with fbcp-pc on the detected and on the true boundary (ties within {PEER_TIE:.1%} of |mu|)")


def claim_ocp_vs_fbcp(rows: pd.DataFrame) -> list[Claim]:
    """The goal as lines of the claims table, one per ocp variant: met, partly met or not, and where it fails.

    Parameters
    ----------
    rows : pandas.DataFrame
        Labelled rows.

    Returns
    -------
    list of Claim
        One per ocp variant with the default energy, named by its label; a single "not
        measured" claim when no surface has both methods.
    """
    pairs = ocp_vs_fbcp(rows)
    judged = pairs[pairs["holds"].notna()]
    if judged.empty:
        return [Claim(_goal_text("ocp"), "—", _NOT_MEASURED, "needs ocp and fbcp-pc on the same surfaces")]
    return [_goal_claim(str(variant), group) for variant, group in judged.groupby("variant", sort=True)]


def _goal_claim(variant: str, judged: pd.DataFrame) -> Claim:
    """The goal's line for one ocp variant, from its judged pairs."""
    judged = judged.sort_values(["config", "peer", "peer_name", "seed"], kind="stable")
    holds = judged["holds"].astype(bool)
    both = judged[(judged["status_ocp"].isin(MEASURED_STATUSES)) & judged["status_peer"].isin(MEASURED_STATUSES)]
    both = both[both["mu_peer"] > MU_FLOOR]  # a ratio of two rounding errors says nothing
    ratio = (both["mu_ocp"] / both["mu_peer"]).replace([np.inf, -np.inf], np.nan).dropna()
    measured = f"{variant} at or below on {int(holds.sum())} of {len(judged)} pairs"
    if not ratio.empty:
        measured += f"; |mu| ratio ocp / fbcp-pc {ratio.min():.3g} – {ratio.max():.3g} (median {ratio.median():.3g})"
    against = pd.Series([f"{c} vs {_short_peer(p, name)}" for c, p, name in
                         zip(judged["config"], judged["peer"], judged["peer_name"])], index=judged.index)
    where = ""
    if holds.any():
        where = "holds on " + _list(_with_seeds(against[holds], judged.loc[holds, "seed"]))
    if (~holds).any():
        where += ("; " if where else "") + "fails on " + _list(_with_seeds(
            against[~holds], judged.loc[~holds, "seed"], judged.loc[~holds, "reason"]))
    return Claim(_goal_text(variant), measured, _status(int(holds.sum()), len(holds)), where)


def _short_peer(peer: str, name: str) -> str:
    # In a list that is all about fbcp-pc, "fbcp-pc (true boundary)" reads "true boundary"; a
    # variant named after the label (two fbcp-pc variants on one boundary) is kept.
    label = PEER_VARIANTS[peer]
    return label.removeprefix("fbcp-pc (").removesuffix(")") + name[len(label):]


def ocp_vs_fbcp_table(rows: pd.DataFrame) -> Table | None:
    """Per surface: ocp's and fbcp-pc's mean |mu| and foldovers, and whether the goal holds.

    Returns
    -------
    Table or None
        None when the run has no surface with both methods.
    """
    pairs = ocp_vs_fbcp(rows)
    if pairs.empty:
        return None

    def figure(status, mu, folds) -> str:
        if status not in MEASURED_STATUSES:
            return status
        text = f"{format_number(mu, 'small')} / {format_number(folds, 'count')}"
        return text + (" (suspect)" if status == "suspect" else "")

    body = []
    for _, r in pairs.sort_values(["variant", *_KEY, "peer", "peer_name"]).iterrows():
        verdict = "—" if r["holds"] is None else ("yes" if r["holds"] else "no")
        classes = ("claim", {"yes": "met", "no": "not-met"}.get(verdict, "not-measured-in-this-run"))
        body.append([Cell(str(r["variant"]), ("method",)), Cell(str(r["config"])), Cell(str(int(r["seed"]))),
                     Cell(r["peer_name"]), Cell(figure(r["status_ocp"], r["mu_ocp"], r["folds_ocp"])),
                     Cell(figure(r["status_peer"], r["mu_peer"], r["folds_peer"])),
                     Cell(verdict, classes), Cell(r["reason"])])
    return Table(["ocp variant", "Surface", "Seed", "Peer", "ocp: mean |mu| / foldovers",
                  "peer: mean |mu| / foldovers", "ocp at or below", "Why not / note"], body,
                 "ocp against fbcp-pc per surface (mean |mu| on the true mesh, foldovers), each ocp variant on its "
                 "own", "peers")
