"""Angle-distortion histograms: how far each corner angle moves under the map, per method."""

from __future__ import annotations

import json
from collections.abc import Sequence

import numpy as np

from ._common import Picture, figure_to_picture, new_figure

__all__ = ["parse_angle_hist", "angle_histogram_figure"]

#: Most curves whose legend fits inside the axes without hiding them.
_LEGEND_INSIDE_MAX = 6


def parse_angle_hist(value) -> np.ndarray | None:
    """A row's ``angle_hist`` (JSON list of counts, or a list) as an int array.

    Parameters
    ----------
    value : str, sequence of int or None

    Returns
    -------
    (B,) numpy.ndarray of int64, or None for a missing or empty histogram (failed cell,
    every face collapsed, a row stored before the column existed).
    """
    if value is None or (isinstance(value, float) and np.isnan(value)):
        return None
    if isinstance(value, str):
        value = json.loads(value) if value.strip() else None
    if value is None or not len(value):
        return None
    return np.asarray(value, dtype=np.int64)


def _share_within(counts: np.ndarray, edges: np.ndarray, limit: float) -> float:
    inner = (edges[:-1] >= -limit) & (edges[1:] <= limit)
    total = counts.sum()
    return float(counts[inner].sum() / total) if total else float("nan")


def angle_histogram_figure(histograms: Sequence[tuple[str, object]], edges: np.ndarray, title: str) -> Picture | None:
    """Histograms of the signed corner-angle change (uv minus 3D, degrees), one curve per variant.

    Each curve is the share of corners per bin (so surfaces and methods with different
    face counts compare), on a log scale so that the rare large changes next to a fold
    stay visible. The end bins hold every change beyond the range (as stored).

    Parameters
    ----------
    histograms : sequence of (str, counts)
        Variant label and its stored ``angle_hist`` (JSON string or list of counts over
        ``edges``); variants without a histogram are skipped.
    edges : (B + 1,) array_like of float
        The bin edges in degrees the counts were taken over
        (``parambench.bench.schema.ANGLE_HIST_EDGES_DEG``).
    title : str
        The surface's name.

    Returns
    -------
    Picture or None
        None when no variant has a histogram.

    Raises
    ------
    ValueError
        A histogram whose length is not ``len(edges) - 1``.
    """
    edges = np.asarray(edges, dtype=np.float64)
    curves = []
    for label, raw in histograms:
        counts = parse_angle_hist(raw)
        if counts is None or counts.sum() == 0:
            continue
        if counts.shape != (edges.size - 1,):
            raise ValueError(f"angle histogram of {label!r} has {counts.size} bins, the edges give {edges.size - 1}.")
        curves.append((label, counts))
    if not curves:
        return None
    # Past a few curves a legend inside the axes hides them: it goes beside them instead.
    outside = len(curves) > _LEGEND_INSIDE_MAX
    fig = new_figure(9.6 if outside else 6.4, 3.2 if len(curves) <= 14 else 3.2 + 0.13 * (len(curves) - 14))
    ax = fig.subplots()
    for label, counts in curves:
        share = counts / counts.sum()
        ax.stairs(np.maximum(share, 1e-9), edges, label=f"{label} ({100 * _share_within(counts, edges, 1.0):.0f}% "
                  "within 1°)", linewidth=1.2)
    ax.axvline(0.0, color="black", lw=0.8)
    ax.set_yscale("log")
    ax.set_ylim(bottom=max(1e-6, 0.5 / max(int(c.sum()) for _, c in curves)))
    ax.set_xlabel("angle in uv − angle in 3D (degrees)")
    ax.set_ylabel("share of corners (log)")
    if outside:
        fig.legend(fontsize=7, frameon=False, loc="outside right upper")
    else:
        ax.legend(fontsize=7, frameon=True, framealpha=0.85, loc="upper right")
    caption = (f"Change of every triangle corner's angle under the map on {title}: 0 is conformal. "
               f"Bins of {edges[1] - edges[0]:g}° from {edges[0]:g}° to {edges[-1]:g}°; larger changes are "
               "counted in the end bins. The legend gives the share of corners within ±1°.")
    return figure_to_picture(fig, f"Angle distortion — {title}", caption)
