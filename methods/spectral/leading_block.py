"""The leading square block of a CSR matrix, read in place instead of copied.

The fine level of :mod:`.multilevel` solves with the interior block L_II of a Laplacian
of a million rows while the whole Laplacian is held too (the problem's own operator).
A copy of L_II is as large as L itself (315 MiB of the 3 GiB peak at a million points).
With the kept (boundary) rows numbered last, L_II is the leading block: its rows are the
first rows of L, each cut before its first column past the block (CSR rows with sorted
indices keep those at their end). :class:`LeadingBlock` holds L and each row's end;
the two-grid kernels read rows from ``starts`` to ``stops``.
"""

from __future__ import annotations

from pathlib import Path

import numba
import numpy as np
import scipy.sparse as sp

from ..numba_cache import configure_numba_cache
from .ordering import submatrix

__all__ = ["LeadingBlock", "as_leading_block"]

_CACHE, _ = configure_numba_cache(Path(__file__).resolve().parent)


@numba.njit(cache=_CACHE, nogil=True)
def _row_stops(indptr, indices, n):  # pragma: no cover - compiled
    """Per row i < n, the position after its last index below n (indices sorted per row)."""
    stops = np.empty(n, dtype=np.int64)
    for i in range(n):
        lo, p = indptr[i], indptr[i + 1]
        while p > lo and indices[p - 1] >= n:
            p -= 1
        stops[i] = p
    return stops


class LeadingBlock:
    """``matrix[:n, :n]`` of a CSR matrix, without copying its entries.

    Parameters
    ----------
    matrix : (N, M) scipy.sparse.csr_matrix of float64
        Its indices are sorted in place (the matrix it represents is unchanged).
    n : int
        Size of the block, at most ``min(N, M)``.

    Attributes
    ----------
    matrix : scipy.sparse.csr_matrix
        The whole matrix (shared, not copied).
    shape : tuple of int
        ``(n, n)``.
    starts, stops : (n,) numpy.ndarray of int64
        Row i of the block is ``indices[starts[i]:stops[i]]``, ``data[starts[i]:stops[i]]``.
    indices : numpy.ndarray of int32 or int64
    data : numpy.ndarray of float64
        The whole matrix's arrays.
    nnz : int
        Entries in the block.
    """

    def __init__(self, matrix: sp.csr_matrix, n: int) -> None:
        if not sp.issparse(matrix) or matrix.format != "csr":
            raise TypeError(f"a LeadingBlock reads a CSR matrix, got {type(matrix).__name__}.")
        n = int(n)
        if not 0 <= n <= min(matrix.shape):
            raise ValueError(f"the block size must be between 0 and {min(matrix.shape)}, got {n}.")
        matrix.sort_indices()
        self.matrix = matrix
        self.shape = (n, n)
        self.indices, self.data = matrix.indices, matrix.data
        self.starts = np.asarray(matrix.indptr[:n], dtype=np.int64)
        self.stops = _row_stops(matrix.indptr, matrix.indices, n)
        self.nnz = int((self.stops - self.starts).sum())

    def diagonal(self) -> np.ndarray:
        """(n,) numpy.ndarray of float64."""
        return self.matrix.diagonal()[: self.shape[0]]

    def tocsr(self) -> sp.csr_matrix:
        """The block as its own (n, n) CSR matrix with sorted indices (a copy)."""
        rows = np.arange(self.shape[0])
        return submatrix(self.matrix, rows, rows)


def as_leading_block(matrix) -> LeadingBlock:
    """``matrix`` itself if it is a :class:`LeadingBlock`, else a square sparse matrix as the block of all its rows.

    Raises
    ------
    ValueError
        ``matrix`` is not square.
    """
    if isinstance(matrix, LeadingBlock):
        return matrix
    a = sp.csr_matrix(matrix, dtype=np.float64)
    if a.shape[0] != a.shape[1]:
        raise ValueError(f"the matrix must be square, got shape {a.shape}.")
    return LeadingBlock(a, a.shape[0])
