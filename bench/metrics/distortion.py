"""Area-weighted summaries of per-triangle distortion."""

from __future__ import annotations

import numpy as np

__all__ = ["area_distortion", "weighted_quantile"]


def area_distortion(s1: np.ndarray, s2: np.ndarray, area_3d: np.ndarray) -> float:
    """Spread of the log area ratio, with the global scale removed.

    ``sqrt(sum_t w_t (log(s1_t s2_t) - m)^2 / sum_t w_t)`` with ``w_t`` the 3D areas and
    ``m`` the area-weighted mean of ``log(s1 s2)``. Removing ``m`` makes the number
    independent of the (arbitrary) overall size of the uv layout: a uniform scaling gives 0.

    Parameters
    ----------
    s1, s2 : (M,) array_like of float64
        Singular values per triangle; ``s1 * s2`` is the uv / 3D area ratio.
    area_3d : (M,) array_like of float64
        Weights.

    Returns
    -------
    float
        NaN when no triangle has a positive area ratio. Triangles with ``s1 * s2 == 0``
        (collapsed, log = -inf) are left out; :func:`count_collapsed` reports them.
    """
    ratio = np.asarray(s1, dtype=np.float64) * np.asarray(s2, dtype=np.float64)
    w = np.asarray(area_3d, dtype=np.float64)
    keep = ratio > 0
    if not keep.any() or w[keep].sum() <= 0:
        return float("nan")
    log_ratio = np.log(ratio[keep])
    w = w[keep]
    mean = np.average(log_ratio, weights=w)
    return float(np.sqrt(np.average((log_ratio - mean) ** 2, weights=w)))


def weighted_quantile(values: np.ndarray, weights: np.ndarray, q: float) -> float:
    """Weighted quantile: the smallest value whose cumulative weight share reaches ``q``.

    Parameters
    ----------
    values, weights : (M,) array_like of float64
    q : float in [0, 1]

    Returns
    -------
    float
    """
    # The inverted-CDF definition returns an attained value (no interpolation between
    # triangles), so "95 % of the area has QC <= qc_p95" holds literally.
    return float(np.quantile(np.asarray(values, dtype=np.float64), q,
                             weights=np.asarray(weights, dtype=np.float64), method="inverted_cdf"))
