"""pytest-benchmark timing statistics as a bar chart (median, with min-max whiskers)."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from ._common import Picture, figure_to_picture, new_figure

__all__ = ["benchmark_figure"]

_COLORS = ("#4e79a7", "#f28e2b", "#59a14f", "#e15759", "#b07aa1", "#76b7b2")
_MAX_BARS = 60


def benchmark_figure(stats: pd.DataFrame) -> Picture | None:
    """Horizontal bars of the median time of each benchmark, coloured by group.

    Parameters
    ----------
    stats : pandas.DataFrame
        Output of :func:`parambench.reports.benchmarks.load_benchmarks`.

    Returns
    -------
    Picture or None
        None when there is no benchmark with a positive median. At most 60 bars (the
        slowest) are drawn; the table lists all.
    """
    data = stats[np.isfinite(stats["median"]) & (stats["median"] > 0)]
    if data.empty:
        return None
    data = data.nlargest(_MAX_BARS, "median").sort_values(["group", "median"], ascending=[False, True])
    groups = list(dict.fromkeys(data["group"]))
    colors = [_COLORS[groups.index(g) % len(_COLORS)] for g in data["group"]]
    y = np.arange(len(data))
    lo = np.clip(data["median"] - data["min"].fillna(data["median"]), 0, None)
    hi = np.clip(data["max"].fillna(data["median"]) - data["median"], 0, None)
    fig = new_figure(7.0, 0.9 + 0.28 * len(data))
    ax = fig.subplots()
    ax.barh(y, data["median"], color=colors, xerr=[lo, hi], error_kw={"elinewidth": 0.8, "capsize": 2})
    labels = [f"{g} / {n}" if g else str(n) for g, n in zip(data["group"], data["name"])]
    ax.set_yticks(y, labels, fontsize=7)
    ax.set_xscale("log")
    ax.set_xlabel("time per call (s), median with min–max")
    ax.grid(True, axis="x", which="both", alpha=0.25)
    caption = "pytest-benchmark: median time per call of each benchmark, whiskers from the fastest to the slowest round."
    return figure_to_picture(fig, "Benchmark timings", caption, rows=max(1, math.ceil(len(data) / 12)))
