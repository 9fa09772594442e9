"""The boundary walk's successor choice: per point (greedy) or as a minimum-cost cycle cover.

Every boundary candidate scores the candidates that could follow it on its loop
(:func:`ahead_scores`: ahead of it within 80 degrees of the walking direction, their
outward directions agreeing, ``|c| (1 + 3 (1 - cos a))``). The greedy walk of
:mod:`.boundary` takes each point's best option on its own. Where the boundary comes
close to itself (the mouth of a narrow inlet, a slot reaching the rim, the ragged edge
of a range scan), two points then take the same successor: one of the two chains ends
in the other's cycle and the loop never closes. On pymeshlab's range scan
``rangemaps/face000.ply`` as bare points, 1052 of the outer rim's 1671 candidates walked
into a 94-point inlet that way, and the outer loop was lost.

:func:`cover_successors` chooses all successors at once: a minimum-cost perfect
matching between the candidates as predecessors and as successors (scipy's
``min_weight_full_bipartite_matching``), where a point may also be matched to itself at
``skip_cost`` (it then lies on no loop). Every point gets at most one predecessor, so
the cycles cover the candidates and a chain that cannot close (an interior candidate,
an open scrap of rim) is left out instead of swallowing a loop. Costs are in units of
each point's own scale (its geodesic ball's radius), so sparse and dense regions of a
graded sampling weigh alike.

:func:`parambench.methods.pointset.boundary.find_boundary` covers only the candidates the
greedy walk's loops leave off: covering every candidate found the same loops on face000
but cut the true loop of ``fold`` (random, 2k and 20k points) into small cycles through
its interior candidates (140 of 316 at 2k) and closed ``real/camelhead``'s touching lips
into a loop.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import min_weight_full_bipartite_matching
from scipy.spatial import cKDTree

from .vectors import off_sheet

__all__ = ["ahead_scores", "projected_candidates", "cover_successors", "COS_CONE", "LATERAL_PENALTY", "BRIDGE_K",
           "SKIP_COST"]

#: Successors lie within this angle of the walking direction.
COS_CONE = np.cos(np.deg2rad(80.0))

#: Weight of the angular deviation in the successor score.
LATERAL_PENALTY = 3.0

#: Boundary points examined when looking beyond the geodesic ball.
BRIDGE_K = 16

#: Cost of leaving a candidate off every loop, in units of its ball radius (a step along
#: a boundary costs about 0.4, a bridge over a missed point up to about 2): a cycle is
#: kept when its steps cost less than this on average.
SKIP_COST = 1.0


def ahead_scores(rows: np.ndarray, idx: np.ndarray, c: np.ndarray, candidates: np.ndarray, outward: np.ndarray,
                 bisector: np.ndarray) -> np.ndarray:
    """Score of each option ``idx[i, j]`` as the successor of ``rows[i]``; +inf where it cannot be.

    Parameters
    ----------
    rows : (R,) numpy.ndarray of int64
        The points choosing.
    idx : (R, B) numpy.ndarray of int64
        Their options, -1 padded.
    c : (R, B, 2) numpy.ndarray of float64
        The options' coordinates in each row's tangent frame.
    candidates : (N,) numpy.ndarray of bool
    outward : (N, 3) numpy.ndarray of float64
        Outward gap directions in 3D.
    bisector : (N, 2) numpy.ndarray of float64
        The same in each point's tangent frame.

    Returns
    -------
    (R, B) numpy.ndarray of float64
        ``|c| (1 + LATERAL_PENALTY (1 - cos a))`` for candidates ahead (``cos a > COS_CONE``
        with the walking direction, the bisector turned by +90 degrees) whose outward
        direction agrees with the row's; +inf elsewhere.
    """
    safe = np.where(idx >= 0, idx, 0)
    ahead_dir = np.stack([-bisector[rows, 1], bisector[rows, 0]], axis=1)  # +90 degrees
    dist = np.sqrt(np.einsum("nbi,nbi->nb", c, c))
    with np.errstate(invalid="ignore", divide="ignore"):
        cos_a = np.einsum("nbi,ni->nb", c, ahead_dir) / dist
    agree = np.einsum("nbi,ni->nb", outward[safe], outward[rows]) > 0
    ok = (idx >= 0) & (idx != rows[:, None]) & candidates[safe] & agree & (cos_a > COS_CONE)
    return np.where(ok, dist * (1.0 + LATERAL_PENALTY * (1.0 - cos_a)), np.inf)


def projected_candidates(points: np.ndarray, e1: np.ndarray, e2: np.ndarray, candidates: np.ndarray,
                         rows: np.ndarray, reach: np.ndarray, k: int = BRIDGE_K) -> tuple[np.ndarray, np.ndarray]:
    """The ``k`` nearest candidates of each row within its ``reach`` (3D), in the row's tangent frame.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    e1, e2 : (N, 3) numpy.ndarray of float64
        Tangent frames.
    candidates : (N,) numpy.ndarray of bool
        At least one.
    rows : (R,) numpy.ndarray of int64
    reach : (R,) numpy.ndarray of float64
    k : int

    Returns
    -------
    near : (R, k') numpy.ndarray of int64
        Point indices, -1 beyond reach, or beyond half of it (the geodesic ball's radius
        where ``reach`` is the walk's) and on another sheet (k' = min(k, number of
        candidates); :func:`~parambench.methods.pointset.vectors.off_sheet`: the swiss
        roll's next turn, projected, lay ahead of its outer end).
    c : (R, k', 2) numpy.ndarray of float64
        Their offsets projected on the row's tangent frame.
    """
    cand_idx = np.flatnonzero(candidates)
    k = min(k, cand_idx.size)
    dist, near = cKDTree(points[cand_idx]).query(points[rows], k=k, distance_upper_bound=float(reach.max()))
    dist, near = dist.reshape(rows.size, k), near.reshape(rows.size, k)
    dist = np.where(dist <= reach[:, None], dist, np.inf)
    near = np.where(np.isfinite(dist), cand_idx[np.minimum(near, cand_idx.size - 1)], -1)
    d = points[np.where(near >= 0, near, 0)] - points[rows, None, :]
    # Beyond the geodesic ball (half the reach) a point off the tangent plane is another
    # sheet; within it the neighbourhoods' own rule (``neighbours``) has decided.
    across = off_sheet(d, np.cross(e1[rows], e2[rows])[:, None, :]) & (dist > 0.5 * reach[:, None])
    near = np.where(across, -1, near)
    c = np.stack([np.einsum("nki,ni->nk", d, e1[rows]), np.einsum("nki,ni->nk", d, e2[rows])], axis=-1)
    return near, c


def cover_successors(points: np.ndarray, ball_indices: np.ndarray, coords: np.ndarray, e1: np.ndarray,
                     e2: np.ndarray, candidates: np.ndarray, outward: np.ndarray, bisector: np.ndarray,
                     reach: np.ndarray, scale: np.ndarray, skip_cost: float = SKIP_COST) -> np.ndarray:
    """Successors of the candidates as a minimum-cost cycle cover (see the module docstring).

    Options are the candidates of each point's geodesic ball (scored in its DEM
    coordinates) and those within ``reach`` in 3D (projected on its tangent plane), the
    lower score where both offer the same point.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    ball_indices : (N, B) numpy.ndarray of int64
        -1 padded.
    coords : (N, B, 2) numpy.ndarray of float64
        DEM coordinates of the balls.
    e1, e2 : (N, 3) numpy.ndarray of float64
        Tangent frames of the DEM coordinates.
    candidates : (N,) numpy.ndarray of bool
    outward : (N, 3) numpy.ndarray of float64
    bisector : (N, 2) numpy.ndarray of float64
    reach : (N,) numpy.ndarray of float64
        Longest step beyond the ball, per point.
    scale : (N,) numpy.ndarray of float64
        Positive length per point the costs are measured in.
    skip_cost : float
        Cost of a point on no loop, in units of its ``scale``.

    Returns
    -------
    (N,) numpy.ndarray of int64
        The successor of each candidate on its cycle; -1 for candidates left off every
        cycle and for non-candidates.
    """
    rows = np.flatnonzero(candidates)
    succ = np.full(candidates.shape[0], -1, dtype=np.int64)
    if rows.size < 2:
        return succ
    near, c = projected_candidates(points, e1, e2, candidates, rows, reach[rows])
    idx = np.concatenate([ball_indices[rows], near], axis=1)
    score = np.concatenate([ahead_scores(rows, ball_indices[rows], coords[rows], candidates, outward, bisector),
                            ahead_scores(rows, near, c, candidates, outward, bisector)], axis=1)
    r, j = np.nonzero(np.isfinite(score))
    pos = np.full(candidates.shape[0], -1, dtype=np.int64)
    pos[rows] = np.arange(rows.size)
    col = pos[idx[r, j]]
    # The matching's weights must be positive (a zero reads as no edge); the offset is
    # far below any step's cost.
    cost = score[r, j] / scale[rows[r]] + 1e-9
    own = np.arange(rows.size)
    order = np.lexsort((cost, col, r))  # per (row, column) pair the cheaper offer first
    r, col, cost = r[order], col[order], cost[order]
    first = np.ones(r.size, dtype=bool)
    first[1:] = (r[1:] != r[:-1]) | (col[1:] != col[:-1])
    graph = sp.csr_matrix((np.r_[cost[first], np.full(rows.size, skip_cost)],
                           (np.r_[r[first], own], np.r_[col[first], own])), shape=(rows.size, rows.size))
    match = min_weight_full_bipartite_matching(graph)[1]
    on_loop = match != own
    succ[rows[on_loop]] = rows[match[on_loop]]
    return succ

