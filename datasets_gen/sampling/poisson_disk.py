"""Poisson-disk selection: the greedy maximal independent set of a radius graph, vectorised.

Dart throwing with candidates in random order accepts a candidate when no accepted point
lies within the radius. The same set is the lexicographically-first maximal independent
set of the "closer than r" graph, which Luby-style rounds compute with array operations:
each round accepts every undecided point whose undecided neighbours all come later, then
rejects their neighbours. With randomly ordered candidates a few dozen rounds suffice.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

__all__ = ["poisson_disk_select"]


def poisson_disk_select(points: np.ndarray, radius: float, n_fixed: int = 0) -> np.ndarray:
    """Greedy Poisson-disk subset in index order, the first ``n_fixed`` points always kept.

    Parameters
    ----------
    points : (n, d) numpy.ndarray of float64
        Candidates; their order is the acceptance order (shuffle them for randomness).
    radius : float
        Minimum distance between kept points (fixed points are not checked against each other).
    n_fixed : int
        Leading points that are kept unconditionally (e.g. boundary points).

    Returns
    -------
    (n,) numpy.ndarray of bool
        True for kept points. Every rejected point lies within ``radius`` of a kept one.
    """
    n = len(points)
    pairs = cKDTree(points).query_pairs(radius, output_type="ndarray")
    pairs = pairs[pairs[:, 1] >= n_fixed]  # pairs of two fixed points do not matter
    state = np.zeros(n, dtype=np.int8)  # 0 undecided, 1 kept, 2 rejected
    state[:n_fixed] = 1
    while True:
        a, b = pairs[:, 0], pairs[:, 1]
        kept = state == 1
        reject = np.zeros(n, dtype=bool)
        reject[b[kept[a]]] = True
        reject[a[kept[b]]] = True
        state[reject & (state == 0)] = 2
        undecided = state == 0
        if not undecided.any():
            return state == 1
        pairs = pairs[undecided[a] & undecided[b]]
        later = np.zeros(n, dtype=bool)
        later[pairs[:, 1]] = True  # has an undecided neighbour with a smaller index
        state[undecided & ~later] = 1
