"""Weight-value histograms at interior and boundary points, W^cot against W^tan (the paper's Fig. 5)."""

from __future__ import annotations

import numpy as np
from matplotlib.ticker import NullFormatter

from ._common import Picture, figure_to_picture, new_figure

__all__ = ["WEIGHT_KEYS", "negative_fractions", "shared_bins", "weights_figure"]

#: Keys of the dataset npz, by (weights, where).
WEIGHT_KEYS = {
    ("cot", "interior"): "w_cot_interior",
    ("cot", "boundary"): "w_cot_boundary",
    ("tan", "interior"): "w_tan_interior",
    ("tan", "boundary"): "w_tan_boundary",
}
_COLORS = {"interior": "#d62728", "boundary": "#1f77b4"}  # red and blue as in the paper
_TITLES = {"cot": "cotangent weights W$^{cot}$", "tan": "tangent-space weights W$^{tan}$"}


def negative_fractions(arrays: dict) -> dict:
    """Share of negative weights per (weights, where) key present in ``arrays``.

    Parameters
    ----------
    arrays : dict of str to numpy.ndarray
        A dataset npz's arrays.

    Returns
    -------
    dict of (str, str) to float
        NaN for an empty array.
    """
    out = {}
    for key, name in WEIGHT_KEYS.items():
        if name in arrays:
            values = np.asarray(arrays[name], dtype=np.float64).ravel()
            values = values[np.isfinite(values)]
            out[key] = float(np.mean(values < 0)) if len(values) else float("nan")
    return out


def shared_bins(samples, n_bins: int = 60, quantiles: tuple = (0.005, 0.995)) -> np.ndarray:
    """Common histogram bin edges over several samples, clipped to central quantiles.

    The range spans the pooled ``quantiles`` (so a few extreme weights do not squash the
    histogram) and always includes 0 (the sign of a weight is what matters).

    Parameters
    ----------
    samples : iterable of 1D numpy.ndarray
    n_bins : int
    quantiles : (float, float)

    Returns
    -------
    (n_bins + 1,) numpy.ndarray of float64
    """
    pooled = np.concatenate([np.asarray(s, dtype=np.float64).ravel() for s in samples] or [np.zeros(0)])
    pooled = pooled[np.isfinite(pooled)]
    if not len(pooled):
        return np.linspace(-1.0, 1.0, n_bins + 1)
    lo, hi = np.quantile(pooled, quantiles)
    lo, hi = min(lo, 0.0), max(hi, 0.0)
    if hi <= lo:
        hi = lo + 1.0
    return np.linspace(lo, hi, n_bins + 1)


def weights_figure(arrays: dict, title: str) -> Picture | None:
    """Histograms of weight values, one panel per weight kind, interior and boundary overlaid.

    Densities (not counts) are drawn, because there are far fewer boundary than interior
    weights. Values beyond the shared bins are clipped into the end bins.

    Parameters
    ----------
    arrays : dict of str to numpy.ndarray
        Needs at least one of the :data:`WEIGHT_KEYS` arrays.
    title : str
        The surface's name.

    Returns
    -------
    Picture or None
        None when ``arrays`` holds no weight samples.
    """
    kinds = [w for w in ("cot", "tan") if any(WEIGHT_KEYS[(w, p)] in arrays for p in ("interior", "boundary"))]
    if not kinds:
        return None
    fractions = negative_fractions(arrays)
    fig = new_figure(3.6 * len(kinds), 2.9)
    axes = np.atleast_1d(fig.subplots(1, len(kinds), squeeze=False)).ravel()
    for ax, kind in zip(axes, kinds):
        samples = {p: np.asarray(arrays[WEIGHT_KEYS[(kind, p)]], dtype=np.float64).ravel()
                   for p in ("interior", "boundary") if WEIGHT_KEYS[(kind, p)] in arrays}
        samples = {p: s[np.isfinite(s)] for p, s in samples.items()}
        bins = shared_bins(samples.values())
        for where, values in samples.items():
            if not len(values):
                continue
            share = fractions.get((kind, where), float("nan"))
            ax.hist(np.clip(values, bins[0], bins[-1]), bins=bins, density=True, histtype="stepfilled",
                    alpha=0.35, color=_COLORS[where], edgecolor=_COLORS[where], linewidth=1.0,
                    label=f"{where} (n={len(values)}, {100 * share:.1f}% < 0)")
        ax.axvline(0.0, color="black", lw=0.8)
        ax.set_title(_TITLES[kind], fontsize=9)
        ax.set_xlabel("weight value")
        ax.set_yscale("log")
        # Minor log labels (3x10^-1, 4x10^-1, ...) crowd into each other on short axes.
        ax.yaxis.set_minor_formatter(NullFormatter())
        ax.legend(fontsize=7, frameon=False, loc="upper center", bbox_to_anchor=(0.5, -0.2))
    axes[0].set_ylabel("density (log)")
    parts = []
    for kind in kinds:
        for where in ("interior", "boundary"):
            if (kind, where) in fractions:
                parts.append(f"{kind} {where} {100 * fractions[(kind, where)]:.1f}%")
    caption = (f"Weight values on {title} at interior (red) and boundary (blue) points. Negative weights: "
               + ", ".join(parts) + ".")
    return figure_to_picture(fig, f"Weight histograms — {title}", caption)
