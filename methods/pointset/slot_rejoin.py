"""One loop for one slot: rejoin the pieces the boundary walk split it into.

Where a slot was cut (:mod:`.slot_cuts`) but one K-nearest-neighbour edge across it was
left standing, the lip points beside that edge see a full disc, the walk dies there, and
its hairpin step (:func:`~parambench.methods.pointset.boundary.hairpin_successors`)
crosses the slot. The slot's loop then closes twice, once on each side of the crossing:
``slit``, jittered 100k points, seed 1: loops of 308 and 96 points instead of one of 404,
split 46 spacings from the slot's end; uniform random 300k: 616 and 84 instead of 696.
Each piece crosses the slot once, the two crossings side by side and in opposite
directions, with nothing but the slot between them.

Two such loops are joined by exchanging the successors of the two crossing steps (a 2-opt
move): with steps ``a1 -> a2`` of one loop and ``b1 -> b2`` of the other, the joined loop
runs ``... a1 -> b2 ... b1 -> a2 ...``. Two holes either side of a land bridge look the
same but for the bridge: the quadrilateral ``a1 a2 b1 b2`` then holds the bridge's points,
and the loops are left apart; so they are where the slot's middle between the crossings
comes near a point.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from .hole_filling import enclosed_points
from .vectors import unit_vectors

__all__ = ["rejoin_split_slots", "JOIN_REACH", "AXIS_CLEARANCE"]

#: The two crossing steps' midpoints lie within this many local spacings of each other,
#: and each new step is at most this long (in local spacings of its first point).
JOIN_REACH = 6.0

#: The slot's middle between the two crossings is at least this many local spacings from
#: every point (a slot 1.3-2 spacings wide leaves 0.65-1 on its axis).
AXIS_CLEARANCE = 0.4

#: The crossing steps run in opposite directions: the cosine of their directions is below this.
_OPPOSED = -0.5


def rejoin_split_slots(points: np.ndarray, normals: np.ndarray, loops: list[np.ndarray], slot_ends: np.ndarray,
                       local_spacing: np.ndarray) -> tuple[list[np.ndarray], int]:
    """Join loops along a cut slot that cross it side by side, until no pair is left.

    Parameters
    ----------
    points, normals : (N, 3) numpy.ndarray of float64
    loops : list of (L_i,) numpy.ndarray of int64
        The walk's cycles, each in walking order (the surface on the same side of each).
    slot_ends : (N,) numpy.ndarray of bool
        Ends of the kNN edges cut across slots; only loops through one of them are joined.
    local_spacing : (N,) numpy.ndarray of float64

    Returns
    -------
    loops : list of numpy.ndarray of int64
        The loops with each joined pair replaced by one loop (in the first one's place).
    n_joined : int
        Pairs joined.
    """
    loops = list(loops)
    tree = None
    n_joined = 0
    while True:
        on_slot = [i for i, c in enumerate(loops) if slot_ends[c].any()]
        join = None
        for pos, ia in enumerate(on_slot):
            for ib in on_slot[pos + 1:]:
                if tree is None:
                    tree = cKDTree(points)
                join = _crossing_pair(points, normals, loops[ia], loops[ib], local_spacing, tree)
                if join is not None:
                    join = (ia, ib) + join
                    break
            if join is not None:
                break
        if join is None:
            return loops, n_joined
        ia, ib, i, j = join
        a, b = loops[ia], loops[ib]
        loops[ia] = np.concatenate([a[:i + 1], np.roll(b, -(j + 1)), a[i + 1:]])
        del loops[ib]
        n_joined += 1


def _crossing_pair(points: np.ndarray, normals: np.ndarray, a: np.ndarray, b: np.ndarray,
                   local_spacing: np.ndarray, tree: cKDTree) -> tuple[int, int] | None:
    """Positions (i, j) of the steps ``a[i] -> a[i+1]`` and ``b[j] -> b[j+1]`` to exchange, or None."""
    a_next, b_next = np.roll(a, -1), np.roll(b, -1)
    mid_a = 0.5 * (points[a] + points[a_next])
    mid_b = 0.5 * (points[b] + points[b_next])
    dir_a = unit_vectors(points[a_next] - points[a])
    dir_b = unit_vectors(points[b_next] - points[b])
    reach = JOIN_REACH * local_spacing[a]
    near = cKDTree(mid_b).query_ball_point(mid_a, reach)
    best, best_cost = None, np.inf
    for i, js in enumerate(near):
        if not js:
            continue
        js = np.asarray(js, dtype=np.int64)
        js = js[dir_b[js] @ dir_a[i] < _OPPOSED]
        if js.size == 0:
            continue
        first = np.linalg.norm(points[b_next[js]] - points[a[i]], axis=1)   # a1 -> b2
        second = np.linalg.norm(points[a_next[i]] - points[b[js]], axis=1)  # b1 -> a2
        ok = (first <= reach[i]) & (second <= reach[i])
        for j in js[ok][np.argsort((first + second)[ok])]:
            cost = float(np.linalg.norm(points[b_next[j]] - points[a[i]])
                         + np.linalg.norm(points[a_next[i]] - points[b[j]]))
            if cost >= best_cost:
                break
            quad = np.array([a[i], a_next[i], b[j], b_next[j]])
            spacing = float(local_spacing[a[i]])
            if (np.unique(quad).size == 4 and _axis_clear(mid_a[i], mid_b[j], spacing, tree)
                    and enclosed_points(points, normals, quad, spacing, tree) == 0):
                best, best_cost = (i, int(j)), cost
                break
    return best


def _axis_clear(start: np.ndarray, end: np.ndarray, spacing: float, tree: cKDTree) -> bool:
    """Whether the segment between the two crossing steps' midpoints keeps :data:`AXIS_CLEARANCE`
    spacings from every point: it runs along the slot's middle, where a land bridge between two
    holes puts its points (a bridge of three points can lie inside a long thin quadrilateral
    by less than the enclosed-points margin)."""
    n = max(2, int(np.ceil(np.linalg.norm(end - start) / (0.25 * spacing))) + 1)
    probes = start + np.linspace(0.0, 1.0, n)[:, None] * (end - start)
    return bool(tree.query(probes)[0].min() >= AXIS_CLEARANCE * spacing)
