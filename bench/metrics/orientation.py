"""Triangle orientation in uv: majority orientation, flipped and collapsed triangles."""

from __future__ import annotations

import numpy as np

__all__ = ["COLLAPSE_REL_TOL", "collapsed_mask", "majority_orientation", "count_foldovers", "count_collapsed",
           "flipped_share"]

#: A uv triangle whose |area| is below this fraction of the mean |uv area| counts as collapsed.
#: Relative, so the test does not depend on the (arbitrary) scale of uv; 1e-12 in area is
#: 1e-6 in length, far below any real mesh's size variation and far above rounding noise.
COLLAPSE_REL_TOL = 1e-12


def collapsed_mask(signed_area_uv: np.ndarray, rel_tol: float = COLLAPSE_REL_TOL) -> np.ndarray:
    """Triangles whose uv image has (numerically) zero area.

    Parameters
    ----------
    signed_area_uv : (M,) array_like of float64
    rel_tol : float
        Threshold as a fraction of the mean absolute uv area.

    Returns
    -------
    (M,) numpy.ndarray of bool
    """
    a = np.abs(np.asarray(signed_area_uv, dtype=np.float64))
    tol = rel_tol * a.mean() if a.size else 0.0
    return a <= tol


def majority_orientation(signed_area_uv: np.ndarray, rel_tol: float = COLLAPSE_REL_TOL) -> int:
    """+1 if at least as many non-collapsed triangles are positive as negative, else -1.

    Parameters
    ----------
    signed_area_uv : (M,) array_like of float64
    rel_tol : float
        See :func:`collapsed_mask`.

    Returns
    -------
    int
    """
    a = np.asarray(signed_area_uv, dtype=np.float64)
    live = ~collapsed_mask(a, rel_tol)
    pos = int(np.count_nonzero(a[live] > 0))
    return 1 if 2 * pos >= int(live.sum()) else -1


def count_foldovers(signed_area_uv: np.ndarray, rel_tol: float = COLLAPSE_REL_TOL) -> int:
    """Triangles whose uv orientation opposes the majority (by count).

    A global reflection of uv therefore gives 0. Collapsed triangles (see
    :func:`count_collapsed`) are neither in the majority nor counted here.

    Parameters
    ----------
    signed_area_uv : (M,) array_like of float64
        From :func:`jacobian_singular_values`.
    rel_tol : float
        See :func:`collapsed_mask`.

    Returns
    -------
    int
    """
    a = np.asarray(signed_area_uv, dtype=np.float64)
    live = ~collapsed_mask(a, rel_tol)
    pos = int(np.count_nonzero(a[live] > 0))
    return min(pos, int(live.sum()) - pos)


def count_collapsed(signed_area_uv: np.ndarray, rel_tol: float = COLLAPSE_REL_TOL) -> int:
    """Triangles with (numerically) zero uv area; see :func:`collapsed_mask`.

    Returns
    -------
    int
    """
    return int(np.count_nonzero(collapsed_mask(signed_area_uv, rel_tol)))


def flipped_share(signed_area_uv: np.ndarray, rel_tol: float = COLLAPSE_REL_TOL) -> float:
    """``min(p, 1 - p)`` with ``p`` the share of non-collapsed triangles with negative uv area.

    The share of triangles in the minority orientation, so a global mirror image of the map
    gives the same value. Collapsed triangles (see :func:`collapsed_mask`) are left out of
    both the count and the total.

    Parameters
    ----------
    signed_area_uv : (M,) array_like of float64
    rel_tol : float
        See :func:`collapsed_mask`.

    Returns
    -------
    float
        In [0, 0.5]; NaN when every triangle collapsed.
    """
    a = np.asarray(signed_area_uv, dtype=np.float64)
    live = ~collapsed_mask(a, rel_tol)
    n_live = int(live.sum())
    if n_live == 0:
        return float("nan")
    p = np.count_nonzero(a[live] < 0) / n_live
    return float(min(p, 1.0 - p))
