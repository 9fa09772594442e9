"""Fill-reducing elimination order for sparse factorisations of surface Laplacians.

SuperLU (scipy.sparse.linalg.splu) offers only minimum-degree and COLAMD orders. On
surface meshes a geometric nested dissection (split at the median of the widest
coordinate, put the one-sided vertex separator last, recurse) gives less fill and, in
complex arithmetic, several times faster factorisations (measured about 4x at 185k
vertices). It needs vertex positions; without them callers fall back to SuperLU's own
minimum-degree order.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

__all__ = ["nested_dissection"]


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
