"""Choice of pinned vertices for two-point methods (LSCM, DNCP)."""

from __future__ import annotations

import numpy as np
from scipy.spatial.distance import cdist

__all__ = ["farthest_pair"]


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
        Indices into ``points``, ``i < j`` by position in ``candidates``; ties go to the
        first pair found, so the choice is deterministic.
    """
    cand = np.asarray(candidates, dtype=np.int64)
    pts = points[cand]
    best, best_pair = -1.0, (0, 1)
    for start in range(0, len(cand), chunk):
        d = cdist(pts[start:start + chunk], pts)
        flat = int(np.argmax(d))
        r, c = divmod(flat, d.shape[1])
        if d[r, c] > best:
            best, best_pair = float(d[r, c]), (start + r, c)
    a, b = sorted(best_pair)
    return int(cand[a]), int(cand[b])
