"""Running time against size on log-log axes, per method, with fitted exponents."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from ._common import Picture, figure_to_picture, new_figure

__all__ = ["fit_power_law", "scaling_fits", "scaling_figure"]

_COLORS = ("#4e79a7", "#e15759", "#59a14f", "#f28e2b", "#b07aa1", "#76b7b2", "#edc948", "#ff9da7", "#9c755f")
_NCOLS = 3


def fit_power_law(n: np.ndarray, t: np.ndarray) -> tuple[float, float]:
    """Least-squares fit of ``t = c * n**p`` on log-log axes.

    Parameters
    ----------
    n, t : (K,) numpy.ndarray of float64
        Sizes and times; pairs with a non-positive or non-finite value are ignored.

    Returns
    -------
    (p, c) : tuple of float
        NaN, NaN when fewer than two distinct sizes remain.
    """
    n = np.asarray(n, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64)
    keep = np.isfinite(n) & np.isfinite(t) & (n > 0) & (t > 0)
    n, t = n[keep], t[keep]
    if len(np.unique(n)) < 2:
        return float("nan"), float("nan")
    slope, intercept = np.polyfit(np.log(n), np.log(t), 1)
    return float(slope), float(np.exp(min(intercept, _MAX_LOG)))


#: Largest log of a fitted coefficient kept finite (math.exp overflows past 709).
_MAX_LOG = 700.0


def _timed(rows: pd.DataFrame) -> pd.DataFrame:
    ok = rows[(rows["status"] == "ok") & (rows["time_total"] > 0)].copy()
    # Real datasets have size 0: the measured point count is the honest x axis anyway.
    ok["n"] = ok["n_points"].where(ok["n_points"] > 0, ok["size"])
    # Cells of one requested size are one size: seeds sample 492 and 493 points of a 500-point
    # bump, and fitting a power law to those two "sizes" gave exponents in the hundreds (and
    # an overflow that stopped the report).
    ok["size_key"] = ok["size"].where(ok["size"] > 0, ok["n"])
    return ok[ok["n"] > 0]


def _per_size(group: pd.DataFrame) -> pd.DataFrame:
    """Median point count and median time per requested size (index: the size), smallest first."""
    return group.groupby("size_key").agg(n=("n", "median"), t=("time_total", "median")).sort_values("n")


def scaling_fits(rows: pd.DataFrame) -> pd.DataFrame:
    """Fitted exponent of time against points per (dataset, sampling, noise, variant).

    Fits use the median time and the median point count over the seeds of each requested
    size (a real dataset's one size is its point count).

    Parameters
    ----------
    rows : pandas.DataFrame
        Labelled rows (see :func:`parambench.reports.labels.add_labels`).

    Returns
    -------
    pandas.DataFrame
        Columns ``dataset``, ``sampling``, ``noise``, ``variant``, ``exponent``,
        ``coefficient``, ``n_sizes``, ``n_min``, ``n_max``; only groups with at least two
        sizes.
    """
    ok = _timed(rows)
    out = []
    for (dataset, sampling, noise, variant), group in ok.groupby(["dataset", "sampling", "noise", "variant"],
                                                                 sort=True):
        med = _per_size(group)
        if len(med) < 2:
            continue
        p, c = fit_power_law(med["n"].to_numpy(), med["t"].to_numpy())
        out.append({"dataset": dataset, "sampling": sampling, "noise": noise, "variant": variant, "exponent": p,
                    "coefficient": c, "n_sizes": len(med), "n_min": float(med["n"].min()),
                    "n_max": float(med["n"].max())})
    return pd.DataFrame(out, columns=["dataset", "sampling", "noise", "variant", "exponent", "coefficient",
                                      "n_sizes", "n_min", "n_max"])


def scaling_figure(rows: pd.DataFrame) -> Picture | None:
    """Time against number of points, log-log, one panel per surface family.

    Dots are single cells, lines join the per-size medians, dashed lines are the fits
    (exponent in the legend).

    Parameters
    ----------
    rows : pandas.DataFrame
        Labelled rows.

    Returns
    -------
    Picture or None
        None when no surface family was timed at two or more sizes.
    """
    ok = _timed(rows)
    fits = scaling_fits(rows)
    if fits.empty:
        return None
    families = list(dict.fromkeys(zip(fits["dataset"], fits["sampling"], fits["noise"])))
    variants = sorted(dict.fromkeys(ok["variant"]))
    colors = {v: _COLORS[i % len(_COLORS)] for i, v in enumerate(variants)}
    ncols = min(_NCOLS, len(families))
    nrows = math.ceil(len(families) / ncols)
    fig = new_figure(3.7 * ncols, 3.1 * nrows)
    axes = np.atleast_1d(fig.subplots(nrows, ncols, squeeze=False)).ravel()
    for ax, (dataset, sampling, noise) in zip(axes, families):
        sub = ok[(ok["dataset"] == dataset) & (ok["sampling"] == sampling) & (ok["noise"] == noise)]
        fam_fits = fits[(fits["dataset"] == dataset) & (fits["sampling"] == sampling) & (fits["noise"] == noise)]
        for fit in fam_fits.itertuples():
            pts = sub[sub["variant"] == fit.variant]
            med = _per_size(pts)
            color = colors[fit.variant]
            ax.scatter(pts["n"], pts["time_total"], s=9, color=color, alpha=0.5, linewidths=0)
            ax.plot(med["n"], med["t"], "-o", ms=3, lw=1.2, color=color,
                    label=f"{fit.variant}: ∝ n^{fit.exponent:.2f}")
            grid = np.geomspace(fit.n_min, fit.n_max, 20)
            ax.plot(grid, fit.coefficient * grid ** fit.exponent, "--", lw=0.8, color=color)
        ax.set_xscale("log")
        ax.set_yscale("log")
        name = " · ".join(str(x) for x in (dataset, sampling) if x) + (f" · noise {noise:g}" if noise else "")
        ax.set_title(name, fontsize=9)
        ax.set_xlabel("points")
        ax.set_ylabel("time (s)")
        ax.grid(True, which="both", alpha=0.25)
        ax.legend(fontsize=7, frameon=False, loc="upper center", bbox_to_anchor=(0.5, -0.22))
    for ax in axes[len(families):]:
        ax.set_axis_off()
    caption = ("Total time against number of points on log-log axes. Dots are single cells, solid lines the "
               "median over seeds, dashed lines least-squares fits t = c·n^p with the exponent p in the legend.")
    return figure_to_picture(fig, "Time against size", caption, rows=nrows)
