"""Reconstruction weights on geodesic balls: tangent-space W^tan (Eq. 13) and 3D LLE (Eqs. 10-12).

Both solve the regularised LLE system of Eqs. 11-12 per point,

    (C + eps tr(C) I) w = 1,   C_jk = x_j . x_k,   w <- w / sum(w),

where x_j is the j-th ball member relative to the centre: its DEM tangent coordinates
``T_x x_j`` (2D, W^tan) or ``x_j - x`` (3D, LLE). C = X X^T has rank d = 2 or 3, so the
Woodbury identity gives the solution from a d x d system,

    w  proportional to  1 - X (lambda I_d + X^T X)^{-1} X^T 1,   lambda = eps tr(C),

exactly the same weights as the B x B solve for a fraction of the cost (O(B) per point
instead of O(B^3)), each point's d x d system solved by a compiled kernel
(:func:`parambench.methods.pointset.local_fits.lle_rows`). Padding gets weight 0.
:func:`dense_weights` is the literal B x B batched solve (identity rows at the padding),
kept as the reference the tests compare against.

With eps > 0 the weights reproduce a planar neighbourhood only approximately:
``sum_j w_j x_j = lambda (lambda I + X^T X)^{-1} X^T 1 / sum(w)``, which vanishes for
a symmetric ball and is O(eps) otherwise.

The default eps is 1e-2: the paper writes "10e-3" and the authors' code uses
``regtol = 10e-3 = 0.01``; 1e-3 is too weak for the saddle.
"""

from __future__ import annotations

from pathlib import Path

import numba
import numpy as np
import scipy.sparse as sp

from parambench.datasets_gen.errors import InvalidInputError

from ..numba_cache import configure_numba_cache
from .local_fits import lle_rows
from .reorder import insert_sorted
from .row_chunks import for_each_chunk

__all__ = [
    "DEFAULT_REG_EPS",
    "tangent_weights",
    "lle3d_weights",
    "lle_weights",
    "dense_weights",
    "weight_matrix",
    "reconstruction_error",
    "negative_weight_stats",
]

# On-disk kernel cache where one is writable, none otherwise (see parambench.methods.numba_cache).
_CACHE, _ = configure_numba_cache(Path(__file__).resolve().parent)

DEFAULT_REG_EPS = 1e-2

#: Centres per batch (batches run on worker threads, see
#: :mod:`parambench.methods.pointset.row_chunks`; 3D LLE gathers its offsets per batch).
_CHUNK = 65536


def lle_weights(offsets: np.ndarray, mask: np.ndarray, reg_eps: float = DEFAULT_REG_EPS) -> np.ndarray:
    """Regularised, normalised LLE weights of padded neighbourhoods (Woodbury form).

    Parameters
    ----------
    offsets : (N, B, d) numpy.ndarray of float64
        Neighbour positions relative to the centre (tangent coordinates or 3D
        differences); rows at padding are ignored.
    mask : (N, B) numpy.ndarray of bool
        True at real neighbours.
    reg_eps : float
        ``eps`` of Eq. 12; must be > 0.

    Returns
    -------
    (N, B) numpy.ndarray of float64
        Weights summing to 1 per row, 0 at padding.

    Raises
    ------
    InvalidInputError
        ``reg_eps <= 0`` or a neighbourhood whose points all coincide with the centre.
    """
    if not reg_eps > 0:
        raise InvalidInputError(f"reg_eps must be > 0, got {reg_eps}; the paper's value is 1e-2.")
    n, b, d = offsets.shape
    if d > 3:
        raise InvalidInputError(f"LLE offsets must have at most 3 coordinates, got {d}.")
    out = np.empty((n, b))
    x = np.ascontiguousarray(offsets, dtype=np.float64)
    members = np.ascontiguousarray(mask, dtype=np.bool_)

    def solve(sl: slice) -> None:
        bad = lle_rows(x, members, float(reg_eps), sl.start, sl.stop, out)
        if bad >= 0:
            raise InvalidInputError(f"neighbourhood of point {bad} is degenerate (all offsets zero); remove duplicates.")

    # Batches on worker threads (the first degenerate point in row order is reported).
    for_each_chunk(solve, n, _CHUNK)
    return out


