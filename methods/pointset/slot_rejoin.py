"""One loop for one slot: rejoin the pieces the boundary walk split it into.

Where a slot was cut (:mod:`.slot_cuts`) but one K-nearest-neighbour edge across it was
left standing, the lip points beside that edge see a full disc, the walk dies there, and
its hairpin step (:func:`~parambench.methods.pointset.boundary.hairpin_successors`)
crosses the slot. The slot's loop then closes twice, once on each side of the crossing:
``slit``, jittered 100k points, seed 1: loops of 308 and 96 points instead of one of 404,
split 46 spacings from the slot's end; uniform random 300k: 616 and 84 instead of 696.
Each piece crosses the slot once, the two crossings side by side and in opposite
directions, with nothing but the slot between them.

The same happens where nothing was cut: a slot that the K nearest neighbours cross only
here and there (``slit``, jittered 2k, seed 5: 9 edges across it, too few to line up)
comes out of the hairpin walk of
:func:`~parambench.methods.pointset.boundary._hairpin_slot_loops` in pieces of 24 and 12
points, each too short and too coarse to pass as a loop; the slot was lost and ``ocp``'s
map passed its check.

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

__all__ = ["rejoin_split_slots", "JOIN_REACH", "AXIS_CLEARANCE", "MIN_CROSSING"]

#: The two crossing steps' midpoints lie within this many local spacings of each other,
#: and each new step is at most this long (local spacings of the two steps' first points,
#: averaged). The pieces' crossings lay 2.6 (slit, jittered 100k seed 1), 4.6 (300k seed 1)
#: and 5.3-6.0 (2k seed 5, in two poses) spacings apart.
JOIN_REACH = 8.0

#: The slot's middle between the two crossings is at least this many local spacings from
#: every point (a slot 1.3-2 spacings wide leaves 0.65-1 on its axis).
AXIS_CLEARANCE = 0.4

#: Both crossing steps span the slot: each at least this many local spacings long (the
#: slot-cut strips are 1.25 wide; the pieces' crossings measured 1.48-1.91). A ring round a
#: void beside a slot 3 spacings wide (slit, random 2k) met the slot's loop with steps of
#: 1.01 and 1.19 and a clear middle, and was joined to it.
MIN_CROSSING = 1.3

#: The crossing steps run in opposite directions: the cosine of their directions is below this.
_OPPOSED = -0.5


def rejoin_split_slots(points: np.ndarray, normals: np.ndarray, loops: list[np.ndarray],
                       slot_ends: np.ndarray | None, local_spacing: np.ndarray,
                       tree: cKDTree | None = None) -> tuple[list[np.ndarray], int]:
    """Join loops that cross one slot side by side, until no pair is left.

    Parameters
    ----------
    points, normals : (N, 3) numpy.ndarray of float64
    loops : list of (L_i,) numpy.ndarray of int64
        The walk's cycles, each in walking order (the surface on the same side of each).
    slot_ends : (N,) numpy.ndarray of bool or None
        Ends of the kNN edges cut across slots; of two loops joined, one passes one of them
        (a piece of the slot where nothing was cut need not: ``slit``, jittered 20k, seed 2,
        a 32-point piece closed by hairpin steps beside the cut one). None: any two loops,
        for a walk whose loops are all judged as slots afterwards.
    local_spacing : (N,) numpy.ndarray of float64
    tree : scipy.spatial.cKDTree, optional
        Of ``points``, where the caller has one (built here otherwise).

    Returns
    -------
    loops : list of numpy.ndarray of int64
        The loops with each joined pair replaced by one loop (in the first one's place).
    n_joined : int
        Pairs joined.
    """
    loops = list(loops)
    if len(loops) < 2:
        return loops, 0
    tree = cKDTree(points) if tree is None else tree
    n_joined = 0
    while True:
        join = _crossing_pair(points, normals, loops, slot_ends, local_spacing, tree)
        if join is None:
            return loops, n_joined
        ia, i, ib, j = join
        a, b = loops[ia], loops[ib]
        loops[ia] = np.concatenate([a[:i + 1], np.roll(b, -(j + 1)), a[i + 1:]])
        del loops[ib]
        n_joined += 1


def _crossing_pair(points: np.ndarray, normals: np.ndarray, loops: list[np.ndarray], slot_ends: np.ndarray | None,
                   local_spacing: np.ndarray, tree: cKDTree) -> tuple[int, int, int, int] | None:
    """The steps ``loops[ia][i] -> [i+1]`` and ``loops[ib][j] -> [j+1]`` to exchange, as
    ``(ia, i, ib, j)`` with ``ia < ib``, the shortest new steps first; None if no pair passes."""
    owner = np.repeat(np.arange(len(loops)), [c.size for c in loops])
    position = np.concatenate([np.arange(c.size) for c in loops])
    start = np.concatenate(loops)
    end = np.concatenate([np.roll(c, -1) for c in loops])
    on_slot = np.array([slot_ends is None or bool(slot_ends[c].any()) for c in loops])
    mid = 0.5 * (points[start] + points[end])
    direction = unit_vectors(points[end] - points[start])
    reach = JOIN_REACH * local_spacing[start]
    crossing = np.linalg.norm(points[end] - points[start], axis=1) >= MIN_CROSSING * local_spacing[start]
    near = cKDTree(mid).query_ball_point(mid, reach)
    u = np.repeat(np.arange(start.size), [len(js) for js in near])
    v = np.concatenate([np.asarray(js, dtype=np.int64) for js in near])
    keep = ((owner[u] < owner[v]) & crossing[u] & crossing[v] & (on_slot[owner[u]] | on_slot[owner[v]])
            & (np.einsum("ei,ei->e", direction[u], direction[v]) < _OPPOSED))
    u, v = u[keep], v[keep]
    first = np.linalg.norm(points[end[v]] - points[start[u]], axis=1)   # a1 -> b2
    second = np.linalg.norm(points[end[u]] - points[start[v]], axis=1)  # b1 -> a2
    limit = 0.5 * (reach[u] + reach[v])  # the same whichever loop comes first
    ok = (first <= limit) & (second <= limit)
    u, v = u[ok], v[ok]
    for e in np.argsort((first + second)[ok], kind="stable"):
        a, b = u[e], v[e]
        quad = np.array([start[a], end[a], start[b], end[b]])
        spacing = float(local_spacing[start[a]])
        if (np.unique(quad).size == 4 and _axis_clear(mid[a], mid[b], spacing, tree)
                and enclosed_points(points, normals, quad, spacing, tree) == 0):
            return int(owner[a]), int(position[a]), int(owner[b]), int(position[b])
    return None


def _axis_clear(start: np.ndarray, end: np.ndarray, spacing: float, tree: cKDTree) -> bool:
    """Whether the segment between the two crossing steps' midpoints keeps :data:`AXIS_CLEARANCE`
    spacings from every point: it runs along the slot's middle, where a land bridge between two
    holes puts its points (a bridge of three points can lie inside a long thin quadrilateral
    by less than the enclosed-points margin)."""
    n = max(2, int(np.ceil(np.linalg.norm(end - start) / (0.25 * spacing))) + 1)
    probes = start + np.linspace(0.0, 1.0, n)[:, None] * (end - start)
    return bool(tree.query(probes)[0].min() >= AXIS_CLEARANCE * spacing)
