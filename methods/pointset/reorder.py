"""Moving per-point rows between the kd-tree order of the front end's stages and the input order.

The stages work on the points in kd-tree order and :func:`parambench.methods.pointset.frontend.build_frontend`
hands back every array in the caller's order. At a million points the ball arrays are
~1 GB; numpy's fancy indexing copies them on one core and ``np.where`` on renumbered
indices makes three temporaries of the same size. These compiled kernels do each in
one pass over the rows on all cores (copies and integer lookups: the values are the
same).
"""

from __future__ import annotations

import weakref
from pathlib import Path

import numba
import numpy as np
from scipy.spatial import cKDTree

from ..numba_cache import configure_numba_cache

__all__ = ["spatial_order", "take_rows", "renumbered_rows", "insert_sorted"]

# On-disk kernel cache where one is writable, none otherwise (see parambench.methods.numba_cache).
_CACHE, _ = configure_numba_cache(Path(__file__).resolve().parent)


#: The last array ordered (a weak reference) and its order: the front end and the
#: two-level solve order the same point array (0.7 s of kd-tree at 1M points each).
_LAST_ORDER: tuple | None = None


def spatial_order(points: np.ndarray) -> np.ndarray:
    """A permutation putting spatially close points at close indices (kd-tree leaf order).

    Graph searches and sparse products over millions of points touch a point's neighbours
    in memory; in a shuffled order every touch is a cache miss (measured: the DEM stage
    2.4x slower at 100k points; the two-level solve's Galerkin product at 1M points 7.7 s
    against 1.0 s). Working in this order and mapping results back removes that.

    The order of the last array given is kept and returned again for the same array
    object. Any permutation gives the same results (the order only serves memory
    locality), so even an array changed in place in between cannot make a result wrong.

    Parameters
    ----------
    points : (N, d) numpy.ndarray of float64

    Returns
    -------
    (N,) numpy.ndarray of int64, read-only
        ``points[order]`` is the reordered set.
    """
    global _LAST_ORDER
    last = _LAST_ORDER  # one read: another thread may replace it meanwhile
    if last is not None and last[0]() is points and last[1].size == len(points):
        return last[1]
    order = np.asarray(cKDTree(points, leafsize=16).indices, dtype=np.int64)
    order.flags.writeable = False
    try:
        _LAST_ORDER = (weakref.ref(points), order)
    except TypeError:  # not an array (a list of points): nothing to recognise it by
        _LAST_ORDER = None
    return order


def take_rows(a: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """``a[rows]`` for a C-contiguous array of one or more dimensions, copied on all cores.

    Parameters
    ----------
    a : (N, ...) numpy.ndarray
    rows : (M,) numpy.ndarray of int
        Row indices into ``a`` (non-negative).

    Returns
    -------
    (M, ...) numpy.ndarray
        Same dtype as ``a``.
    """
    a = np.ascontiguousarray(a)
    rows = np.ascontiguousarray(rows, dtype=np.int64)
    if rows.size and (rows.min() < 0 or rows.max() >= a.shape[0]):
        raise IndexError(f"row indices must lie in [0, {a.shape[0] - 1}].")
    out = np.empty((rows.size,) + a.shape[1:], dtype=a.dtype)
    width = int(np.prod(a.shape[1:], dtype=np.int64))
    if out.size:
        _take_rows(a.reshape(a.shape[0], width), rows, out.reshape(rows.size, width))
    return out


def renumbered_rows(indices: np.ndarray, rows: np.ndarray, order: np.ndarray) -> np.ndarray:
    """``indices[rows]`` with every entry ``v >= 0`` replaced by ``order[v]`` (-1 padding kept).

    Parameters
    ----------
    indices : (N, B) numpy.ndarray of int64
        Point indices of the reordered set, -1 at padding.
    rows : (M,) numpy.ndarray of int
        Rows to take.
    order : (N,) numpy.ndarray of int64
        Input index of each reordered point.

    Returns
    -------
    (M, B) numpy.ndarray of int64
    """
    indices = np.ascontiguousarray(indices, dtype=np.int64)
    rows = np.ascontiguousarray(rows, dtype=np.int64)
    order = np.ascontiguousarray(order, dtype=np.int64)
    if rows.size and (rows.min() < 0 or rows.max() >= indices.shape[0]):
        raise IndexError(f"row indices must lie in [0, {indices.shape[0] - 1}].")
    out = np.empty((rows.size, indices.shape[1]), dtype=np.int64)
    _renumbered_rows(indices, rows, order, out)
    return out


@numba.njit(cache=_CACHE, nogil=True, parallel=True)
def _take_rows(a, rows, out):
    """``out[r] = a[rows[r]]`` (2-D views)."""
    width = a.shape[1]
    for r in numba.prange(rows.size):
        src = rows[r]
        for c in range(width):
            out[r, c] = a[src, c]


@numba.njit(cache=_CACHE, nogil=True, parallel=True)
def _renumbered_rows(indices, rows, order, out):
    """``out[r, c] = order[indices[rows[r], c]]``, or -1 where that entry is negative."""
    width = indices.shape[1]
    for r in numba.prange(rows.size):
        src = rows[r]
        for c in range(width):
            v = indices[src, c]
            out[r, c] = order[v] if v >= 0 else -1


@numba.njit(cache=_CACHE, nogil=True, inline="always")
def insert_sorted(cols, vals, m, j, v):  # pragma: no cover - compiled
    """Insert column ``j`` with value ``v`` into the first ``m`` entries of a row kept sorted by column.

    ``cols`` and ``vals`` need room for ``m + 1`` entries; equal columns keep their
    insertion order (the CSR builds of the front end reproduce scipy's layouts with it).
    """
    pos = m
    while pos > 0 and cols[pos - 1] > j:
        cols[pos] = cols[pos - 1]
        vals[pos] = vals[pos - 1]
        pos -= 1
    cols[pos] = j
    vals[pos] = v
