"""The OCP energy landscape E(k) and boundary turning number t(k) (the paper's Fig. 9)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._common import Picture, figure_to_picture, new_figure

__all__ = ["LandscapeCurve", "landscape_figure"]

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


def landscape_figure(curves: list[LandscapeCurve], title: str) -> Picture:
    """Plot E(k) above t(k) for each curve, sharing the k axis.

    Samples are sorted by k. The energy axis is logarithmic when every finite energy is
    positive (the bowls span decades), the k axis when k spans more than a factor of 20.

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
    fig = new_figure(6.4, 3.3)
    ax_e, ax_t = fig.subplots(2, 1, sharex=True, height_ratios=[2.2, 1.0])
    all_e, all_k = [], []
    for i, curve in enumerate(curves):
        color = _COLORS[i % len(_COLORS)]
        order = np.argsort(curve.k, kind="stable")
        k, e, t = curve.k[order], curve.energy[order], curve.turning[order]
        ax_e.plot(k, e, "-o", color=color, ms=3, lw=1.2, label=curve.label)
        ax_t.step(k, np.round(t, 6), where="mid", color=color, lw=1.2)
        ax_t.plot(k, t, "o", color=color, ms=2.5)
        if curve.k_opt == curve.k_opt:
            for ax in (ax_e, ax_t):
                ax.axvline(curve.k_opt, color=color, ls="--", lw=0.9)
            right = curve.k_opt > np.nanmax(k) - 0.3 * (np.nanmax(k) - np.nanmin(k))
            ax_e.annotate(f"k_opt = {curve.k_opt:.3g}", (curve.k_opt, 1.0), xycoords=("data", "axes fraction"),
                          xytext=(-3 if right else 3, -12 - 10 * i), textcoords="offset points", fontsize=8,
                          color=color, ha="right" if right else "left")
        all_e.append(e[np.isfinite(e)])
        all_k.append(k[np.isfinite(k)])
    energies, ks = np.concatenate(all_e), np.concatenate(all_k)
    if len(energies) and np.all(energies > 0):
        ax_e.set_yscale("log")
    if len(ks) and ks.min() > 0 and ks.max() / ks.min() > 20:
        ax_e.set_xscale("log")
    ax_e.set_ylabel("energy Ê_C")
    ax_e.grid(True, which="major", alpha=0.3)
    ax_e.legend(fontsize=8, frameon=False)
    ax_t.set_ylabel("turns t")
    ax_t.set_xlabel("scale k")
    ax_t.grid(True, alpha=0.3)
    ax_t.yaxis.get_major_locator().set_params(integer=True)
    fig.suptitle(f"Energy and turning number along the k line search — {title}", fontsize=10)
    caption = (f"Line search over the scale k (OCP, optimized DNCP) on {title}: the energy Ê_C against the scale k (top) and the turning number of "
               f"the outer boundary polygon (bottom). Below k_opt the boundary spins (t > 1) in lower bowls; the search "
               f"keeps to the t = 1 branch (dashed: the chosen k_opt).")
    return figure_to_picture(fig, f"OCP landscape — {title}", caption)
