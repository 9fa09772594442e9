"""Choice of pinned vertices for two-point methods (LSCM, DNCP)."""

from __future__ import annotations

import numpy as np
from scipy.spatial.distance import cdist

__all__ = ["farthest_pair", "opposite_pairs"]

#: Relative difference under which two distances count as the same (see farthest_pair).
_TIE_RTOL = 1e-9

#: Most tied pairs told apart by :func:`_spread_score` (each costs a pass over all points):
#: an evenly sampled circle ties every diameter, and there candidate order decides.
_MAX_SCORED_TIES = 8


def farthest_pair(points: np.ndarray, candidates: np.ndarray, chunk: int = 2048) -> tuple[int, int]:
    """The two candidate vertices farthest apart in 3D.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    candidates : (B,) numpy.ndarray of int64
        Indices to choose from (usually all boundary vertices), B >= 2.
    chunk : int
        Rows of the distance matrix evaluated at once (bounds memory to chunk * B floats).

    Returns
    -------
    (i, j) : tuple of int
        Indices into ``points``, ``i < j`` by position in ``candidates``. Distances within
        a relative 1e-9 of the largest are ties (a square's two diagonals), so the choice
        does not depend on the last bits of rounding. Ties go to the pair with the smallest
        :func:`_spread_score` (what the points say, not their order: the first pair in
        candidate order was taken, and ``lscm-igl`` on a shuffled copy of a jittered square
        grid gave another map, 2e-3 of its size apart), and where that ties too (an exactly
        symmetric mesh) or more than ``_MAX_SCORED_TIES`` pairs tie (an evenly sampled
        circle) to the first pair in candidate order (row by row).
    """
    cand = np.asarray(candidates, dtype=np.int64)
    pts = points[cand]
    starts = range(0, len(cand), chunk)
    peaks = [float(cdist(pts[start:start + chunk], pts).max()) for start in starts]
    # Symmetric shapes have exact ties that rounding splits differently from one scipy
    # release to the next: distances within rounding of the maximum count as equal. Only
    # the chunks holding one are computed again.
    floor = max(peaks) * (1.0 - _TIE_RTOL)
    tied = []
    for start, peak in zip(starts, peaks):
        if peak >= floor:
            rows, cols = np.nonzero(cdist(pts[start:start + chunk], pts) >= floor)
            keep = start + rows < cols  # each pair once, in candidate order
            tied.append(np.column_stack([start + rows[keep], cols[keep]]))
    pairs = np.concatenate(tied)
    if 1 < len(pairs) <= _MAX_SCORED_TIES:
        score = np.array([_spread_score(points, cand[a], cand[b]) for a, b in pairs])
        pairs = pairs[score <= score.min() * (1.0 + _TIE_RTOL)]
    a, b = pairs[0]
    return int(cand[a]), int(cand[b])


def _spread_score(points: np.ndarray, i: int, j: int) -> float:
    """Sum over all points of the distance to the nearer of ``points[i]``, ``points[j]``.

    Invariant under the order of the points and under rigid motions, and different for the
    diagonals of a square whose inside is not exactly symmetric; a rule on coordinates (the
    pair whose points come first in x) was not: in the centred principal frame the
    corners of a square share their x up to rounding, and a worker process with other
    thread settings took the other diagonal.
    """
    near = np.minimum(np.linalg.norm(points - points[i], axis=1), np.linalg.norm(points - points[j], axis=1))
    return float(np.sort(near).sum())  # sorted: the sum does not depend on the points' order


def opposite_pairs(points: np.ndarray, loop: np.ndarray, start: int, count: int) -> list[tuple[int, int]]:
    """Pairs of loop vertices half the loop's length apart, at evenly shifted places along it.

    The other pin pairs DNCP tries where the farthest pair gives no regular map: well
    separated along the boundary (each pair cuts the loop into two halves of equal
    length), spread around it, and in a fixed order. Pair j (j = 1..count) starts
    ``j / (2 (count + 1))`` of the loop's length after ``start``, so the shifts cover half
    the loop (the other half gives the same pairs swapped) without repeating the pair at
    ``start``.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    loop : (L,) numpy.ndarray of int64
        A boundary loop (usually the outer one), L >= 2.
    start : int
        A vertex of the loop where the shifts start (usually a pin of the farthest pair);
        the loop's first vertex if it is not on the loop.
    count : int
        Pairs wanted.

    Returns
    -------
    list of (int, int)
        At most ``count`` pairs of distinct vertices, in the order of their shifts; pairs
        that repeat an earlier one (short loops) are dropped.
    """
    loop = np.asarray(loop, dtype=np.int64)
    seg = np.linalg.norm(points[np.roll(loop, -1)] - points[loop], axis=1)
    arc = np.concatenate([[0.0], np.cumsum(seg)[:-1]])      # arc length at each loop vertex
    perimeter = float(seg.sum())
    where = np.flatnonzero(loop == start)
    origin = arc[where[0]] if where.size else 0.0

    def nearest(s: float) -> int:
        # circular distance along the loop, so the vertex just before the origin is found too
        d = np.abs((arc - s + 0.5 * perimeter) % perimeter - 0.5 * perimeter)
        return int(loop[int(np.argmin(d))])

    pairs: list[tuple[int, int]] = []
    for j in range(1, count + 1):
        s = origin + j * perimeter / (2.0 * (count + 1))
        a, b = nearest(s % perimeter), nearest((s + 0.5 * perimeter) % perimeter)
        if a != b and (a, b) not in pairs and (b, a) not in pairs:
            pairs.append((a, b))
    return pairs
