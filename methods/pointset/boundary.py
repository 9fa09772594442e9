"""Boundary points by the angle criterion, ordered into oriented loops (paper Sec. 4.1).

Detection: a point is on the boundary when the largest angular gap between the spokes
to its geodesic-ball members, in its DEM tangent plane, exceeds a threshold (120 degrees
by default; interior points of a reasonable sampling have gaps well under 90 degrees,
points on a straight boundary have 180). The whole geodesic ball is used, not only the
K nearest, so a locally sparse interior does not look like a boundary.

Ordering: at a boundary point the bisector g of the gap points out of the surface; the
loop direction is g turned by +90 degrees in the tangent plane (seen from the normal's
side), which keeps the surface on the left. Each boundary point's successor is the
nearest other boundary point of its ball lying ahead (positive component along that
direction). Loops are the cycles of this successor map. Walking with the surface on the
left makes the outer loop counter-clockwise and holes clockwise seen from the normals'
side, the convention of :class:`parambench.datasets_gen.surface.Surface`.

Fake loops: cycles with fewer than ``min_loop_size`` points (default 8) are dropped as
isolated gaps in the sampling, and so are cycles shorter (3D perimeter) than two ball
radii of their points, the rim of a locally much denser patch (seen on the camelhead
scan), and, given the local spacing, loops of fewer than 32 points that ring a void of
an irregular sampling (spaced along themselves wider than the sampling, or with an empty
disk inside narrower than 1.9 of their own steps: :func:`empty_radius_inside`);
boundary points on no kept cycle are dropped too (all counted in the diagnostics). Where the walk finds no boundary point ahead inside the ball (a notch the
angle criterion missed) it looks among boundary points up to two ball radii away (its own
ball's or the typical one's, whichever is larger). Candidates the walk's loops leave off
(where the boundary comes close to itself, two points take the same successor and a
chain runs into a small cycle) are chained again all at once, as a minimum-cost cycle
cover (:mod:`.boundary_cover`, :func:`_cover_loops`). Boundary points the walk stepped over
(where two sides nearly touch, and the notches of a rim cut across a mesh's triangles)
are put back (:mod:`.boundary_putback`). Last, loops that cross themselves within a few
steps in the tangent plane (a curl through points closer together than the sampling,
common on random samplings of real surfaces) are untangled (:mod:`.loop_untangle`). Loops are
returned longest (3D perimeter) first, so the outer boundary of a surface with holes
comes first.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numba
import numpy as np
from scipy.spatial import cKDTree

from parambench.datasets_gen.errors import InvalidInputError, NoBoundaryError

from ..geometry2d import signed_area_2d
from ..numba_cache import configure_numba_cache
from .boundary_putback import put_back_rounds
from .boundary_cover import BRIDGE_K, ahead_scores, cover_successors, projected_candidates
from .normals import tangent_frames
from .row_chunks import for_each_chunk
from .hole_filling import enclosed_points, is_slot
from .loop_untangle import untangle_loops
from .loop_wrap import wrap_outside_points
from .slot_rejoin import rejoin_split_slots
from .slot_tips import put_back_slot_tips
from .vectors import unit_vectors

__all__ = [
    "LOWER_ANGLES_DEG",
    "BoundaryLoops",
    "angular_gaps",
    "successors",
    "bridge_successors",
    "cycles",
    "empty_radius_inside",
    "is_outer_rim",
    "find_boundary",
    "no_boundary_error",
    "DEFAULT_MIN_LOOP_SIZE",
]

# On-disk kernel cache where one is writable, none otherwise (see parambench.methods.numba_cache).
_CACHE, _ = configure_numba_cache(Path(__file__).resolve().parent)

DEFAULT_MIN_LOOP_SIZE = 8

#: Angles the front end's boundary stage tries, in order, when its loops leave boundary
#: candidates that ring a missed hole (:func:`parambench.methods.pointset.frontend.boundary_stage`);
#: a point-set method's retries after a map whose check finds the same use them too. A
#: hole of a LiDAR tile's ground returns (``real/lidar-ground``, 8 spacings across): 14
#: of its 16 rim points pass 120 degrees and no loop closes, at 100 it is a loop. Holes
#: 5.4 grid steps across in flat jittered grids: 100 finds some, 90 the others.
LOWER_ANGLES_DEG = (100.0, 90.0)

#: Balls per batch of :func:`angular_gaps` (batches run on worker threads).
_GAP_CHUNK = 32768

#: A loop shorter than this many ball radii of its points (or of the typical ball, when
#: balls follow the local spacing and are small in a dense patch) cannot enclose a hole
#: the balls could see: it is the rim of a locally denser patch, not a boundary.
_MIN_PERIMETER_BALLS = 2.0

#: A loop whose points are spaced along it more than this many local spacings apart
#: is the ring of points around a void of an irregular (random) sampling, not a
#: boundary: a boundary curve is sampled along itself at least as densely as the
#: surface around it. Measured at 2k-100k random samplings of the generated surfaces:
#: rings of voids 1.3-2.7, true loops (holes included) 0.6-0.9, real meshes 0.6-0.8.
_MAX_LOOP_SPACING = 1.25

#: Rings around voids are short: random samplings of 2k-100k points gave 8-16 points.
#: Longer loops are kept whatever their spacing (the boundary of an adaptively sampled
#: cap is spaced 1.34 local spacings apart along itself: its interior neighbours are
#: denser than the boundary curve).
_MAX_VOID_RING = 32

#: A loop of fewer than ``_MAX_VOID_RING`` points is kept only when the largest empty disk
#: inside it has a radius of at least this many of the loop's own mean steps: a hole is
#: much wider than its boundary's sampling, the ring around a void of an irregular
#: sampling is not (its points are about as far apart as the void is wide). Measured
#: (radius over mean step): small true holes 2.16-5.0 (holes, holes-bumped at 2k points,
#: random, graded and jittered with noise; bunny10k's two wide holes 2.4); void rings of
#: random samplings at 20k points 0.41-1.71, among them two on ``slit`` spaced 1.0 and
#: 1.22 local spacings along themselves, which the spacing rule kept.
_MIN_EMPTY_STEPS = 1.9

#: Holes narrower than the balls: a rim point of a hole whose radius is below its ball's
#: sees the rim beyond across the hole, and its gap stays under the angle (a plane with a
#: hole 4.6 spacings across: 12 rim points, none a candidate; 100 holes 6 spacings across
#: at 10k points: 16 missed, the map passed 2.5e-2 off). The angle criterion is taken
#: again on the members within this share of each ball's radius ...
SMALL_HOLE_SHARE = 0.5
#: ... where at most this share of the points pass it (and are no candidates): a regular
#: sampling (jittered 3.9-4.5 %; jittered planes and bumps with 36 or 100 small holes
#: 7.4-8.3 %, their rims included), not an irregular one, whose voids fill the small
#: balls' gaps (graded 11-15.6 %: at 0.25 a void ring of ``protrusions`` graded 2k became a
#: loop; uniform random 65-72 %).
MAX_SMALL_GAP_SHARE = 0.10
#: ... and the loops kept are those of fewer than ``_MAX_VOID_RING`` points around an empty
#: disk at most this many ball radii wide (the rest the balls see).
_MAX_SMALL_HOLE_BALLS = 1.25
#: On irregular samplings (more points pass than that share) only the points near a void
#: are kept: one whose empty disk touching it on its gap's side is at least this many local
#: spacings in radius. Measured (the disk along the half-ball gap's bisector, plane with one
#: hole, 2k and 20k points, seeds 0-1): points away from the rims of random samplings at
#: most 2.1, of graded ones at most 2.4; rims of holes 6 spacings across 2.1-3.5 in the
#: median, 4 spacings across 1.0-2.3 (these a random sampling cannot tell from its voids).
VOID_RADIUS = 2.2
#: ... and the loops kept there enclose an empty disk of at least this many of their own mean
#: steps (``_MIN_EMPTY_STEPS`` elsewhere).
VOID_EMPTY_STEPS = 2.5
#: The pass runs below this many points: it cost 2.0 s of ``holes`` graded at 200k points
#: (the boundary stage 1.9 -> 3.9 s), which at a million would take a sixth of the minute
#: issue #14 allows. Above it a hole narrower than the balls is about 5 spacings of a
#: million-point scan.
SMALL_HOLE_MAX_POINTS = 200_000

#: An outer rim found by the cycle cover (:func:`is_outer_rim`): this share of its points''
#: outward directions leave its polygon, ...
_RIM_FACING = 0.9
#: ... and probes this many mean steps out along them lie, in the median, ...
_RIM_PROBE = 1.5
#: ... at least this share of that distance from every point.
_RIM_EMPTY = 0.8

#: No loop closed and more than this share of the points are candidates: too few points
#: to have an inside (:func:`no_boundary_error`).
_MOSTLY_BOUNDARY = 0.4

#: Grid (per side) on which the empty disk inside a small loop is searched.
_EMPTY_GRID = 32
#: Above this many loops :func:`empty_radii_inside` builds one kd-tree of all the points instead of
#: scanning them once per loop (a scan of 1M points took 1/14 of the time of building the tree).
_LOOPS_PER_TREE = 16

#: Angle criterion of the points on a slot's lips (see :func:`find_boundary`).
_LIP_ANGLE_DEG = 60.0

#: A dead end's hairpin step (:func:`hairpin_successors`) reaches this many bridge reaches ...
_HAIRPIN_REACH = 1.5
#: ... to a candidate whose outward direction has a cosine below minus this with its own.
_HAIRPIN_FACING = 0.5
#: ... lying on its open side: the step's cosine with its outward direction at least minus
#: this. An end cap's point's gap bisector leans along the slot (slit, graded 2k seed 1: the
#: facing lip's chain start lay at 91 degrees, and the slot's loop did not close).
_HAIRPIN_BEHIND = 0.25

#: Rounds of "drop points on too-small cycles, walk again".
_MAX_PRUNE_ROUNDS = 20

@dataclass(frozen=True, eq=False)
class BoundaryLoops:
    """Boundary points in oriented loops.

    Attributes
    ----------
    loops : list of (L_i,) numpy.ndarray of int64
        Loops in walking order, longest first; outer counter-clockwise, holes clockwise
        seen from the normals' side; decimated if asked.
    mask : (N,) numpy.ndarray of bool
        True at the points of ``loops``.
    candidates : (N,) numpy.ndarray of bool
        Every point passing the angle criterion (before loop extraction and decimation).
    max_gap : (N,) numpy.ndarray of float64
        Largest angular gap per point, radians.
    diagnostics : dict
        ``n_candidates``, ``n_in_loops``, ``n_dropped_points`` (candidates on no cycle),
        ``n_dropped_loops`` (too small), ``loop_sizes`` (before decimation),
        ``n_put_back`` (points the walk stepped over, put back on their loop; see
        :func:`~.boundary_putback.put_back_passed_over`; counted in ``n_in_loops`` and ``loop_sizes``),
        ``n_hairpin_slots`` (slot and hole loops of the second walk), ``n_cover_loops`` (loops of
        the cycle cover of the candidates the walk left off, :func:`_cover_loops`),
        ``n_untangled`` (2-opt moves that undid a loop's local self-crossings,
        :func:`parambench.methods.pointset.loop_untangle.untangle_loops`).
    """

    loops: list
    mask: np.ndarray
    candidates: np.ndarray
    max_gap: np.ndarray
    diagnostics: dict


def angular_gaps(coords: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Largest angular gap between ball spokes, and its bisector, per point.

    Parameters
    ----------
    coords : (N, B, 2) numpy.ndarray of float64
        Tangent coordinates of ball members.
    mask : (N, B) numpy.ndarray of bool
        Real members (at least one per row).

    Returns
    -------
    gap : (N,) numpy.ndarray of float64
        Radians in (0, 2 pi].
    bisector : (N, 2) numpy.ndarray of float64
        Unit vector in the tangent frame pointing into the middle of the gap (out of the
        surface at a boundary point).

    Notes
    -----
    In batches of balls on worker threads: numpy's ``arctan2`` gives the spoke angles,
    a compiled kernel sorts each row's members and finds the gap (the arithmetic of
    :func:`_angular_gaps_numpy`, which sorted the whole padded (N, B) array; equal
    angles of opposite zero sign are the only values whose order may differ, and they
    cannot change a gap), numpy's ``cos``/``sin`` give the bisector.
    """
    n, b = mask.shape
    if b == 0:
        return _angular_gaps_numpy(coords, mask)
    gap = np.empty(n)
    mid = np.empty(n)
    mask = np.ascontiguousarray(mask)

    def batch(sl: slice) -> None:
        # arctan2 stays numpy's (its float64 loop is SIMD on this hardware: a compiled
        # libm atan2 need not give the same last bit).
        ang = np.arctan2(coords[sl, :, 1], coords[sl, :, 0])
        _largest_gaps(ang, mask[sl], gap[sl], mid[sl])

    for_each_chunk(batch, n, _GAP_CHUNK)
    return gap, np.stack([np.cos(mid), np.sin(mid)], axis=1)


