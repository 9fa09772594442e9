"""Orders of the points of a sparse problem: fill-reducing elimination, and cache-friendly storage.

SuperLU (scipy.sparse.linalg.splu) offers only minimum-degree and COLAMD orders. On
surface meshes a geometric nested dissection (split at the median of the widest
coordinate, put the one-sided vertex separator last, recurse) gives less fill and, in
complex arithmetic, several times faster factorisations (measured about 4x at 185k
vertices). It needs vertex positions; without them callers fall back to SuperLU's own
minimum-degree order.

Point clouds come in any order; sparse products, extractions and sweeps over a
Laplacian in that order miss the cache at every neighbour. :func:`leaf_order` (kd-tree
leaves) and :func:`symmetric_permutation` put a problem into an order where neighbours
are close in memory.
"""

from __future__ import annotations

from pathlib import Path

import numba
import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from ..numba_cache import configure_numba_cache
from ..pointset.reorder import insert_sorted

__all__ = ["nested_dissection", "leaf_order", "symmetric_permutation"]

_CACHE, _ = configure_numba_cache(Path(__file__).resolve().parent)


def leaf_order(points: np.ndarray) -> np.ndarray:
    """Kd-tree leaf order of ``points``: a permutation keeping spatial neighbours close in memory.

    Parameters
    ----------
    points : (N, d) numpy.ndarray of float64

    Returns
    -------
    (N,) numpy.ndarray of int64
        ``points[order]`` is the reordered set.
    """
    return np.asarray(cKDTree(points, leafsize=16).indices, dtype=np.int64)


def symmetric_permutation(a: sp.spmatrix, order: np.ndarray) -> sp.csr_matrix:
    """``a[order][:, order]`` as CSR with sorted indices, in one compiled pass on all cores.

    Parameters
    ----------
    a : (N, N) scipy.sparse matrix
    order : (N,) numpy.ndarray of int
        A permutation of the rows.

    Returns
    -------
    (N, N) scipy.sparse.csr_matrix
        Same dtype as ``a``. (scipy's row gather and column renumbering took 3.7 s at a
        million points and 29 nonzeros per row.)
    """
    a = sp.csr_matrix(a)
    order = np.ascontiguousarray(order, dtype=np.int64)
    inverse = np.empty_like(order)
    inverse[order] = np.arange(order.size)
    lengths = np.diff(a.indptr)[order]
    indptr = np.zeros(order.size + 1, dtype=a.indptr.dtype)
    np.cumsum(lengths, out=indptr[1:])
    indices = np.empty_like(a.indices)
    data = np.empty_like(a.data)
    _permute_rows(a.indptr, a.indices, a.data, order, inverse, indptr, indices, data)
    out = sp.csr_matrix((data, indices, indptr), shape=a.shape)
    out.has_sorted_indices = True
    return out


@numba.njit(cache=_CACHE, nogil=True, parallel=True)
def _permute_rows(indptr, indices, data, order, inverse, out_ptr, out_idx, out_val):  # pragma: no cover
    """Row r of the output is row ``order[r]`` of the input, columns renumbered by ``inverse`` and sorted."""
    for r in numba.prange(order.size):
        src = order[r]
        start = out_ptr[r]
        m = 0
        for p in range(indptr[src], indptr[src + 1]):
            insert_sorted(out_idx[start:], out_val[start:], m, inverse[indices[p]], data[p])
            m += 1


def nested_dissection(points: np.ndarray, pattern: sp.spmatrix, leaf_size: int = 64) -> np.ndarray:
    """Geometric nested-dissection permutation.

    Parameters
    ----------
    points : (V, d) numpy.ndarray of float64
        Vertex positions (any dimension); only used to split.
    pattern : (V, V) scipy.sparse matrix
        Its nonzero pattern (symmetrised) is the graph to dissect.
    leaf_size : int
        Parts this small are not split further.

    Returns
    -------
    (V,) numpy.ndarray of int64
        ``perm`` such that ``A[perm][:, perm]`` factorises with little fill.
    """
    n = points.shape[0]
    coo = sp.triu(sp.csr_matrix(pattern) + sp.csr_matrix(pattern).T, k=1).tocoo()
    pieces: list[np.ndarray] = []
    # Explicit stack of (vertex ids, local edge endpoints, emit-only flag); children are
    # pushed so that left, right and then the separator are emitted in that order.
    stack: list[tuple[np.ndarray, np.ndarray, np.ndarray, bool]] = [
        (np.arange(n, dtype=np.int64), coo.row.astype(np.int64), coo.col.astype(np.int64), False)
    ]
    while stack:
        idx, a, b, emit = stack.pop()
        if emit or idx.size <= leaf_size:
            pieces.append(idx)
            continue
        p = points[idx]
        axis = int(np.argmax(p.max(axis=0) - p.min(axis=0)))
        c = p[:, axis]
        left = c < np.median(c)
        if left.all() or not left.any():
            pieces.append(idx)
            continue
        cross = left[a] != left[b]
        sep = np.zeros(idx.size, dtype=bool)
        # One-sided separator: the left endpoints of the edges that cross the cut.
        sep[np.where(left[a[cross]], a[cross], b[cross])] = True
        part_l = left & ~sep
        part_r = ~left
        children = []
        for part in (part_l, part_r):
            local = np.cumsum(part) - 1
            keep = part[a] & part[b]
            children.append((idx[part], local[a[keep]], local[b[keep]], False))
        stack.append((idx[sep], a[:0], b[:0], True))
        stack.append(children[1])
        stack.append(children[0])
    return np.concatenate(pieces)
