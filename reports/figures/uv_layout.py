"""Every method's uv layout side by side, triangles coloured by QC on one shared scale."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from matplotlib import colormaps
from matplotlib.collections import LineCollection, PolyCollection
from matplotlib.colors import Normalize
from matplotlib.cm import ScalarMappable

from ..load import CellArrays
from ._common import (MAX_FACES_PER_PANEL, Picture, figure_to_picture, new_figure, splat, subsample_faces,
                      wrap_label)

__all__ = ["LayoutPanel", "shared_qc_range", "uv_layout_figure", "QC_CMAP", "FOLDOVER_COLOR"]

QC_CMAP = "viridis"
FOLDOVER_COLOR = "#e0115f"
#: Panels per row: 8 keeps the quick suite's distinct maps (12 to 14 of its 19 variants, near-identical
#: ones sharing a panel) to two rows, one page with the checkerboards.
_NCOLS = 8
_PANEL_IN = 1.75
_TITLE_PT = 7.5
_LINE_IN = 1.25 * _TITLE_PT / 72
#: Lower than the default: eight panels across are printed about 9 inches wide.
_DPI = 90


@dataclass
class LayoutPanel:
    """One method's map: its label, arrays and headline numbers for the panel title.

    ``qc_mean_high`` is the highest QC mean of the methods the panel stands for, when it
    draws several near-identical maps (:mod:`parambench.reports.map_groups`); the title then gives the
    range.
    """

    label: str
    arrays: CellArrays
    qc_mean: float = float("nan")
    foldovers: float = float("nan")
    qc_mean_high: float = float("nan")


def shared_qc_range(qc_arrays, upper_quantile: float = 0.99) -> tuple[float, float]:
    """One colour scale for all panels: from 1 (conformal) to a high quantile of all QC.

    A quantile rather than the maximum, so one sliver triangle does not wash out every
    panel; larger values saturate (the colour bar says so with an arrow).

    Parameters
    ----------
    qc_arrays : iterable of (M_i,) numpy.ndarray of float64
    upper_quantile : float

    Returns
    -------
    (vmin, vmax) : tuple of float
        ``vmin = 1``, ``vmax >= 1.05``.
    """
    finite = [q[np.isfinite(q)] for q in qc_arrays]
    finite = [q for q in finite if len(q)]
    if not finite:
        return 1.0, 2.0
    values = np.concatenate(finite)
    return 1.0, float(max(1.05, np.quantile(values, upper_quantile)))


def _heading(panel: LayoutPanel) -> str:
    """The panel's title: its label, then QC mean (a range for a group of maps) and foldovers."""
    facts = []
    if panel.qc_mean == panel.qc_mean:
        high = panel.qc_mean_high
        spread = high == high and f"{high:.3f}" != f"{panel.qc_mean:.3f}"
        facts.append(f"QC mean {panel.qc_mean:.3f}" + (f"–{high:.3f}" if spread else ""))
    n_flipped = int(panel.arrays.flipped.sum())
    facts.append(f"{n_flipped} foldover{'s' if n_flipped != 1 else ''}")
    return (wrap_label(panel.label, _PANEL_IN, _TITLE_PT, 3) + "\n"
            + wrap_label(", ".join(facts), _PANEL_IN, _TITLE_PT, 2))