def tangent_weights(coords: np.ndarray, mask: np.ndarray, reg_eps: float = DEFAULT_REG_EPS) -> np.ndarray:
    """W^tan (Eq. 13): LLE weights of the DEM tangent coordinates, the centre at the origin.

    Parameters
    ----------
    coords : (N, B, 2) numpy.ndarray of float64
        ``T_x x_j`` per ball member.
    mask : (N, B) numpy.ndarray of bool
    reg_eps : float

    Returns
    -------
    (N, B) numpy.ndarray of float64
        Rows sum to 1; 0 at padding.
    """
    return lle_weights(coords, mask, reg_eps)


def lle3d_weights(points: np.ndarray, ball_indices: np.ndarray, reg_eps: float = DEFAULT_REG_EPS) -> np.ndarray:
    """Classic LLE weights (Eqs. 10-12) in 3D on the same neighbourhoods.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    ball_indices : (N, B) numpy.ndarray of int64
        -1 at padding.
    reg_eps : float

    Returns
    -------
    (N, B) numpy.ndarray of float64
    """
    mask = ball_indices >= 0
    out = np.empty(ball_indices.shape)
    for start in range(0, points.shape[0], _CHUNK):
        stop = min(start + _CHUNK, points.shape[0])
        idx = ball_indices[start:stop]
        offsets = points[np.where(idx >= 0, idx, 0)] - points[start:stop, None, :]
        out[start:stop] = lle_weights(offsets, mask[start:stop], reg_eps)
    return out


def dense_weights(offsets: np.ndarray, mask: np.ndarray, reg_eps: float = DEFAULT_REG_EPS) -> np.ndarray:
    """The same weights by the literal padded B x B batched solve (reference implementation).

    Padding rows and columns of C are replaced by identity rows with right-hand side 0,
    so padding gets weight 0. O(B^3) per point: for tests and small inputs.

    Parameters
    ----------
    offsets : (N, B, d) numpy.ndarray of float64
    mask : (N, B) numpy.ndarray of bool
    reg_eps : float

    Returns
    -------
    (N, B) numpy.ndarray of float64
    """
    m = mask.astype(np.float64)
    x = offsets * m[:, :, None]
    c = np.einsum("nji,nki->njk", x, x)
    tr = np.einsum("njj->n", c)
    b = mask.shape[1]
    c = c + (reg_eps * tr)[:, None, None] * np.eye(b) * m[:, :, None]
    c = c + np.eye(b) * (1.0 - m)[:, :, None]
    w = np.linalg.solve(c, m[:, :, None])[:, :, 0]
    return w / w.sum(axis=1, keepdims=True)


def weight_matrix(ball_indices: np.ndarray, weights: np.ndarray, *,
                  weight_rows: np.ndarray | None = None) -> sp.csr_matrix:
    """Sparse (N, N) weight matrix from padded per-ball weights.

    Built directly in CSR form (rows are already grouped) by compiled kernels on all
    cores: each row's members are sorted by column in place, so no COO pass or sparse
    sort is needed even at millions of points.

    Parameters
    ----------
    ball_indices : (N, B) numpy.ndarray of int64
        -1 at padding; distinct members per row.
    weights : (M, B) numpy.ndarray of float64
    weight_rows : (N,) numpy.ndarray of int, optional
        Row r's weights are ``weights[weight_rows[r]]`` (default: ``weights[r]``), so
        weights kept in another row order need no reordered copy.

    Returns
    -------
    (N, N) scipy.sparse.csr_matrix of float64
        ``W[i, j]`` = weight of member j in i's ball; no diagonal; sorted indices.
        The same arrays as :func:`_weight_matrix_scipy`.
    """
    n = ball_indices.shape[0]
    idx = np.ascontiguousarray(ball_indices, dtype=np.int64)
    w = np.ascontiguousarray(weights, dtype=np.float64)
    rows = (np.arange(n, dtype=np.int64) if weight_rows is None
            else np.ascontiguousarray(weight_rows, dtype=np.int64))
    counts = np.empty(n, dtype=np.int64)
    _member_counts(idx, counts)
    indptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(counts, out=indptr[1:])
    nnz = int(indptr[-1])
    idx_dtype = np.int32 if n < 2**31 - 1 and nnz < 2**31 - 1 else np.int64
    indices = np.empty(nnz, dtype=idx_dtype)
    data = np.empty(nnz)
    _sorted_members(idx, w, rows, indptr, indices, data)
    mat = sp.csr_matrix((data, indices, indptr.astype(idx_dtype)), shape=(n, n))
    mat.has_sorted_indices = True  # each row written in column order by _sorted_members
    return mat


