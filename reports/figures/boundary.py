"""Detected boundary points and loops against the ground-truth boundary (cf. the paper's Fig. 7)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from matplotlib.collections import LineCollection
from matplotlib.lines import Line2D

from ._common import Picture, figure_to_picture, new_figure, view_projection

__all__ = ["BoundaryPanel", "boundary_scores", "classify_points", "boundary_figure"]

_NCOLS = 3
_MAX_CLOUD = 20_000  # grey context points drawn per panel
_GT_COLOR = "#333333"
_DET_COLOR = "#f28e2b"
_FALSE_COLOR = "#e15759"
_MISS_COLOR = "#1f1f1f"
_LOOP_COLORS = ("#4e79a7", "#59a14f", "#b07aa1", "#76b7b2", "#edc948")


@dataclass
class BoundaryPanel:
    """One detection to draw.

    Attributes
    ----------
    label : str
    points : (N, 3) numpy.ndarray of float64
    gt_loops : list of int arrays or None
        Ground-truth boundary loops (outer first).
    det_mask : (N,) numpy.ndarray of bool or None
        Points flagged as boundary by the detector.
    det_loops : list of int arrays or None
        Loops the detector assembled.
    faces : (M, 3) int array or None
        A triangulation of the points, used only to view the surface from its front side.
    """

    label: str
    points: np.ndarray
    gt_loops: list | None = None
    det_mask: np.ndarray | None = None
    det_loops: list | None = None
    faces: np.ndarray | None = None


def boundary_scores(n_points: int, gt_loops, det_mask=None, det_loops=None) -> dict:
    """Precision and recall of detected boundary points against the ground truth.

    The detected set is ``det_mask`` when given, else the points of ``det_loops``; the true
    set is the points of ``gt_loops``.

    Parameters
    ----------
    n_points : int
    gt_loops : list of int arrays
    det_mask : (n_points,) bool array, optional
    det_loops : list of int arrays, optional

    Returns
    -------
    dict
        ``n_true``, ``n_detected``, ``n_hit`` (ints), ``precision`` = hit / detected and
        ``recall`` = hit / true (NaN when the denominator is 0), ``n_gt_loops``,
        ``n_det_loops`` (int, or None when loops were not given).
    """
    truth = np.zeros(n_points, dtype=bool)
    for loop in gt_loops or []:
        truth[loop] = True
    if det_mask is not None:
        found = np.asarray(det_mask, dtype=bool).copy()
    else:
        found = np.zeros(n_points, dtype=bool)
        for loop in det_loops or []:
            found[loop] = True
    hit = int(np.count_nonzero(truth & found))
    n_true, n_found = int(truth.sum()), int(found.sum())
    return {
        "n_true": n_true, "n_detected": n_found, "n_hit": hit,
        "precision": hit / n_found if n_found else float("nan"),
        "recall": hit / n_true if n_true else float("nan"),
        "n_gt_loops": None if gt_loops is None else len(gt_loops),
        "n_det_loops": None if det_loops is None else len(det_loops),
    }


def classify_points(n_points: int, gt_loops, det_mask: np.ndarray):
    """Split points into detected-and-true, detected-but-false and missed.

    Parameters
    ----------
    n_points : int
    gt_loops : list of int arrays, or None
        Ground truth; with None every detected point counts as a hit and none as missed.
    det_mask : (n_points,) bool array

    Returns
    -------
    hit, false_alarm, missed : (n_points,) numpy.ndarray of bool
    """
    mask = np.asarray(det_mask, dtype=bool)
    if gt_loops is None:
        return mask.copy(), np.zeros(n_points, dtype=bool), np.zeros(n_points, dtype=bool)
    truth = np.zeros(n_points, dtype=bool)
    for loop in gt_loops:
        truth[loop] = True
    return mask & truth, mask & ~truth, truth & ~mask


def _closed_segments(xy: np.ndarray, loops) -> list[np.ndarray]:
    return [xy[np.append(loop, loop[0])] for loop in loops or [] if len(loop) > 1]


def _draw_panel(ax, panel: BoundaryPanel, seed: int) -> str:
    xy, _, _ = view_projection(panel.points, panel.faces)
    n = len(panel.points)
    rng = np.random.default_rng(seed)
    cloud = rng.choice(n, size=_MAX_CLOUD, replace=False) if n > _MAX_CLOUD else np.arange(n)
    ax.scatter(xy[cloud, 0], xy[cloud, 1], s=1.0, c="#c8c8c8", linewidths=0)
    if panel.gt_loops:
        ax.add_collection(LineCollection(_closed_segments(xy, panel.gt_loops), colors=_GT_COLOR, linewidths=3.0,
                                         alpha=0.45, zorder=2))
    mask = panel.det_mask
    if mask is None and panel.det_loops:
        mask = np.zeros(n, dtype=bool)
        for loop in panel.det_loops:
            mask[loop] = True
    if mask is not None:
        hit, false_alarm, missed = classify_points(n, panel.gt_loops, mask)
        ax.scatter(xy[hit, 0], xy[hit, 1], s=12, c=_DET_COLOR, linewidths=0, zorder=4.5)
        ax.scatter(xy[false_alarm, 0], xy[false_alarm, 1], s=22, c=_FALSE_COLOR, edgecolors="black",
                   linewidths=0.5, zorder=5)
        ax.scatter(xy[missed, 0], xy[missed, 1], s=26, facecolors="none", edgecolors=_MISS_COLOR,
                   linewidths=1.0, zorder=5)
    for i, seg in enumerate(_closed_segments(xy, panel.det_loops)):
        ax.plot(seg[:, 0], seg[:, 1], color=_LOOP_COLORS[i % len(_LOOP_COLORS)], lw=1.0, ls="--", zorder=4)
    ax.set_aspect("equal")
    ax.set_axis_off()
    facts = ""
    if panel.gt_loops is not None and mask is not None:
        s = boundary_scores(n, panel.gt_loops, mask, panel.det_loops)
        facts = (f"precision {s['precision']:.2f}, recall {s['recall']:.2f}"
                 + (f", {s['n_det_loops']} loop(s) found vs {s['n_gt_loops']}" if s["n_det_loops"] is not None
                    else ""))
    elif mask is not None:
        facts = f"{int(mask.sum())} boundary points detected (no ground truth)"
    ax.set_title(panel.label + ("\n" + facts if facts else ""), fontsize=9)
    return facts


def boundary_figure(panels: list[BoundaryPanel], title: str, *, seed: int = 0) -> Picture:
    """Draw detected boundaries over the ground truth, in a 3D view of the point set.

    Parameters
    ----------
    panels : list of BoundaryPanel
        At least one.
    title : str
        The surface's name.
    seed : int
        Seed of the subsampling of the grey context points.

    Returns
    -------
    Picture
    """
    if not panels:
        raise ValueError("boundary_figure needs at least one panel.")
    ncols = min(_NCOLS, len(panels))
    nrows = math.ceil(len(panels) / ncols)
    legend_in = 0.4 if ncols > 1 else 0.55  # one narrow panel: the legend takes two lines
    height = 3.0 * nrows + legend_in
    # Fixed margins: constrained layout mis-places titles of equal-aspect panels next to a legend.
    fig = new_figure(max(3.4 * ncols, 6.4), height, layout=None)
    fig.subplots_adjust(left=0.01, right=0.99, bottom=legend_in / height, top=1.0 - 0.5 / height,
                        wspace=0.04, hspace=0.3)
    axes = np.atleast_1d(fig.subplots(nrows, ncols, squeeze=False)).ravel()
    for ax, panel in zip(axes, panels):
        _draw_panel(ax, panel, seed)
    for ax in axes[len(panels):]:
        ax.set_axis_off()
    handles = [Line2D([], [], color=_GT_COLOR, lw=3.0, alpha=0.45, label="ground-truth boundary"),
               Line2D([], [], color=_DET_COLOR, marker="o", ls="", ms=4, label="detected, on the boundary"),
               Line2D([], [], color=_FALSE_COLOR, marker="o", mec="black", mew=0.5, ls="", ms=5,
                      label="detected, not on it"),
               Line2D([], [], color=_MISS_COLOR, marker="o", mfc="none", ls="", ms=5, label="missed"),
               Line2D([], [], color=_LOOP_COLORS[0], lw=1.0, ls="--", label="detected loop")]
    fig.legend(handles=handles, loc="lower center", ncol=5 if ncols > 1 else 3, fontsize=7, frameon=False)
    caption = (f"Boundary detection on {title}: points the angle criterion flags (orange if on the true boundary, "
               f"red if not), true boundary points it missed (open circles) and the loops built from the flagged "
               f"points (dashed), over the true boundary (grey). Precision is the share of flagged points that are "
               f"truly on the boundary, recall the share of true boundary points flagged.")
    return figure_to_picture(fig, f"Boundary detection — {title}", caption, rows=nrows)