def _draw_panel(ax, panel: LayoutPanel, norm: Normalize, max_faces: int, seed: int) -> None:
    arrays = panel.arrays
    uv, faces = arrays.uv, arrays.faces
    heading = _heading(panel)
    ax.set_title(heading, fontsize=_TITLE_PT)
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])
    for spine in ax.spines.values():
        spine.set_color("#cccccc")
    if not np.isfinite(uv).all():
        ax.text(0.5, 0.5, "uv has NaN or inf:\nnothing to draw", ha="center", va="center",
                transform=ax.transAxes, fontsize=9, color=FOLDOVER_COLOR)
        return
    shown = subsample_faces(len(faces), max_faces, keep=arrays.flipped, seed=seed)
    verts = uv[faces[shown]]
    qc = np.nan_to_num(arrays.qc[shown], nan=norm.vmax, posinf=norm.vmax)
    # Edges in the face colour hide the hairline seams antialiasing leaves between triangles.
    tris = PolyCollection(splat(verts, len(faces)), array=qc, cmap=QC_CMAP, norm=norm, edgecolors="face", linewidths=0.15,
                          antialiased=False)
    ax.add_collection(tris)
    flipped = verts[arrays.flipped[shown]]
    if len(flipped):
        ax.add_collection(PolyCollection(flipped, facecolors=FOLDOVER_COLOR, edgecolors=FOLDOVER_COLOR,
                                         linewidths=0.8, alpha=0.9))
        centres = flipped.mean(axis=1)
        ax.scatter(centres[:, 0], centres[:, 1], s=28, facecolors="none", edgecolors=FOLDOVER_COLOR,
                   linewidths=1.0)
    for loop in arrays.gt_loops or []:
        closed = uv[np.append(loop, loop[0])]
        ax.add_collection(LineCollection([closed], colors="black", linewidths=0.7))
    lo, hi = uv.min(axis=0), uv.max(axis=0)
    pad = 0.03 * max(float((hi - lo).max()), 1e-12)
    ax.set_xlim(lo[0] - pad, hi[0] + pad)
    ax.set_ylim(lo[1] - pad, hi[1] + pad)


def uv_layout_figure(panels: list[LayoutPanel], title: str, *, max_faces: int = MAX_FACES_PER_PANEL,
                     seed: int = 0) -> Picture:
    """Draw the uv layouts of several methods on one surface.

    Parameters
    ----------
    panels : list of LayoutPanel
        At least one.
    title : str
        The surface's name.
    max_faces : int
        Triangles drawn per panel at most (foldovers always drawn).
    seed : int
        Seed of the subsampling.

    Returns
    -------
    Picture
        Panels on a grid of up to eight columns, one colour bar for all; ``panels`` locates
        each method's panel (for the HTML detail view).
    """
    if not panels:
        raise ValueError("uv_layout_figure needs at least one panel.")
    vmin, vmax = shared_qc_range([p.arrays.qc for p in panels])
    norm = Normalize(vmin=vmin, vmax=vmax, clip=True)
    ncols = min(_NCOLS, len(panels))
    nrows = math.ceil(len(panels) / ncols)
    # Room for three title lines; a group of maps (a longer label) adds a line or two.
    lines = max(_heading(p).count("\n") + 1 for p in panels)
    fig = new_figure(_PANEL_IN * ncols + 0.9, (_PANEL_IN + 0.55 + _LINE_IN * max(0, lines - 3)) * nrows)
    axes = np.atleast_1d(fig.subplots(nrows, ncols, squeeze=False)).ravel()
    for ax, panel in zip(axes, panels):
        _draw_panel(ax, panel, norm, max_faces, seed)
    where = {p.label: ax for p, ax in zip(panels, axes)}
    for ax in axes[len(panels):]:
        ax.set_axis_off()
    bar = fig.colorbar(ScalarMappable(norm=norm, cmap=colormaps[QC_CMAP]), ax=list(axes), shrink=0.85,
                       extend="max", pad=0.01, aspect=30)
    bar.set_label("QC (1 = conformal)", fontsize=8)
    bar.ax.tick_params(labelsize=7)
    caption = (f"uv layouts on {title}, triangles coloured by QC distortion on one scale for all methods "
               f"({vmin:g} to {vmax:.3g}; larger values saturate). Foldovers are filled and circled in red, "
               f"ground-truth boundary loops drawn in black.")
    if any(len(p.arrays.faces) > max_faces for p in panels):
        caption += (f" Meshes over {max_faces} triangles are drawn from a random {max_faces} of them (all "
                    f"foldovers kept), each enlarged to close the gaps.")
    return figure_to_picture(fig, f"uv layouts — {title}", caption, rows=nrows, panel_axes=where,
                             dpi=_DPI)