def _weight_matrix_scipy(ball_indices: np.ndarray, weights: np.ndarray) -> sp.csr_matrix:
    """:func:`weight_matrix` by boolean gathers and scipy's sort (the reference of its tests)."""
    n = ball_indices.shape[0]
    mask = ball_indices >= 0
    counts = mask.sum(axis=1)
    indptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(counts, out=indptr[1:])
    idx_dtype = np.int32 if n < 2**31 - 1 and indptr[-1] < 2**31 - 1 else np.int64
    w = sp.csr_matrix((weights[mask], ball_indices[mask].astype(idx_dtype), indptr.astype(idx_dtype)),
                      shape=(n, n))
    w.sort_indices()
    return w


@numba.njit(cache=_CACHE, nogil=True, parallel=True)
def _member_counts(ball_indices, counts):
    """Real members (index >= 0) per row."""
    n, b = ball_indices.shape
    for r in numba.prange(n):
        m = 0
        for c in range(b):
            if ball_indices[r, c] >= 0:
                m += 1
        counts[r] = m


#: Chunks of rows :func:`_sorted_members` shares out (each allocates its scratch once).
_ROW_CHUNKS = 256


@numba.njit(cache=_CACHE, nogil=True, parallel=True)
def _sorted_members(ball_indices, weights, weight_rows, indptr, indices, data):
    """CSR rows: row r's members (``ball_indices[r]``) in column order with ``weights[weight_rows[r]]``.

    Insertion sort per row (a few dozen members); members are distinct, so the order is
    the one scipy's ``sort_indices`` gives.
    """
    n, b = ball_indices.shape
    n_chunks = min(n, _ROW_CHUNKS)
    for ch in numba.prange(n_chunks):
        cols = np.empty(b, dtype=np.int64)
        vals = np.empty(b)
        for r in range(ch * n // n_chunks, (ch + 1) * n // n_chunks):
            src = weight_rows[r]
            m = 0
            for c in range(b):
                j = ball_indices[r, c]
                if j < 0:
                    continue
                insert_sorted(cols, vals, m, j, weights[src, c])
                m += 1
            at = indptr[r]
            for t in range(m):
                indices[at + t] = cols[t]
                data[at + t] = vals[t]


def reconstruction_error(offsets: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """``R_x = |x - sum_j w_j x_j|^2`` per point (Eq. 10), with weights summing to 1.

    Parameters
    ----------
    offsets : (N, B, d) numpy.ndarray of float64
        Neighbours relative to the centre: tangent coordinates (R_x measured in the
        tangent plane, for W^tan) or 3D differences (for 3D LLE). Padding must carry
        weight 0.
    weights : (N, B) numpy.ndarray of float64

    Returns
    -------
    (N,) numpy.ndarray of float64
    """
    out = np.empty(weights.shape[0])

    def error(sl: slice) -> None:
        r = np.einsum("nb,nbi->ni", weights[sl], offsets[sl])
        out[sl] = np.einsum("ni,ni->n", r, r)

    # Batches on worker threads; each row's einsum is the same as on all rows at once.
    for_each_chunk(error, weights.shape[0], _CHUNK)
    return out


def negative_weight_stats(weights: np.ndarray, mask: np.ndarray, boundary_mask: np.ndarray, *,
                          bins: int = 40) -> dict:
    """Negative-weight statistics at interior and boundary points (paper Fig. 5).

    Parameters
    ----------
    weights : (N, B) numpy.ndarray of float64
    mask : (N, B) numpy.ndarray of bool
        Real entries.
    boundary_mask : (N,) numpy.ndarray of bool
    bins : int
        Histogram bins over the range of all weights.

    Returns
    -------
    dict
        ``negative_fraction``: {"interior", "boundary"} fraction of weights < 0;
        ``points_with_negative``: {"interior", "boundary"} fraction of points having any;
        ``min_weight``: {"interior", "boundary"};
        ``histogram``: {"edges": list, "interior": counts, "boundary": counts}.
        JSON-serialisable; NaN-free (empty groups report 0).

    Notes
    -----
    Two passes over batches of rows on worker threads (range and counts, then the
    histograms over the common range), instead of copying each group's weights whole
    (~1 GB of temporaries at a million points). Counts, minima and maxima do not depend
    on the batching, and neither does a value's histogram bin (numpy's uniform-bin rule
    uses the range only), so the result equals :func:`_negative_weight_stats_whole`'s.
    """
    n = weights.shape[0]
    n_chunks = -(-n // _CHUNK)
    groups = (("interior", ~boundary_mask), ("boundary", boundary_mask))
    # Per batch: range of all real weights; per group: real weights, negative ones, rows,
    # rows with a negative weight, smallest weight (NaN-propagating, as ndarray.min).
    ranges = np.full((n_chunks, 2), np.nan)
    counts = np.zeros((2, n_chunks, 4), dtype=np.int64)
    minima = np.full((2, n_chunks), np.nan)

    def tally(sl: slice) -> None:
        c = sl.start // _CHUNK
        w, m = weights[sl], mask[sl]
        real = w[m]
        if real.size:
            ranges[c] = real.min(), real.max()
        for g, (_, rows) in enumerate(groups):
            sub_w, sub_m = w[rows[sl]], m[rows[sl]]
            vals = sub_w[sub_m]
            neg = (sub_w < 0) & sub_m
            counts[g, c] = vals.size, neg.sum(), sub_w.shape[0], neg.any(axis=1).sum()
            if vals.size:
                minima[g, c] = vals.min()

    for_each_chunk(tally, n, _CHUNK)
    some = counts[:, :, 0].sum(axis=0) > 0  # batches with real weights
    lo, hi = ((float(ranges[some, 0].min()), float(ranges[some, 1].max())) if some.any() else (0.0, 1.0))
    if hi <= lo:
        hi = lo + 1.0
    edges = np.histogram_bin_edges([], bins=bins, range=(lo, hi))
    hist = np.zeros((2, n_chunks, int(bins)), dtype=np.int64)

    def histogram(sl: slice) -> None:
        c = sl.start // _CHUNK
        w, m = weights[sl], mask[sl]
        for g, (_, rows) in enumerate(groups):
            # An int bin count with a range takes numpy's fast path for uniform bins.
            hist[g, c] = np.histogram(w[rows[sl]][m[rows[sl]]], bins=bins, range=(lo, hi))[0]

    for_each_chunk(histogram, n, _CHUNK)
    out: dict = {"negative_fraction": {}, "points_with_negative": {}, "min_weight": {},
                 "histogram": {"edges": edges.tolist()}}
    for g, (key, _) in enumerate(groups):
        n_vals, n_neg, n_rows, n_rows_neg = (int(v) for v in counts[g].sum(axis=0))
        has = counts[g, :, 0] > 0
        out["negative_fraction"][key] = float(np.int64(n_neg) / n_vals) if n_vals else 0.0
        out["points_with_negative"][key] = float(np.float64(n_rows_neg) / n_rows) if n_rows else 0.0
        out["min_weight"][key] = float(minima[g, has].min()) if n_vals else 0.0
        out["histogram"][key] = hist[g].sum(axis=0).tolist()
    return out


def _negative_weight_stats_whole(weights: np.ndarray, mask: np.ndarray, boundary_mask: np.ndarray, *,
                                 bins: int = 40) -> dict:
    """:func:`negative_weight_stats` on whole arrays (the reference of its tests)."""
    finite = weights[mask]
    lo, hi = (float(finite.min()), float(finite.max())) if finite.size else (0.0, 1.0)
    if hi <= lo:
        hi = lo + 1.0
    edges = np.histogram_bin_edges([], bins=bins, range=(lo, hi))
    out: dict = {"negative_fraction": {}, "points_with_negative": {}, "min_weight": {},
                 "histogram": {"edges": edges.tolist()}}
    for key, rows in (("interior", ~boundary_mask), ("boundary", boundary_mask)):
        sub_w = weights[rows]
        sub_m = mask[rows]
        vals = sub_w[sub_m]
        neg = (sub_w < 0) & sub_m
        out["negative_fraction"][key] = float(neg.sum() / vals.size) if vals.size else 0.0
        out["points_with_negative"][key] = float(neg.any(axis=1).mean()) if sub_w.shape[0] else 0.0
        out["min_weight"][key] = float(vals.min()) if vals.size else 0.0
        # An int bin count with a range takes numpy's fast path for uniform bins.
        out["histogram"][key] = np.histogram(vals, bins=bins, range=(lo, hi))[0].tolist()
    return out
