"""SDP's QC and foldovers against the number of points on surfaces with holes (issue "SDP as it is")."""

from __future__ import annotations

import pandas as pd

from ._common import Picture, figure_to_picture, new_figure

__all__ = ["sdp_curve_figure"]

_COLORS = ("#4e79a7", "#e15759", "#59a14f", "#f28e2b", "#b07aa1", "#76b7b2")


def sdp_curve_figure(curve: pd.DataFrame) -> Picture | None:
    """QC mean (left) and foldover share (right) against N, one line per surface and variant.

    Parameters
    ----------
    curve : pandas.DataFrame
        Output of :func:`parambench.reports.claims.sdp_size_curve` (columns ``family``, ``variant``,
        ``n``, ``qc_mean``, ``foldover_fraction``).

    Returns
    -------
    Picture or None
        None when ``curve`` is empty.
    """
    if curve.empty:
        return None
    fig = new_figure(7.2, 2.6)
    ax_q, ax_f = fig.subplots(1, 2)
    for i, ((family, variant), g) in enumerate(curve.groupby(["family", "variant"], sort=True)):
        g = g.sort_values("n")
        color = _COLORS[i % len(_COLORS)]
        label = f"{variant} · {family}"
        ax_q.plot(g["n"], g["qc_mean"], "-o", ms=3, color=color, label=label)
        ax_f.plot(g["n"], 100.0 * g["foldover_fraction"].fillna(0.0), "-o", ms=3, color=color, label=label)
    for ax, ylabel in ((ax_q, "QC mean"), (ax_f, "foldovers (% of faces)")):
        ax.set_xscale("log")
        ax.set_xlabel("points N", fontsize=8)
        ax.set_ylabel(ylabel, fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(True, which="both", alpha=0.25)
    ax_q.legend(fontsize=7, frameon=False)
    caption = ("SDP on surfaces with holes against the number of points: the median QC mean over seeds (left) and the "
               "median share of folded faces (right), as measured in this run.")
    return figure_to_picture(fig, "SDP against N", caption)