def _ball_radii(coords: np.ndarray) -> np.ndarray:
    """Largest tangent-coordinate length per ball (0 at padding), in batches on worker threads."""
    out = np.empty(coords.shape[0])

    def radii(sl: slice) -> None:
        c = coords[sl]
        out[sl] = np.sqrt(np.einsum("nbi,nbi->nb", c, c)).max(axis=1)

    for_each_chunk(radii, coords.shape[0], _GAP_CHUNK)
    return out


def _angular_gaps_numpy(coords: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`angular_gaps` on whole padded arrays in numpy (the reference of the kernel's tests)."""
    n, b = mask.shape
    ang = np.where(mask, np.arctan2(coords[..., 1], coords[..., 0]), np.inf)
    ang.sort(axis=1)
    size = mask.sum(axis=1)
    rows = np.arange(n)
    first = ang[:, 0]
    last = ang[rows, size - 1]
    wrap = first + 2.0 * np.pi - last
    if b > 1:
        with np.errstate(invalid="ignore"):
            diffs = np.diff(ang, axis=1)
        diffs = np.where(np.arange(b - 1)[None, :] < (size - 1)[:, None], diffs, -np.inf)
        j = np.argmax(diffs, axis=1)
        inner = diffs[rows, j]
    else:
        j = np.zeros(n, dtype=np.int64)
        inner = np.full(n, -np.inf)
    use_wrap = wrap >= inner
    gap = np.where(use_wrap, wrap, inner)
    mid = np.where(use_wrap, last + 0.5 * wrap, ang[rows, j] + 0.5 * np.where(use_wrap, 0.0, inner))
    return gap, np.stack([np.cos(mid), np.sin(mid)], axis=1)


@numba.njit(cache=_CACHE, nogil=True)
def _largest_gaps(ang, mask, gap, mid):
    """Per row: the largest gap between the sorted angles of the members (wrapping round), and its middle angle.

    Ties go to the wrap-around gap, then to the first inner gap (``argmax``'s rule). A
    row without members gets ``-inf`` and NaN, as the numpy expressions gave.
    """
    n, b = ang.shape
    a = np.empty(b)
    for r in range(n):
        m = 0
        for c in range(b):  # the members' angles, insertion-sorted (B is at most a few dozen)
            if not mask[r, c]:
                continue
            x = ang[r, c]
            pos = m
            while pos > 0 and a[pos - 1] > x:
                a[pos] = a[pos - 1]
                pos -= 1
            a[pos] = x
            m += 1
        if m == 0:
            gap[r] = -np.inf
            mid[r] = np.nan
            continue
        wrap = a[0] + 2.0 * np.pi - a[m - 1]
        j = 0
        inner = -np.inf
        for t in range(m - 1):
            d = a[t + 1] - a[t]
            if d > inner:
                inner = d
                j = t
        if wrap >= inner:
            gap[r] = wrap
            mid[r] = a[m - 1] + 0.5 * wrap
        else:
            gap[r] = inner
            mid[r] = a[j] + 0.5 * inner


def successors(ball_indices: np.ndarray, coords: np.ndarray, candidates: np.ndarray,
               outward: np.ndarray, bisector: np.ndarray) -> np.ndarray:
    """Next boundary point of each candidate, walking with the surface on the left.

    Among the candidates of the ball that lie ahead (within 80 degrees of the walking
    direction) and whose own outward direction agrees (positive dot product in 3D), the
    one minimising ``|c| (1 + 3 (1 - cos a))`` is chosen, with ``a`` the angle between c
    and the walking direction: the nearest point, unless a slightly farther one lies much
    closer to the boundary line (a point just inside the boundary is passed over).

    Parameters
    ----------
    ball_indices : (N, B) numpy.ndarray of int64
    coords : (N, B, 2) numpy.ndarray of float64
    candidates : (N,) numpy.ndarray of bool
        Boundary points.
    outward : (N, 3) numpy.ndarray of float64
        Outward gap direction of every point in 3D (zero rows are fine off candidates).
    bisector : (N, 2) numpy.ndarray of float64
        The same direction in each point's tangent frame (:func:`angular_gaps`).

    Returns
    -------
    (N,) numpy.ndarray of int64
        Successor point index for candidates, -1 where no boundary point lies ahead and
        for non-candidates.
    """
    rows = np.flatnonzero(candidates)
    succ = np.full(candidates.shape[0], -1, dtype=np.int64)
    if rows.size == 0:
        return succ
    succ[rows] = _best_ahead(rows, ball_indices[rows], coords[rows], candidates, outward, bisector)
    return succ


def _best_ahead(rows, idx, c, candidates, outward, bisector):
    """Per row, the index in ``idx`` (-1 padded) of the best successor, or -1."""
    score = ahead_scores(rows, idx, c, candidates, outward, bisector)
    best = np.argmin(score, axis=1)
    pick = np.arange(rows.size)
    return np.where(np.isfinite(score[pick, best]), idx[pick, best], -1)


def bridge_successors(points: np.ndarray, e1: np.ndarray, e2: np.ndarray, candidates: np.ndarray,
                      outward: np.ndarray, bisector: np.ndarray, succ: np.ndarray,
                      reach: float | np.ndarray) -> np.ndarray:
    """Fill missing successors from boundary points beyond the geodesic ball.

    Where the angle criterion misses a boundary point (a notch of the sampling, a
    concave corner) its neighbours along the boundary find no successor in their balls.
    They look again among all boundary points within ``reach`` in 3D, projected into
    their tangent frame, with the same choice rule as :func:`successors`.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    e1, e2 : (N, 3) numpy.ndarray of float64
        Tangent frames of the DEM coordinates.
    candidates : (N,) numpy.ndarray of bool
    outward : (N, 3) numpy.ndarray of float64
    bisector : (N, 2) numpy.ndarray of float64
    succ : (N,) numpy.ndarray of int64
        Successors so far (-1 = missing); not modified.
    reach : float or (N,) numpy.ndarray of float64
        Search radius, one for all points or one per point.

    Returns
    -------
    (N,) numpy.ndarray of int64
    """
    rows = np.flatnonzero(candidates & (succ < 0))
    out = succ.copy()
    if rows.size == 0 or np.count_nonzero(candidates) < 2:
        return out
    row_reach = np.broadcast_to(np.asarray(reach, dtype=float), candidates.shape)[rows]
    near, c = projected_candidates(points, e1, e2, candidates, rows, row_reach)
    out[rows] = _best_ahead(rows, near, c, candidates, outward, bisector)
    return out


def hairpin_successors(points: np.ndarray, candidates: np.ndarray, outward: np.ndarray, succ: np.ndarray,
                       reach: float | np.ndarray, bridged: np.ndarray | None = None) -> np.ndarray:
    """Turn the walk around the end of a slot: a dead end steps to the facing lip.

    At the end of a slot 1.5-2 spacings wide the boundary turns by 180 degrees within
    about one spacing, below what the angle criterion resolves: the lip's last candidate
    finds nothing ahead, even after :func:`bridge_successors`. Its successor is then the
    nearest candidate that faces it (outward directions opposed, cosine below
    ``-_HAIRPIN_FACING``), lies on its open side (along its outward direction) within
    ``_HAIRPIN_REACH`` times ``reach``, and has no predecessor yet; where two dead ends
    pick the same point, the nearer gets it. Second to a facing candidate, a dead end
    steps to the start of an open chain (a candidate with a successor and no
    predecessor) whose outward direction is not within 60 degrees of its own: an end
    cap's last point faces the slot's axis, at right angles to the other lip. "On its
    open side" allows up to ``arccos(-_HAIRPIN_BEHIND)`` (104 degrees) off the outward
    direction. A bridge (:func:`bridge_successors`) from such a point that reaches farther than the facing candidate is replaced by the
    hairpin: at a slot's end the bridge otherwise leaves the lip for a sampling gap
    several spacings away (slit, random 2k: 5 spacings, against 2 across the slot).

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    candidates : (N,) numpy.ndarray of bool
    outward : (N, 3) numpy.ndarray of float64
        Outward gap direction of each point in 3D.
    succ : (N,) numpy.ndarray of int64
        Successors from the balls (:func:`successors`; -1 = missing); not modified.
    reach : float or (N,) numpy.ndarray of float64
        The bridges' reach (:func:`bridge_successors`).
    bridged : (N,) numpy.ndarray of int64, optional
        ``succ`` with the bridges filled in; the dead ends are those of ``succ``, and a
        bridge is kept where it is nearer than the hairpin step.

    Returns
    -------
    (N,) numpy.ndarray of int64
        ``bridged`` (or ``succ``) with the hairpin steps.
    """
    if bridged is None:
        bridged = succ
    out = bridged.copy()
    rows = np.flatnonzero(candidates & (succ < 0))
    cand_idx = np.flatnonzero(candidates)
    if rows.size == 0 or cand_idx.size < 2:
        return out
    radius = _HAIRPIN_REACH * np.broadcast_to(np.asarray(reach, dtype=float), candidates.shape)[rows]
    k = min(BRIDGE_K, cand_idx.size)
    dist, near = cKDTree(points[cand_idx]).query(points[rows], k=k, distance_upper_bound=float(radius.max()))
    found = np.isfinite(dist) & (dist <= radius[:, None])
    near = cand_idx[np.minimum(near, cand_idx.size - 1)]
    has_pred = np.zeros(candidates.shape[0], dtype=bool)
    has_pred[succ[succ >= 0]] = True  # the balls' steps; bridges may be overruled
    cos_out = np.einsum("nki,ni->nk", outward[near], outward[rows])
    # The start of an open chain: an end cap's last point, which faces the slot's axis
    # rather than the other lip, meets the other lip's chain there (slit, jittered 2k
    # seed 1: outward directions at 90 degrees, and the slot's loop did not close).
    has_pred_bridged = np.zeros(candidates.shape[0], dtype=bool)
    has_pred_bridged[bridged[bridged >= 0]] = True
    chain_start = (bridged >= 0) & ~has_pred_bridged
    # Such a step comes second: to a facing candidate farther away, and to a dead end
    # that faces the same point (slit, random 2k seed 1: a sampling void's candidate 1.85
    # spacings from a lip's chain start took it from the facing lip 2.14 away).
    facing = cos_out < -_HAIRPIN_FACING
    meets_chain = chain_start[near] & (cos_out < _HAIRPIN_FACING) & ~facing
    toward = np.einsum("nki,ni->nk", points[near] - points[rows, None, :], outward[rows])
    ahead = toward > -_HAIRPIN_BEHIND * dist
    ok = found & (facing | meets_chain) & ahead & ~has_pred[near] & (near != rows[:, None])
    rank = np.where(ok, meets_chain.astype(np.int64), 2)
    best = np.argmin(rank, axis=1)  # facing first, then nearest first
    pick = np.arange(rows.size)
    has = ok[pick, best]
    rows, target, gap = rows[has], near[pick, best][has], dist[pick, best][has]
    second = rank[pick, best][has]
    bridge = out[rows]
    bridge_len = np.where(bridge >= 0, np.linalg.norm(points[np.maximum(bridge, 0)] - points[rows], axis=1), np.inf)
    shorter = gap < bridge_len
    rows, target, gap, second = rows[shorter], target[shorter], gap[shorter], second[shorter]
    first = np.lexsort((gap, second, target))
    keep = np.ones(first.size, dtype=bool)
    keep[1:] = target[first][1:] != target[first][:-1]
    out[rows[first][keep]] = target[first][keep]
    return out


def cycles(succ: np.ndarray, nodes: np.ndarray) -> list[np.ndarray]:
    """Cycles of a partial successor map.

    A plain loop over the boundary points (O(#boundary), which is O(sqrt N) for a
    surface sampling), since following pointers is inherently sequential.

    Parameters
    ----------
    succ : (N,) numpy.ndarray of int64
        Successor or -1.
    nodes : (M,) numpy.ndarray of int64
        Where walks start.

    Returns
    -------
    list of (L_i,) numpy.ndarray of int64
        Each cycle once, starting at its smallest index.
    """
    state = np.zeros(succ.shape[0], dtype=np.int8)  # 0 new, 1 on current path, 2 done
    found = []
    for start in nodes.tolist():
        if state[start]:
            continue
        path = []
        v = start
        while v >= 0 and state[v] == 0:
            state[v] = 1
            path.append(v)
            v = int(succ[v])
        if v >= 0 and state[v] == 1:
            cyc = np.asarray(path[path.index(v):], dtype=np.int64)
            found.append(np.roll(cyc, -int(np.argmin(cyc))))
        for u in path:
            state[u] = 2
    return found


def empty_radii_inside(points: np.ndarray, loops: Sequence[np.ndarray]) -> list[float]:
    """:func:`empty_radius_inside` of each loop, with one kd-tree of all the points where there are many.

    Without a tree each loop scans all N points for its neighbourhood: a uniform random
    sampling of 3M points closed thousands of void rings, and the scans took 10 minutes
    of its front end. The tree of all points gives the same distances (the nearest point
    of a sample inside a loop lies within three loop radii of its centroid).

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    loops : sequence of (L,) numpy.ndarray of int64

    Returns
    -------
    list of float
        One radius per loop, in the same length unit as ``points``.
    """
    tree = cKDTree(points) if len(loops) > _LOOPS_PER_TREE else None
    return [empty_radius_inside(points, c, tree) for c in loops]


def empty_radius_inside(points: np.ndarray, loop: np.ndarray, tree: cKDTree | None = None,
                        grid: int = _EMPTY_GRID) -> float:
    """Radius of the largest disk inside a small loop that holds no point, approximately.

    The loop is projected onto its least-squares plane; on a ``grid`` x ``grid`` lattice
    over its bounding box, the samples inside the projected polygon (even-odd rule) are
    lifted back to that plane in 3D and their distances to the nearest point of ``tree``
    taken; the largest is returned (0 when no sample falls inside). Meant for loops of a
    few dozen points, small enough to be near planar.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    loop : (L,) numpy.ndarray of int64
    tree : scipy.spatial.cKDTree, optional
        Of all the points. Without it, one is built over the points within three times
        the loop's radius of its centroid (the nearest point of any sample inside the
        loop is among them), so a small loop costs O(N) arithmetic, not a tree of all N.
    grid : int
        Samples per side of the bounding box.

    Returns
    -------
    float
    """
    q = points[loop]
    centre, plane, x = _in_loop_plane(q)
    lo, hi = x.min(axis=0), x.max(axis=0)
    u, v = np.meshgrid(np.linspace(lo[0], hi[0], grid), np.linspace(lo[1], hi[1], grid))
    g = np.column_stack([u.ravel(), v.ravel()])
    a, b = x, np.roll(x, -1, axis=0)
    gy = g[:, 1:]
    crosses = (a[:, 1] > gy) != (b[:, 1] > gy)
    with np.errstate(divide="ignore", invalid="ignore"):
        x_at = a[:, 0] + (gy - a[:, 1]) * (b[:, 0] - a[:, 0]) / (b[:, 1] - a[:, 1])
    inside = (np.count_nonzero(crosses & (g[:, :1] < x_at), axis=1) % 2) == 1
    if not inside.any():
        return 0.0
    if tree is None:
        radius = float(np.sqrt(((q - centre) ** 2).sum(axis=1).max()))
        near = ((points - centre) ** 2).sum(axis=1) <= (3.0 * radius) ** 2
        tree = cKDTree(points[near])
    dist, _ = tree.query(centre + g[inside] @ plane)
    return float(dist.max())


def _in_loop_plane(q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A loop's points (L, 3) in its least-squares plane: (centroid (3,), axes (2, 3), coordinates (L, 2))."""
    centre = q.mean(axis=0)
    _, _, vt = np.linalg.svd(q - centre, full_matrices=False)
    return centre, vt[:2], (q - centre) @ vt[:2].T


def _smaller_angle(angle_deg: float) -> float:
    """The angle to propose below ``angle_deg``: 100 degrees, or 20 below where that is not lower."""
    return 100.0 if angle_deg > 100.0 else max(angle_deg - 20.0, 10.0)


def no_boundary_error(n_candidates: int, angle_deg: float, min_loop_size: int,
                      n_points: int | None = None, note: str = "") -> NoBoundaryError:
    """The error for "no loop", worded by how many points passed the angle criterion.

    Most of the points (``n_points``, when given): too few points to have an inside
    (40 random points on a square: 21 candidates, which read as "closed surface").
    Few candidates: the surface is closed, or its rim drowns in noise (``fold``, an open
    strip, at normal noise of 0.5 spacings: 22 candidates), or its only opening is a hole
    smaller than the balls (a sphere without a 15-degree cap, 2,949 points: 16
    candidates, refused as "closed"; at 100 degrees one loop, and a map matching the
    mesh's ``scp``). Many that do not close into a loop: the
    boundary is too ragged or sparse for balls of this size. ``note``, a sentence on a
    cause told from elsewhere (the front end's noisy plane fits,
    :func:`~parambench.methods.pointset.failure_causes.noisy_points_note`), ends the message.
    """
    error = _no_boundary_error(n_candidates, angle_deg, min_loop_size, n_points)
    return NoBoundaryError(f"{error} {note}") if note else error


def _no_boundary_error(n_candidates: int, angle_deg: float, min_loop_size: int,
                       n_points: int | None) -> NoBoundaryError:
    if n_points is not None and n_candidates > _MOSTLY_BOUNDARY * n_points:
        return NoBoundaryError(
            f"{n_candidates} of the {n_points} points pass the {angle_deg:g}-degree angle criterion, so "
            "the points have almost no inside: too few points, or a strip or curve only a spacing or two "
            "wide; sample the surface more densely (a few hundred points or more, several across it)."
        )
    if n_candidates < 4 * min_loop_size:
        return NoBoundaryError(
            f"no boundary found ({n_candidates} isolated point(s) pass the {angle_deg:g}-degree angle "
            "criterion): closed surface: cut it open before flattening; or, if the surface has a rim, the "
            "rim is too noisy or sparsely sampled to tell from the inside (denoise the points, or sample "
            f"the rim more densely); or its only opening is a hole narrower than the geodesic balls (about "
            f"5 spacings across), whose rim points see each other across it: lower boundary_angle_deg "
            f"(e.g. {_smaller_angle(angle_deg):g})."
        )
    return NoBoundaryError(
        f"{n_candidates} points pass the {angle_deg:g}-degree angle criterion but no boundary loop closes: "
        "a closed surface (cut it open before flattening) or a boundary too ragged or sparsely sampled "
        "(sample the boundary curve more densely, or raise k_nn or ball_eps_factor)."
    )


def _loop_spacing(points: np.ndarray, loop: np.ndarray, local_spacing: np.ndarray) -> float:
    """Mean gap between consecutive loop points over the local spacing of the loop's points."""
    return _perimeter(points, loop) / loop.size / float(np.median(local_spacing[loop]))


def _perimeter(points: np.ndarray, loop: np.ndarray) -> float:
    p = points[loop]
    return float(np.linalg.norm(p - np.roll(p, -1, axis=0), axis=1).sum())


def find_boundary(points: np.ndarray, normals: np.ndarray, ball_indices: np.ndarray, coords: np.ndarray, *,
                  angle_deg: float = 120.0, decimate: int = 1,
                  min_loop_size: int = DEFAULT_MIN_LOOP_SIZE, require_loop: bool = True,
                  local_spacing: np.ndarray | None = None, lips: np.ndarray | None = None,
                  slot_ends: np.ndarray | None = None) -> BoundaryLoops:
    """Boundary points and loops of a point set from its geodesic balls.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    normals : (N, 3) numpy.ndarray of float64
        The normals whose tangent frames (:func:`parambench.methods.pointset.normals.tangent_frames`)
        the DEM coordinates are expressed in.
    ball_indices : (N, B) numpy.ndarray of int64
        -1 at padding.
    coords : (N, B, 2) numpy.ndarray of float64
        DEM tangent coordinates.
    angle_deg : float
        Angle-criterion threshold in degrees, in (0, 360).
    decimate : int
        Keep every ``decimate``-th point of each loop (1 keeps all; Fig. 7d uses 2).
    min_loop_size : int
        Smaller cycles are dropped as sampling gaps.
    require_loop : bool
        Raise when no loop is found; when False, return empty ``loops`` instead (the
        caller may retry with wider balls).
    local_spacing : (N,) numpy.ndarray of float64, optional
        Spacing around each point; when given, loops of fewer than 32 points spaced
        along them more than 1.25 local spacings apart are dropped as rings around
        voids of the sampling (random samplings have such voids; a true boundary is
        sampled along itself about as densely as the surface around it), and so are
        loops of fewer than 32 points whose largest empty disk inside
        (:func:`empty_radius_inside`) is narrower than 1.9 of their mean steps.
    lips : (N,) numpy.ndarray of bool, optional
        Points whose edges across a slot were cut
        (:mod:`parambench.methods.pointset.slot_cuts`): they are candidates from a gap of
        ``_LIP_ANGLE_DEG`` on. At a slot's end the lip's last points see the other lip
        beyond the end (gaps of 90-120 degrees on the slit at 2k points) and were left
        out of the loop.
    slot_ends : (N,) numpy.ndarray of bool, optional
        Ends of every cut edge: where there is one, the walk takes hairpin steps
        (:func:`hairpin_successors`).

    Returns
    -------
    BoundaryLoops

    Raises
    ------
    InvalidInputError
        Parameters out of range.
    NoBoundaryError
        No loop found (``require_loop``): see :func:`no_boundary_error` for the message.
    """
    if not 0.0 < angle_deg < 360.0:
        raise InvalidInputError(f"boundary_angle_deg must lie in (0, 360), got {angle_deg}.")
    if int(decimate) != decimate or decimate < 1:
        raise InvalidInputError(f"boundary_decimate must be a positive integer, got {decimate}.")
    mask = ball_indices >= 0
    gap, bisector = angular_gaps(coords, mask)
    candidates = gap > np.deg2rad(angle_deg)
    if lips is not None:
        candidates |= lips & (gap > np.deg2rad(min(_LIP_ANGLE_DEG, angle_deg)))
    e1, e2 = tangent_frames(normals)
    ball_radius = _ball_radii(coords)
    # Bridges span up to twice the typical ball radius, or twice the point's own ball
    # radius where the sampling is coarser (graded samplings: a small hole in a sparse
    # region, 3 spacings of 0.093 between two of its candidates, against a median ball
    # radius of 0.1 over the dense rest, was lost).
    typical_radius = float(np.median(ball_radius))
    outward = bisector[:, :1] * e1 + bisector[:, 1:] * e2
    hairpins = slot_ends is not None and bool(slot_ends.any())
    reach = 2.0 * np.maximum(ball_radius, typical_radius)
    all_cycles, n_pruned, hairpin_from = _walk_pruned(points, ball_indices, coords, e1, e2, candidates, outward,
                                                      bisector, reach, min_loop_size, hairpins=hairpins)
    kept = _true_loops(points, all_cycles, ball_radius, typical_radius, min_loop_size, local_spacing)
    n_rejoined = 0
    if hairpins and local_spacing is not None:
        kept = [c for c in kept if _slot_loop_plausible(points, normals, c, hairpin_from, slot_ends, local_spacing)]
        # Loops only: joined with the ring of a void beside the slot, the slot's loop took
        # in 9-23 points off the boundary (slit, random 100k, 3 seeds of 6).
        kept, n_rejoined = rejoin_split_slots(points, normals, kept, slot_ends, local_spacing)
    n_dropped_loops = n_pruned + len(all_cycles) - len(kept)
    n_cover_loops = 0
    if not hairpins:
        more = _cover_loops(points, ball_indices, coords, e1, e2, candidates, outward, bisector, reach,
                            min_loop_size, kept, ball_radius, typical_radius, local_spacing)
        kept, n_cover_loops = kept + more, len(more)
    n_small_holes = 0
    if not hairpins and local_spacing is not None and kept and points.shape[0] < SMALL_HOLE_MAX_POINTS:
        small = _small_hole_loops(points, ball_indices, coords, e1, e2, candidates, bisector, reach, min_loop_size,
                                  kept, ball_radius, typical_radius, local_spacing, angle_deg)
        kept, n_small_holes = kept + small, len(small)
    n_hairpin_slots = 0
    if not hairpins and local_spacing is not None:
        slots = _hairpin_slot_loops(points, normals, ball_indices, coords, e1, e2, candidates, outward, bisector,
                                    reach, min_loop_size, kept, ball_radius, typical_radius, local_spacing)
        if slots:
            slots, _ = put_back_slot_tips(points, normals, slots, outward, None)
            kept, n_hairpin_slots = kept + slots, len(slots)
    if not kept and require_loop:
        raise no_boundary_error(int(candidates.sum()), angle_deg, min_loop_size, points.shape[0])
    kept.sort(key=lambda c: _perimeter(points, c), reverse=True)
    n_put_back = 0
    if hairpins:
        kept, n_put_back = put_back_slot_tips(points, normals, kept, outward, slot_ends)
    kept, n_passed_over = put_back_rounds(points, normals, kept, ball_indices, gap, outward)
    n_put_back += n_passed_over
    kept, n_untangled = untangle_loops(points, normals, kept)
    kept, n_wrapped, n_notches = wrap_outside_points(points, normals, kept, outward, ball_indices)
    in_loops = int(sum(c.size for c in kept))
    loops = [c[::int(decimate)] for c in kept]
    out_mask = np.zeros(points.shape[0], dtype=bool)
    for loop in loops:
        out_mask[loop] = True
    diagnostics = {
        "n_candidates": int(candidates.sum()),
        "n_in_loops": in_loops,
        "n_dropped_points": int(candidates.sum()) - (in_loops - n_put_back),
        "n_dropped_loops": int(n_dropped_loops),
        "loop_sizes": [int(c.size) for c in kept],
        "n_put_back": n_put_back,
        "n_wrapped": n_wrapped,
        "n_notches_dropped": n_notches,
        "n_hairpin_slots": n_hairpin_slots,
        "n_slot_pieces_rejoined": n_rejoined,
        "n_cover_loops": n_cover_loops,
        "n_small_holes": n_small_holes,
        "n_untangled": n_untangled,
    }
    return BoundaryLoops(loops=loops, mask=out_mask, candidates=candidates, max_gap=gap,
                         diagnostics=diagnostics)


#: A loop of the hairpin walk that is no slot is a hole when it encloses an empty disk of
#: at least this many of its mean steps (the cover's test with a higher bar: hairpin
#: steps also close loops round a random sampling's voids, one at 1.90 on ``cap``,
#: random, 100k points; the swiss roll's hole, which the walk and the cover miss at
#: 2,000 and 5,000 points, 4.55 and 8.23).
HAIRPIN_HOLE_EMPTY_STEPS = 3.0

#: ... and encloses at most this share of its own size in points: the swiss roll's hole
#: (5,000 points) left 1 point inside its 121-point loop, which the loop wrap takes in.
HAIRPIN_HOLE_ENCLOSED = 0.05


def _hairpin_slot_loops(points, normals, ball_indices, coords, e1, e2, candidates, outward, bisector, reach,
                        min_loop_size, kept, ball_radius, typical_radius, local_spacing) -> list[np.ndarray]:
    """Slots and holes the plain walk left open, closed by a walk with hairpin steps.

    A slot 2-3 spacings wide that the K nearest neighbours do not bridge (so none was cut:
    pymeshlab's bunny with a slot cut into it) has lips that pass the angle criterion, but
    the walk dies at its ends, where the boundary turns within a spacing. When at least
    ``min_loop_size`` candidates are on no loop, the walk is run again with hairpin steps,
    and the loops it closes that share no point with ``kept`` are taken when they are
    slots (:func:`~parambench.methods.pointset.hole_filling.is_slot`: narrow and long)
    enclosing no point (:func:`~parambench.methods.pointset.hole_filling.enclosed_points`):
    elsewhere hairpin steps make loops of a random sampling's voids, most small and round,
    some (plane, random 20k seed 2) as narrow and long as a slot but drawn around points.
    They are also taken when they are holes: round an empty disk of at least
    :data:`HAIRPIN_HOLE_EMPTY_STEPS` mean steps, enclosing at most
    :data:`HAIRPIN_HOLE_ENCLOSED` of their size in points. The swiss roll's hole
    (scikit-learn's ``make_swiss_roll(hole=True)``, 7 spacings across and 30 long at 2,000
    points) was missed at 2,000 and 5,000 points: the plain walk turned away at its
    corners into the rim's voids, and its chain ran into the outer loop. The walk's pieces of
    one slot are joined first (:func:`~parambench.methods.pointset.slot_rejoin.rejoin_split_slots`),
    and a joined loop is taken only as a slot.
    """
    on_loop = np.zeros(points.shape[0], dtype=bool)
    for loop in kept:
        on_loop[loop] = True
    if np.count_nonzero(candidates & ~on_loop) < min_loop_size:
        return []
    again, _, _ = _walk_pruned(points, ball_indices, coords, e1, e2, candidates, outward, bisector, reach,
                               min_loop_size, hairpins=True)
    pieces = [c for c in again if not on_loop[c].any()]
    tree = cKDTree(points)
    # Joining is for a slot's pieces: a joined loop stands only as a slot (the hole test is
    # for loops the walk closed whole); pieces in no joined slot are judged as before.
    joined, n_joined = rejoin_split_slots(points, normals, pieces, None, local_spacing, tree)
    slots = []
    if n_joined:
        piece_ids = {id(c) for c in pieces}
        made = [c for c in joined if id(c) not in piece_ids]  # the joins' new loops
        slots = [c for c in _true_loops(points, made, ball_radius, typical_radius, min_loop_size, local_spacing)
                 if _slot_or_hole(points, normals, c, local_spacing, tree, holes=False)]
        in_slots = np.zeros(points.shape[0], dtype=bool)
        for c in slots:
            in_slots[c] = True
        pieces = [c for c in pieces if not in_slots[c].any()]
    new = _true_loops(points, pieces, ball_radius, typical_radius, min_loop_size, local_spacing)
    return slots + [c for c in new if _slot_or_hole(points, normals, c, local_spacing, tree)]


def _slot_or_hole(points: np.ndarray, normals: np.ndarray, loop: np.ndarray, local_spacing: np.ndarray,
                  tree: cKDTree | None = None, holes: bool = True) -> bool:
    """Whether a loop closed through hairpin steps bounds a slot or a hole, not points.

    A slot (:func:`~parambench.methods.pointset.hole_filling.is_slot`) enclosing no
    point, or (with ``holes``) a hole round an empty disk of
    :data:`HAIRPIN_HOLE_EMPTY_STEPS` mean steps enclosing at most
    :data:`HAIRPIN_HOLE_ENCLOSED` of the loop's size in points.
    """
    tree = cKDTree(points) if tree is None else tree
    spacing = float(np.median(local_spacing[loop]))
    if is_slot(points, normals, loop, spacing):
        allowed = 0
    elif not holes:
        return False
    elif empty_radius_inside(points, loop, tree) >= HAIRPIN_HOLE_EMPTY_STEPS * _perimeter(points, loop) / loop.size:
        allowed = int(HAIRPIN_HOLE_ENCLOSED * loop.size)
    else:
        return False
    return enclosed_points(points, normals, loop, spacing, tree) <= allowed


def _slot_loop_plausible(points: np.ndarray, normals: np.ndarray, loop: np.ndarray, hairpin_from: np.ndarray,
                         slot_ends: np.ndarray, local_spacing: np.ndarray) -> bool:
    """Whether a loop of the walk on a slot-cut graph may stand.

    Where slots were cut the walk takes hairpin steps everywhere, and on a random
    sampling they also close rings round its widest voids far from any cut (``slit``,
    uniform random 300k and 1M points: a 17-point ring through 2 hairpin steps, 78
    spacings from the slot, its empty disk 1.9 of its steps, which passed
    :func:`_true_loops` and came out as a third loop). A loop as short as a void's ring
    (under ``_MAX_VOID_RING`` points) that turns through a hairpin step and passes no cut
    end is held to the test of the hairpin walk's own loops (:func:`_slot_or_hole`); the
    others stand as :func:`_true_loops` judged them (a rim encloses the surface, which
    that test would refuse).
    """
    if loop.size >= _MAX_VOID_RING or not hairpin_from[loop].any() or slot_ends[loop].any():
        return True
    return _slot_or_hole(points, normals, loop, local_spacing)


def _walk_pruned(points: np.ndarray, ball_indices: np.ndarray, coords: np.ndarray, e1: np.ndarray, e2: np.ndarray,
                 candidates: np.ndarray, outward: np.ndarray, bisector: np.ndarray, reach: float | np.ndarray,
                 min_loop_size: int, hairpins: bool = False) -> tuple[list[np.ndarray], int]:
    """Cycles of the boundary walk over the candidates, after pruning the points of small cycles.

    Parameters
    ----------
    points, ball_indices, coords
        As for :func:`find_boundary`.
    e1, e2 : (N, 3) numpy.ndarray of float64
        Tangent frames of the DEM coordinates.
    candidates : (N,) numpy.ndarray of bool
        Points passing the angle criterion.
    outward : (N, 3) numpy.ndarray of float64
        The gap bisector of each point in 3D.
    bisector : (N, 2) numpy.ndarray of float64
        The same in tangent coordinates.
    reach : float or (N,) numpy.ndarray of float64
        Longest bridge (:func:`bridge_successors`).
    min_loop_size : int
        Cycles with fewer points are pruned.
    hairpins : bool
        Take hairpin steps (:func:`hairpin_successors`): where a slot was cut, and in the
        second walk of :func:`_hairpin_slot_loops`, whose loops are kept only when they
        are slots. On a random sampling's voids the step made extra loops (cap, random
        100k: 2 loops instead of 1), and restricted to the points near the cuts it missed
        the steps some slots need (slit, random 20k).

    Returns
    -------
    cycles : list of numpy.ndarray of int64
        The last walk's cycles: none smaller than ``min_loop_size`` unless
        ``_MAX_PRUNE_ROUNDS`` walks all still had small ones.
    n_pruned : int
        Small cycles whose points were dropped before the last walk.
    hairpin_from : (N,) numpy.ndarray of bool
        Points that took a hairpin step in any walk (none without ``hairpins``).
    """
    hairpin_from = np.zeros(candidates.shape[0], dtype=bool)

    def walk(active: np.ndarray) -> np.ndarray:
        in_ball = successors(ball_indices, coords, active, outward, bisector)
        succ = bridge_successors(points, e1, e2, active, outward, bisector, in_ball, reach)
        if hairpins:
            bridged = succ
            succ = hairpin_successors(points, active, outward, in_ball, reach, bridged=bridged)
            hairpin_from[:] |= (succ != bridged) & active
        return succ

    cycles_found, n_pruned = _pruned_cycles(walk, candidates, min_loop_size, keep_broken=True)
    return cycles_found, n_pruned, hairpin_from


def _pruned_cycles(step: Callable[[np.ndarray], np.ndarray], candidates: np.ndarray,
                   min_loop_size: int, keep_broken: bool = False) -> tuple[list[np.ndarray], int]:
    """Cycles of ``step(active)``'s successors, walked again without the points of small cycles.

    A wrong step into a sampling gap ends the walk in a small cycle and would cut a true
    loop open: the points of small cycles are dropped and the successors chosen again
    until none is left (at most ``_MAX_PRUNE_ROUNDS`` times). Returns the last cycles and
    the number of small cycles dropped.

    With ``keep_broken``, a cycle of ``min_loop_size`` or more that an earlier round
    closed and the last one broke is returned too, where it shares no point with the
    cycles already returned (the latest rounds first). The walk's steps are not local:
    with points elsewhere dropped, a hairpin or a bridge can go to another point, and on
    ``slit`` (uniform random 100k, seed 5) the slot's 390-point loop of the first round
    was left with a dead end in every later one; the slot was lost, and the angle retry
    that followed found two false loops.
    """
    active = candidates.copy()
    n_pruned = 0
    earlier: list[list[np.ndarray]] = []
    for _ in range(_MAX_PRUNE_ROUNDS):
        all_cycles = cycles(step(active), np.flatnonzero(active))
        small = [c for c in all_cycles if c.size < min_loop_size]
        if not small:
            break
        n_pruned += len(small)
        active[np.concatenate(small)] = False
        if keep_broken:
            earlier.append([c for c in all_cycles if c.size >= min_loop_size])
    if keep_broken and earlier:
        taken = np.zeros(candidates.shape[0], dtype=bool)
        for c in all_cycles:
            taken[c] = True
        for round_cycles in reversed(earlier):
            for c in round_cycles:
                if not taken[c].any():
                    all_cycles.append(c)
                    taken[c] = True
    return all_cycles, n_pruned


def _cover_loops(points, ball_indices, coords, e1, e2, candidates, outward, bisector, reach, min_loop_size, kept,
                 ball_radius, typical_radius, local_spacing) -> list[np.ndarray]:
    """Loops of the candidates the walk's loops left off, from a minimum-cost cycle cover.

    Where the boundary comes close to itself (an inlet's mouth, a hole beside the rim, a
    range scan's ragged edge), two points of the greedy walk take the same successor
    and a long chain of the rim runs into a small cycle or a dead end: pymeshlab's range
    scan ``rangemaps/face000.ply`` (82,499 points) kept 4 loops, none of them its rim,
    recall 0.054. The candidates on no kept loop are chained again all at once
    (:func:`~.boundary_cover.cover_successors`, costs in ball radii; points of cycles
    under ``min_loop_size`` dropped and the rest covered again, as in
    :func:`_walk_pruned`). Its cycles are kept when they pass :func:`_true_loops` and
    enclose an empty disk of at least ``_MIN_EMPTY_STEPS`` of their own mean steps
    whatever their size, or, where the walk kept no loop, are an outer rim
    (:func:`is_outer_rim`): the cover closes chains the walk leaves open, among them the
    line where two sides touch (``real/camelhead``'s lips: a 67-point loop around a disk
    of 1.32 steps; face000's rim and holes 7-45). Uniform random points in a square or
    rectangle (1 seed in 20 at 2k and 3k points, 8 in 20 at 10k, 6 in 20 at 4k in a 4:1
    rectangle) had their rim only from the cover, which the empty-disk test alone dropped:
    NoBoundaryError. Only where the walk kept nothing: points scattered over
    ``real/camelhead`` (5k) have a 43-point chain beside the walk's rim that faces out
    as a rim does (a second, false loop).
    """
    rest = candidates.copy()
    if kept:
        rest[np.concatenate(kept)] = False
    if np.count_nonzero(rest) < min_loop_size:
        return []
    scale = np.maximum(ball_radius, 1e-3 * typical_radius)
    reach = np.broadcast_to(np.asarray(reach, dtype=float), rest.shape)
    found, _ = _pruned_cycles(lambda active: cover_successors(points, ball_indices, coords, e1, e2, active, outward,
                                                              bisector, reach, scale), rest, min_loop_size)
    found = _true_loops(points, found, ball_radius, typical_radius, min_loop_size, local_spacing)
    holes = [r >= _MIN_EMPTY_STEPS * _perimeter(points, c) / c.size
             for c, r in zip(found, empty_radii_inside(points, found))]
    if kept or all(holes):
        return [c for c, hole in zip(found, holes) if hole]
    # The walk kept no loop: an outer rim only the cover closed is the boundary too.
    tree = cKDTree(points)
    return [c for c, hole in zip(found, holes) if hole or is_outer_rim(points, c, outward, tree)]


def is_outer_rim(points: np.ndarray, loop: np.ndarray, outward: np.ndarray, tree: cKDTree) -> bool:
    """Whether ``loop`` is a rim with the surface inside it and nothing beyond it.

    The empty-disk test of :func:`_cover_loops` judges a loop by what it encloses, which
    suits a hole; an outer rim encloses the surface itself. It is recognised by its gap
    bisectors: at least ``_RIM_FACING`` of its points' outward directions leave the loop's
    polygon (in its least-squares plane), and probes ``_RIM_PROBE`` mean steps out along
    them lie, in the median, at least ``_RIM_EMPTY`` of that distance from every point.
    Measured on uniform random points in a square (2k-3k points, the seeds whose greedy
    walk closed no loop): the rim 0.99-1.0 facing and 1.0 empty; rings of voids the cover
    found 0-0.12 and 0.37-0.77; ``real/camelhead``'s lips 0.45 and 1.0.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    loop : (L,) numpy.ndarray of int64
    outward : (N, 3) numpy.ndarray of float64
        Each point's gap bisector in 3D (:func:`find_boundary`).
    tree : scipy.spatial.cKDTree
        Of ``points``.

    Returns
    -------
    bool
    """
    q = points[loop]
    _, plane, x = _in_loop_plane(q)
    tangent = np.roll(x, -1, axis=0) - np.roll(x, 1, axis=0)
    inward = np.sign(signed_area_2d(x)) * np.column_stack([-tangent[:, 1], tangent[:, 0]])
    leaving = np.einsum("ij,ij->i", outward[loop] @ plane.T, inward) < 0
    if np.mean(leaving) < _RIM_FACING:
        return False
    reach = _RIM_PROBE * _perimeter(points, loop) / loop.size
    dist, _ = tree.query(q + reach * unit_vectors(outward[loop]))
    return bool(np.median(dist) >= _RIM_EMPTY * reach)


def _small_hole_loops(points, ball_indices, coords, e1, e2, candidates, bisector, reach, min_loop_size, kept,
                      ball_radius, typical_radius, local_spacing, angle_deg) -> list[np.ndarray]:
    """Loops of holes narrower than the balls, from the angle criterion on the balls' nearer members.

    The gap is measured again over the members within :data:`SMALL_HOLE_SHARE` of each
    ball's radius; where at most :data:`MAX_SMALL_GAP_SHARE` of the points pass it, those
    points and the candidates the walk's loops left off are chained by the cycle cover
    (:func:`_cover_loops`, with its loop tests: a ring around a void of the sampling
    encloses no disk wide enough).
    """
    n = points.shape[0]
    gap = np.empty(n)
    mid = np.empty((n, 2))

    for start in range(0, n, 8 * _GAP_CHUNK):  # in row blocks: the (N, B) radii are large at a million points
        sl = slice(start, min(start + 8 * _GAP_CHUNK, n))
        c = coords[sl]
        near = (ball_indices[sl] >= 0) & (np.einsum("nbi,nbi->nb", c, c) <= (SMALL_HOLE_SHARE * ball_radius[sl, None]) ** 2)
        gap[sl], mid[sl] = angular_gaps(c, near)
        # No member that near (a sparse point of a graded sampling's rim): open all round,
        # facing where its whole ball's gap does (a zero direction has no successor).
        lone = sl.start + np.flatnonzero(~near.any(axis=1))
        gap[lone], mid[lone] = 2.0 * np.pi, bisector[lone]
    small = gap > np.deg2rad(angle_deg)
    outward = mid[:, :1] * e1 + mid[:, 1:] * e2
    irregular = np.count_nonzero(small & ~candidates) > MAX_SMALL_GAP_SHARE * n
    if irregular:
        on_loops = np.zeros(n, dtype=bool)
        on_loops[np.concatenate(kept)] = True
        small = _void_rims(points, small, small & ~on_loops, outward, local_spacing, ball_radius)
        if not small.any():
            return []
    found = _cover_loops(points, ball_indices, coords, e1, e2, small | candidates, outward, mid, reach, min_loop_size,
                         kept, ball_radius, typical_radius, local_spacing)
    # Only what the balls cannot see: short loops around a disk no wider than the balls.
    # Graded samplings gave longer ones beside their true loops (60 and 2,260 points,
    # disks 1.6 and 11 ball radii wide); the holes they are for have 12-21 points, 0.65-0.99.
    # On an irregular sampling the disk must be as wide as the voids' seeds asked for, and
    # much wider than the loop's steps (a ring round a void of ``protrusions`` random 2k:
    # 1.79 local spacings; one of ``real/camelhead``: 2.46, but 2.09 of its own steps;
    # holes 4 spacings across on graded 2k / 20k: 2.43 / 2.51 and 3.23 / 3.06).
    least, least_steps = (VOID_RADIUS, VOID_EMPTY_STEPS) if irregular else (0.0, 0.0)
    found = [c for c in found if c.size < _MAX_VOID_RING]
    empty = empty_radii_inside(points, found)
    return [c for c, r in zip(found, empty)
            if max(least * float(np.median(local_spacing[c])), least_steps * _perimeter(points, c) / c.size)
            <= r <= _MAX_SMALL_HOLE_BALLS * float(np.median(ball_radius[c]))]


def _void_rims(points: np.ndarray, small: np.ndarray, seeds: np.ndarray, outward: np.ndarray,
               local_spacing: np.ndarray, ball_radius: np.ndarray) -> np.ndarray:
    """Of the points ``small`` marks, those near a void wider than an irregular sampling leaves.

    A point of ``seeds`` borders a void when the disk of :data:`VOID_RADIUS` local
    spacings that touches it on its gap's side (centred that far out along ``outward``)
    holds no point; the points kept are those of ``small`` within a hole's reach of such a
    point: the diameter :data:`_MAX_SMALL_HOLE_BALLS` allows, plus a spacing.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    small, seeds : (N,) numpy.ndarray of bool
        The points to choose from, and those whose disks are tried (not the rims of the
        loops already kept: their disks are empty outside the surface).
    outward : (N, 3) numpy.ndarray of float64
        The gaps' directions, in 3D (zero where a point has none).
    local_spacing, ball_radius : (N,) numpy.ndarray of float64

    Returns
    -------
    (N,) numpy.ndarray of bool
        A subset of ``small``.
    """
    tried = np.flatnonzero(seeds)
    direction = unit_vectors(outward[tried])
    radius = VOID_RADIUS * local_spacing[tried]
    dist, _ = cKDTree(points).query(points[tried] + radius[:, None] * direction)
    # The point itself is on the disk's rim: it is empty when nothing is nearer.
    seeds = tried[(dist >= radius * (1.0 - 1e-9)) & (np.einsum("ij,ij->i", direction, direction) > 0.5)]
    out = np.zeros_like(small)
    if seeds.size == 0:
        return out
    idx = np.flatnonzero(small)
    reach = 2.0 * _MAX_SMALL_HOLE_BALLS * ball_radius[seeds] + local_spacing[seeds]
    near = cKDTree(points[idx]).query_ball_point(points[seeds], reach)
    out[idx[np.unique(np.concatenate([np.asarray(j, dtype=np.int64) for j in near]))]] = True
    return out


def _true_loops(points: np.ndarray, all_cycles: list[np.ndarray], ball_radius: np.ndarray, typical_radius: float,
                min_loop_size: int, local_spacing: np.ndarray | None) -> list[np.ndarray]:
    """The cycles that are boundary loops, in their order: big enough, long enough, not void rings.

    A loop needs ``min_loop_size`` points and a perimeter of ``_MIN_PERIMETER_BALLS``
    ball radii (the larger of its own median and the typical one); with
    ``local_spacing``, a loop of fewer than ``_MAX_VOID_RING`` points spaced more than
    ``_MAX_LOOP_SPACING`` local spacings apart, or whose largest empty disk inside
    (:func:`empty_radius_inside`) is narrower than ``_MIN_EMPTY_STEPS`` of its own mean
    steps, is a ring around a void of the sampling.
    """
    kept = [c for c in all_cycles if c.size >= min_loop_size
            and _perimeter(points, c) >= _MIN_PERIMETER_BALLS * max(float(np.median(ball_radius[c])), typical_radius)]
    if local_spacing is not None:
        kept = [c for c in kept
                if c.size >= _MAX_VOID_RING or _loop_spacing(points, c, local_spacing) <= _MAX_LOOP_SPACING]
        small = [c for c in kept if c.size < _MAX_VOID_RING]
        wide = {id(c) for c, r in zip(small, empty_radii_inside(points, small))
                if r >= _MIN_EMPTY_STEPS * _perimeter(points, c) / c.size}
        kept = [c for c in kept if c.size >= _MAX_VOID_RING or id(c) in wide]
    return kept
