"""Graph Laplacian of a row-normalised weight matrix: ``L = I - W`` (paper Eq. 14)."""

from __future__ import annotations

import scipy.sparse as sp

__all__ = ["graph_laplacian"]


def graph_laplacian(weights: sp.spmatrix) -> sp.csr_matrix:
    """``L = I - W`` for weights whose rows sum to 1.

    ``[(I - W) f]_i`` approximates ``k_i / 2`` times the Laplace-Beltrami operator of f
    at point i (Eq. 14); rows of L sum to 0. W is generally non-symmetric, so L is too.

    Parameters
    ----------
    weights : (N, N) scipy.sparse matrix
        No diagonal entries expected (a diagonal is subtracted like any other entry).

    Returns
    -------
    (N, N) scipy.sparse.csr_matrix of float64
        Sorted indices, explicit unit diagonal.
    """
    n = weights.shape[0]
    lap = (sp.identity(n, format="csr") - weights).tocsr()
    lap.sort_indices()
    return lap
