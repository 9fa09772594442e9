"""The OCP energy landscape E(k) and boundary turning number t(k) (the paper's Fig. 9)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from matplotlib.ticker import NullFormatter

from ._common import Picture, figure_to_picture, new_figure, wrap_label

__all__ = ["LandscapeCurve", "landscape_figure", "split_by_scale"]

_COLORS = ("#4e79a7", "#e15759", "#59a14f", "#f28e2b", "#b07aa1", "#76b7b2")


@dataclass
class LandscapeCurve:
    """One method's line search over the scale k.

    Attributes
    ----------
    label : str
    k, energy, turning : (K,) numpy.ndarray of float64
        Sampled scales, the energy at each, and the boundary turning number at each.
    k_opt : float
        The chosen scale (NaN if not recorded).
    """

    label: str
    k: np.ndarray
    energy: np.ndarray
    turning: np.ndarray
    k_opt: float = float("nan")


def split_by_scale(curves: list[LandscapeCurve], factor: float = 4.0) -> list[list[LandscapeCurve]]:
    """Group curves whose k_opt are within ``factor`` of each other (one panel per group).

    A variant whose k_opt is far from the others (the paper-literal OCP energy lands at
    k ~ 10-30 where the default is at ~1) would squeeze every other curve into a corner of
    a shared axis; it gets its own panel instead. Curves without a k_opt go with the first group.

    Parameters
    ----------
    curves : list of LandscapeCurve
    factor : float

    Returns
    -------
    list of list of LandscapeCurve
        Groups by increasing k_opt, in the input order within a group.
    """
    with_k = sorted((c for c in curves if c.k_opt == c.k_opt and c.k_opt > 0), key=lambda c: c.k_opt)
    groups: list[list[LandscapeCurve]] = []
    for curve in with_k:
        if groups and curve.k_opt <= factor * groups[-1][0].k_opt:
            groups[-1].append(curve)
        else:
            groups.append([curve])
    rest = [c for c in curves if not (c.k_opt == c.k_opt and c.k_opt > 0)]
    if rest:
        groups = [rest + (groups[0] if groups else [])] + groups[1:]
    order = {id(c): i for i, c in enumerate(curves)}
    return [sorted(g, key=lambda c: order[id(c)]) for g in groups]


def _draw(ax_e, ax_t, curves: list[LandscapeCurve], offset: int) -> None:
    all_e = []
    for i, curve in enumerate(curves):
        color = _COLORS[(offset + i) % len(_COLORS)]
        order = np.argsort(curve.k, kind="stable")
        k, e, t = curve.k[order], curve.energy[order], curve.turning[order]
        # k_opt goes in the legend, not next to its line: labels near k = 1 collided.
        label = curve.label + (f" (k_opt {curve.k_opt:.4g})" if curve.k_opt == curve.k_opt else "")
        ax_e.plot(k, e, "-o", color=color, ms=2.5, lw=1.1, label=label)
        ax_t.step(k, np.round(t, 6), where="mid", color=color, lw=1.1)
        ax_t.plot(k, t, "o", color=color, ms=2)
        if curve.k_opt == curve.k_opt:
            for ax in (ax_e, ax_t):
                ax.axvline(curve.k_opt, color=color, ls="--", lw=0.8)
        all_e.append(e[np.isfinite(e)])
    energies = np.concatenate(all_e) if all_e else np.zeros(0)
    if len(energies) and np.all(energies > 0):
        ax_e.set_yscale("log")
    # Always a log k axis: the same reading on every surface, whatever the spread of k.
    ax_e.set_xscale("log")
    # Minor log labels (2x10^-1, 3x10^-1, ...) run into each other on these short axes.
    for axis in (ax_e.xaxis, ax_e.yaxis, ax_t.xaxis):
        axis.set_minor_formatter(NullFormatter())
    ax_e.grid(True, which="major", alpha=0.3)
    ax_e.legend(fontsize=7, frameon=False, loc="best")
    ax_e.tick_params(labelsize=7)
    ax_t.tick_params(labelsize=7)
    ax_t.grid(True, alpha=0.3)
    ax_t.yaxis.get_major_locator().set_params(integer=True)
    ax_t.set_xlabel("scale k (log)", fontsize=8)


def landscape_figure(curves: list[LandscapeCurve], title: str) -> Picture:
    """Plot E(k) above t(k) for each curve, with a log k axis on every panel.

    Curves whose k_opt differ by more than a factor 4 go to separate panels side by side
    (:func:`split_by_scale`). The energy axis is logarithmic when every finite energy is
    positive (the bowls span decades).

    Parameters
    ----------
    curves : list of LandscapeCurve
        At least one.
    title : str
        The surface's name.

    Returns
    -------
    Picture
    """
    if not curves:
        raise ValueError("landscape_figure needs at least one curve.")
    groups = split_by_scale(curves)
    fig = new_figure(3.4 * len(groups) + 0.4, 3.0)
    grid = fig.subplots(2, len(groups), squeeze=False, height_ratios=[2.2, 1.0], sharex="col")
    offset = 0
    for col, group in enumerate(groups):
        _draw(grid[0, col], grid[1, col], group, offset)
        offset += len(group)
    grid[0, 0].set_ylabel("energy Ê_C", fontsize=8)
    grid[1, 0].set_ylabel("turns t", fontsize=8)
    fig.suptitle(wrap_label(f"k line search — {title}", 3.4 * len(groups), 9, 2), fontsize=9)
    caption = (f"Line search over the scale k (OCP, optimized DNCP) on {title}: the energy Ê_C against k (top, log k "
               f"axis on every surface) and the turning number of the outer boundary polygon (bottom). Below k_opt the "
               f"boundary spins (t > 1) in lower bowls; the search keeps to the t = 1 branch (dashed: k_opt, also in "
               f"the legend)." + (" Variants whose k_opt differ by more than a factor 4 are drawn on separate panels."
                                  if len(groups) > 1 else ""))
    return figure_to_picture(fig, f"OCP landscape — {title}", caption)
