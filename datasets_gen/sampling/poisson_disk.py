"""Poisson-disk selection: the greedy maximal independent set of a radius graph, vectorised.

Dart throwing with candidates in random order accepts a candidate when no accepted point
lies within the radius. The same set is the lexicographically-first maximal independent
set of the "closer than r" graph, which Luby-style rounds compute with array operations:
each round accepts every undecided point whose undecided neighbours all come later, then
rejects their neighbours. With randomly ordered candidates a few dozen rounds suffice.

The radius may vary per point (graded samplings): two points conflict when they are closer
than the mean of their radii, a symmetric rule, so the same independent-set rounds apply.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

__all__ = ["poisson_disk_select"]

#: Variable radii are grouped in levels of this ratio; pairs are searched level against level.
LEVEL_RATIO = np.sqrt(2.0)


def poisson_disk_select(points: np.ndarray, radius, n_fixed: int = 0) -> np.ndarray:
    """Greedy Poisson-disk subset in index order, the first ``n_fixed`` points always kept.

    Parameters
    ----------
    points : (n, d) numpy.ndarray of float64
        Candidates; their order is the acceptance order (shuffle them for randomness).
    radius : float or (n,) numpy.ndarray of float64
        Minimum distance between kept points (fixed points are not checked against each
        other). Per-point radii: points i and j conflict when closer than
        ``(radius[i] + radius[j]) / 2``.
    n_fixed : int
        Leading points that are kept unconditionally (e.g. boundary points).

    Returns
    -------
    (n,) numpy.ndarray of bool
        True for kept points. Every rejected point lies within its conflict distance of a kept one.
    """
    n = len(points)
    if np.ndim(radius) == 0:
        pairs = cKDTree(points).query_pairs(float(radius), output_type="ndarray")
    else:
        pairs = _variable_radius_pairs(points, np.asarray(radius, dtype=float))
    pairs = pairs[pairs[:, 1] >= n_fixed]  # pairs of two fixed points do not matter
    return _greedy_independent_set(pairs, n, n_fixed)


def _variable_radius_pairs(points: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """(p, 2) index pairs i < j closer than the mean of their radii.

    A pair query at the largest radius would return ~(r_max / r_min)^2 times too many pairs
    where the radius is small, so points are grouped in levels of radius (ratio
    ``LEVEL_RATIO`` within a level) and each pair of levels is searched at the largest
    conflict distance the two levels can have.
    """
    if len(points) == 0:
        return np.zeros((0, 2), dtype=np.int64)
    level = np.floor(np.log(radius / radius.min()) / np.log(LEVEL_RATIO)).astype(np.int64)
    groups = [np.flatnonzero(level == k) for k in np.unique(level)]
    trees = [cKDTree(points[g]) for g in groups]
    r_top = [float(radius[g].max()) for g in groups]
    out = []
    for a, (ga, ta) in enumerate(zip(groups, trees)):
        for b in range(a, len(groups)):
            reach = 0.5 * (r_top[a] + r_top[b])
            if b == a:
                ij = ta.query_pairs(reach, output_type="ndarray")
                i, j = ga[ij[:, 0]], ga[ij[:, 1]]
                dist = np.linalg.norm(points[i] - points[j], axis=1)
            else:
                found = ta.sparse_distance_matrix(trees[b], reach, output_type="ndarray")
                i, j, dist = ga[found["i"]], groups[b][found["j"]], found["v"]
            close = dist < 0.5 * (radius[i] + radius[j])
            i, j = i[close], j[close]
            out.append(np.column_stack([np.minimum(i, j), np.maximum(i, j)]))
    return np.concatenate(out).astype(np.int64)


def _greedy_independent_set(pairs: np.ndarray, n: int, n_fixed: int) -> np.ndarray:
    """Lexicographically-first maximal independent set of the conflict graph, fixed points kept."""
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
