"""Triangle orientation in uv: signed areas, majority orientation, flipped and collapsed triangles.

The evaluation's one definition of a foldover: every count, share and picture of flipped
triangles in :mod:`bench` comes from here. The methods keep their own
(:mod:`parambench.methods.geometry2d`), so a bug in theirs cannot hide itself in the scores.
"""

from __future__ import annotations

import numpy as np

__all__ = ["COLLAPSE_REL_TOL", "triangle_signed_areas", "collapsed_mask", "majority_orientation", "flipped_mask",
           "count_foldovers", "count_collapsed", "flipped_share"]

#: A uv triangle whose |area| is below this fraction of the mean |uv area| counts as collapsed.
#: Relative, so the test does not depend on the (arbitrary) scale of uv; 1e-12 in area is
#: 1e-6 in length, far below any real mesh's size variation and far above rounding noise.
COLLAPSE_REL_TOL = 1e-12


def triangle_signed_areas(uv: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Signed area of every uv triangle, positive where its corners run counter-clockwise.

    Parameters
    ----------
    uv : (N, 2) array_like of float64
    faces : (M, 3) array_like of int

    Returns
    -------
    (M,) numpy.ndarray of float64
        In the units of uv squared.
    """
    q = np.asarray(uv, dtype=np.float64)[np.asarray(faces, dtype=np.int64)]
    d1, d2 = q[:, 1] - q[:, 0], q[:, 2] - q[:, 0]
    return 0.5 * (d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0])


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


def flipped_mask(signed_area_uv: np.ndarray, rel_tol: float = COLLAPSE_REL_TOL) -> np.ndarray:
    """Triangles whose uv orientation opposes the majority (see :func:`majority_orientation`).

    A global reflection of uv therefore flips nothing. Collapsed triangles (see
    :func:`collapsed_mask`) are never flipped.

    Parameters
    ----------
    signed_area_uv : (M,) array_like of float64
        From :func:`triangle_signed_areas`.
    rel_tol : float
        See :func:`collapsed_mask`.

    Returns
    -------
    (M,) numpy.ndarray of bool
    """
    a = np.asarray(signed_area_uv, dtype=np.float64)
    return ~collapsed_mask(a, rel_tol) & (np.sign(a) != majority_orientation(a, rel_tol))


def count_foldovers(signed_area_uv: np.ndarray, rel_tol: float = COLLAPSE_REL_TOL) -> int:
    """Number of flipped triangles: :func:`flipped_mask` (same parameters) summed, an int."""
    return int(np.count_nonzero(flipped_mask(signed_area_uv, rel_tol)))


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
