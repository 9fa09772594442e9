"""Area-weighted summaries of per-triangle distortion."""

from __future__ import annotations

import numpy as np

__all__ = ["area_distortion", "normalized_area_distortion", "weighted_quantile"]


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


def normalized_area_distortion(s1: np.ndarray, s2: np.ndarray, area_3d: np.ndarray) -> float:
    """Area-weighted mean of ``|log r_t|``, ``r_t`` the triangle's share of the uv area over its share of the 3D area.

    Both total areas are normalised to 1 first, so ``r_t = (s1_t s2_t / R)`` with
    ``R = sum_t s1_t s2_t A_t / sum_t A_t`` the overall uv / 3D area ratio; a similarity
    gives 0, and a triangle with twice its fair share of uv area contributes ``log 2``.
    Unlike :func:`area_distortion` (a standard deviation of ``log r``) this is the mean
    absolute deviation from the undistorted value, the form the area-preservation
    literature reports.

    Parameters
    ----------
    s1, s2 : (M,) array_like of float64
        Singular values per triangle.
    area_3d : (M,) array_like of float64
        3D areas (weights).

    Returns
    -------
    float
        NaN when no triangle has a positive area ratio; triangles with ``s1 * s2 == 0``
        (collapsed) are left out of the mean but their (zero) uv area is in the totals.
    """
    ratio = np.asarray(s1, dtype=np.float64) * np.asarray(s2, dtype=np.float64)
    w = np.asarray(area_3d, dtype=np.float64)
    keep = ratio > 0
    total_3d = w.sum()
    if not keep.any() or total_3d <= 0 or w[keep].sum() <= 0:
        return float("nan")
    overall = float(np.dot(ratio, w)) / float(total_3d)
    return float(np.average(np.abs(np.log(ratio[keep] / overall)), weights=w[keep]))


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
