"""Neighbourhoods that do not reach across a slot: an in-plane gap narrower than a neighbourhood.

Where a surface has a slot (the two lips of a cut, a hole 1.5-2 spacings wide), a lip
point's K nearest neighbours include points of the other lip. The lips then look like
interior points to the angle criterion (their neighbourhoods are full discs) and the
slot is lost. The gap tests of :mod:`parambench.methods.pointset.surface_neighbours`
look along the normal and see nothing here: both lips lie in one tangent plane.

An edge crosses a slot when it crosses an empty strip of its tangent plane: the strip is
at least :data:`MIN_WIDTH` spacings wide, measured across it between the edge's ends;
the middle of that span (all but :data:`MARGIN` of it at each side) is empty over
:data:`STRIP_LENGTH` local spacings, half on each side of the edge; and points line
both its sides at both ends (a strip that runs off the surface is empty on its outer
half without being a slot). Widths are measured against the larger of the smooth local
spacing and the spacing over one ring: where a graded sampling's density changes fast
the smooth one lags, and the sparse side's own gaps would pass for strips. Both are
scaled by the tangent share of the kNN distances (:func:`in_plane_share`): normal noise
lengthens every edge but not the slot.

A uniform random sampling still leaves such a strip empty now and then (about e^-11
per place and direction at the threshold): on `holes`, random 20k, the strip test
fires on 124 edges. Those strips are short; a slot gives crossings all along it. So
crossings are cut only where they line up, side by side, over :data:`MIN_CUT_EXTENT`
spacings (:func:`elongated_groups`); the others are counted (``n_lone_crossings``)
and left.

The strip test needs :data:`STRIP_NEIGHBOURS` neighbours per point (a kd-tree search
that would take seconds at a million points), so it runs only on the points that three
cheap screens leave: (1) kNN edges at least :data:`MIN_LENGTH` spacings long whose
midpoint lies at least :data:`CLEARANCE` spacings from every neighbour of both ends;
(1b) of those, the edges that cross a strip :data:`SCREEN_HALF_LENGTH` spacings each
way, empty among the points two graph steps from the edge's first end (a necessary
condition, without a search); (2) of those, the edges that line up with others over
:data:`MIN_EXTENT` spacings. On jittered samplings without a slot screen 1b leaves
0-1 edges of 20k points.

The walk of :mod:`parambench.methods.pointset.boundary` then needs a hairpin step at
the slot's ends (:func:`~parambench.methods.pointset.boundary.hairpin_successors`):
the boundary turns by 180 degrees within about a spacing there.
"""

from __future__ import annotations

from pathlib import Path

import numba
import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from ..numba_cache import configure_numba_cache
from .neighbourhoods import KnnGraph, local_spacing

__all__ = ["slot_cut_graph", "slots_on_loops", "cut_ends", "void_edges", "elongated_groups", "strip_crossings",
           "MIN_WIDTH", "STRIP_LENGTH"]

_CACHE, _ = configure_numba_cache(Path(__file__).resolve().parent)

#: The cuts are kept only when at least this share of their ends lies on or next to a
#: boundary loop found on the cut graph (:func:`slots_on_loops`).
MIN_ON_LOOP = 0.5

#: Screen 1: an edge at least this many local spacings long ...
MIN_LENGTH = 1.2
#: ... whose midpoint is at least this far (spacings, the width unit) from its ends'
#: neighbours.
#: The slit's crossing edges measure 0.71-1.0 of the smooth spacing (graded and random
#: samplings; 0.96 jittered).
CLEARANCE = 0.65
#: Screen 2: screened edges whose midpoints lie within this many (median local) spacings ...
LINK = 6.0
#: ... whose directions agree to this cosine ...
ALIGNED = 0.5
#: ... and whose midpoints are side by side (the step along the edge at most this many spacings) are linked ...
SIDE_STEP = 0.75
#: ... and a group is examined when its midpoints span at least this many spacings.
MIN_EXTENT = 6.0

#: Screen 1b: the strip's half length judged on the graph's two-ring (which reaches about
#: three spacings).
SCREEN_HALF_LENGTH = 1.5

#: Near each end of a slot (this many spacings before it), edges across its line with a
#: clear midpoint are cut too (:func:`_tip_crossings`); the line is fitted over as many.
TIP_REACH = 5.0
#: ... and beyond the last crossing the strip test found, up to this many spacings (or
#: the slot's end, whichever comes first): where the K nearest neighbours bridge a slot
#: only here and there, that crossing can lie 10 spacings from the end (slit, jittered
#: 20k). Growing 5 at a time from each round's new ends instead ran past the end at
#: noise 0.5 (slit, jittered 2k seed 2), where the end's blocking point is less clear.
TIP_EXTENT = 12.0
#: A point within this share of the slot's width (its cut edges' median span across
#: its line) of the line ends the slot ...
TIP_BLOCK = 0.3
#: ... and a cut edge's midpoint must be this share of the width clear of every point.
TIP_CLEARANCE = 0.4

#: Crossings are cut only where they line up (as in screen 2) over this many spacings: a
#: random sampling's chance strips line up over at most 7.3 (bump and plane, random 100k),
#: the slit's slot over 12.6-38 (2k-20k).
MIN_CUT_EXTENT = 9.0

#: A crossing that does not line up with others is still cut when its strip is empty
#: over this length (local spacings): a slot the K nearest neighbours bridge only here and
#: there (slit, jittered 20k: 28 edges across, scattered over its 95 spacings, none in a
#: run of 9) is long and straight; a random sampling's chance strips of this length are
#: rare, though not rare enough alone (see :data:`MIN_SUPPORT_EXTENT`).
LONE_STRIP_LENGTH = 16.0
#: Neighbours the long strip is judged on (they reach about 12 spacings).
LONE_NEIGHBOURS = 512
#: ... and such a crossing needs others along its strip, their midpoints spanning this
#: many spacings (see :func:`_supported`).
MIN_SUPPORT_EXTENT = 3.0

#: The strip: at least this wide across (local spacings) ...
MIN_WIDTH = 1.25
#: ... empty but for this share of its width at each side ...
MARGIN = 0.1
#: ... over this length along it, half on each side of the edge.
STRIP_LENGTH = 8.0
#: The strip must be lined by points on both sides at both ends (within this many spacings
#: of its sides, from this share of its half length on): a strip that runs off the
#: surface across its boundary is empty on the outside half without being a slot.
FLANK_WIDTH = 2.0
FLANK_FROM = 0.75
#: Strip directions tried, evenly spread over 180 degrees from the edge's own normal
#: direction. With 24 from the tangent frame's first axis, detection depended on the
#: pose: the generated slit lies along x, one of the 24, and in 9 random rotations
#: (random/graded/jittered x 2k/20k) the slot was found on 8 of 18 cases; with 48 relative
#: to the edge, on 17 of 18, as in the axis-aligned pose.
N_ORIENTATIONS = 48
#: Neighbours per examined point that the emptiness is judged on (they reach about
#: 6 spacings, the strip's half length plus the edge's).
STRIP_NEIGHBOURS = 128
#: Candidates per examined point, in units of K: a row whose edges across are cut is
#: filled up from these.
POOL_FACTOR = 3
#: No edge is cut when more than this share of the points are ends of the edges screen
#: 1b passed, or are to be examined after screen 2: a slot is a line through the
#: surface, while an anisotropic sampling (scan lines 3-5 spacings apart) is "slots"
#: everywhere. There every cut was undone after the walk (``reverted``), and linking the
#: crossings took 77 of 78 s (9,947 points, lines 3 spacings apart: 54k crossings) or
#: more memory than the machine had (8,330 points, 15 apart, k_nn=48: 24 GB).
#: Shares before and after screen 2 where a slot was cut: up to 0.17 and 0.136 (slit,
#: random, graded and jittered, 2k and 20k); a random sampling without one reaches 0.19
#: and 0.18 (fold and bump, random); scan lines 5 spacings apart 0.45 and 0.44, 3 apart 0.99.
MAX_EXAMINED_SHARE = 0.3


@numba.njit(cache=_CACHE)
def _clear_of(points, indices, a, i, j, cx, cy, cz, r2):
    """Whether every neighbour of ``a`` but ``i`` and ``j`` lies at least sqrt(r2) from c."""
    for m in range(indices.shape[1]):
        q = indices[a, m]
        if q == i or q == j:
            continue
        ex, ey, ez = points[q, 0] - cx, points[q, 1] - cy, points[q, 2] - cz
        if ex * ex + ey * ey + ez * ez < r2:
            return False
    return True


@numba.njit(parallel=True, cache=_CACHE)
def _void_edges(points, indices, h, min_length, clearance, out):
    n, k = indices.shape
    for r in numba.prange(n):
        i = np.int64(r)
        for c in range(k):
            j = indices[i, c]
            dx, dy, dz = points[j, 0] - points[i, 0], points[j, 1] - points[i, 1], points[j, 2] - points[i, 2]
            if dx * dx + dy * dy + dz * dz < (min_length * h[i]) ** 2:
                continue
            cx = 0.5 * (points[i, 0] + points[j, 0])
            cy = 0.5 * (points[i, 1] + points[j, 1])
            cz = 0.5 * (points[i, 2] + points[j, 2])
            r2 = (clearance * h[i]) ** 2
            out[i, c] = (_clear_of(points, indices, i, i, j, cx, cy, cz, r2)
                         and _clear_of(points, indices, j, i, j, cx, cy, cz, r2))


@numba.njit(parallel=True, cache=_CACHE)
def _in_plane_share(points, indices, distances, normals, out):
    n, k = indices.shape
    for r in numba.prange(n):
        i = np.int64(r)
        planar = 0.0
        full = 0.0
        for c in range(k):
            j = indices[i, c]
            off = ((points[j, 0] - points[i, 0]) * normals[i, 0] + (points[j, 1] - points[i, 1]) * normals[i, 1]
                   + (points[j, 2] - points[i, 2]) * normals[i, 2])
            d = distances[i, c]
            planar += np.sqrt(max(d * d - off * off, 0.0))
            full += d
        out[i] = planar / full if full > 0.0 else 1.0


def in_plane_share(points: np.ndarray, graph: KnnGraph, normals: np.ndarray) -> np.ndarray:
    """How much of the kNN spacing lies in the tangent plane, averaged over each point's ring.

    Normal noise lengthens every kNN edge (by about sqrt(1 + 2 s^2) at noise s spacings)
    without widening a slot in the tangent plane, so a spacing measured in 3D understates
    how many spacings wide the slot is: the slit's slot, 2 spacings wide, was not found
    at noise 0.35 and 0.5 (jittered 2k); at 0.5 it was with the unit scaled by 0.8 (seeds
    0 and 1). The strip test measures in the tangent plane, so its unit must too.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    graph : KnnGraph
    normals : (N, 3) numpy.ndarray of float64
        Unit normals.

    Returns
    -------
    (N,) numpy.ndarray of float64
        Mean in-plane kNN distance over mean kNN distance, in (0, 1]; averaged once over
        each point and its K neighbours.
    """
    share = np.empty(graph.indices.shape[0])
    _in_plane_share(points, graph.indices, graph.distances, np.ascontiguousarray(normals, dtype=np.float64), share)
    return (share + share[graph.indices].sum(axis=1)) / (graph.indices.shape[1] + 1)


def void_edges(points: np.ndarray, graph: KnnGraph, h: np.ndarray, *, min_length: float = MIN_LENGTH,
               clearance: float = CLEARANCE) -> np.ndarray:
    """Screen 1: long kNN edges whose midpoint has no neighbour of either end nearby.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    graph : KnnGraph
        K nearest neighbours of ``points``.
    h : (N,) numpy.ndarray of float64
        Local spacing of each point (length units).
    min_length, clearance : float
        In units of the row's local spacing.

    Returns
    -------
    (N, K) numpy.ndarray of bool
        Edge ``i -> graph.indices[i, c]`` passes.
    """
    out = np.zeros(graph.indices.shape, dtype=bool)
    _void_edges(points, graph.indices, np.ascontiguousarray(h, dtype=np.float64), float(min_length),
                float(clearance), out)
    return out


def _link_groups(midpoints: np.ndarray, directions: np.ndarray, spacing: np.ndarray,
                 link: float = LINK) -> tuple[int, np.ndarray]:
    """Connected groups of edges linked as :func:`elongated_groups` describes: (count, label per edge)."""
    e = midpoints.shape[0]
    h = float(np.median(spacing))
    pairs = cKDTree(midpoints).query_pairs(link * h, output_type="ndarray")
    a, b = pairs[:, 0], pairs[:, 1]
    cos = np.einsum("ei,ei->e", directions[a], directions[b])
    aligned = np.abs(cos) >= ALIGNED
    # Across both edges: their mean direction (the slot's normal where they cross one).
    across = directions[a] + np.sign(cos)[:, None] * directions[b]
    across /= np.maximum(np.linalg.norm(across, axis=1), 1e-300)[:, None]
    step = midpoints[b] - midpoints[a]
    side = np.abs(np.einsum("ei,ei->e", step, across)) <= SIDE_STEP * h
    a, b = a[aligned & side], b[aligned & side]
    adj = sp.coo_matrix((np.ones(a.size), (a, b)), shape=(e, e))
    return connected_components(adj, directed=False)


def elongated_groups(midpoints: np.ndarray, directions: np.ndarray, spacing: np.ndarray, *, link: float = LINK,
                     min_extent: float = MIN_EXTENT) -> np.ndarray:
    """Screen 2: edges that line up, side by side, over ``min_extent`` spacings.

    Two edges are linked when their midpoints lie within ``link`` spacings, their
    directions agree (``|cos| >= ALIGNED``: the edges across a slot lean up to about 45
    degrees either way) and the step between the midpoints runs across them (along
    their mean direction it is at most ``SIDE_STEP`` spacings), as the midpoints of the
    edges across a slot line up along it.

    Parameters
    ----------
    midpoints : (E, 3) numpy.ndarray of float64
    directions : (E, 3) numpy.ndarray of float64
        Unit edge directions (sign does not matter).
    spacing : (E,) numpy.ndarray of float64
        Local spacing at each midpoint.
    link, min_extent : float
        In spacings (the median of ``spacing``, and each group's median).

    Returns
    -------
    (E,) numpy.ndarray of bool
        The edges of linked groups whose midpoints span at least ``min_extent`` times
        the group's median spacing along the group's principal direction.
    """
    e = midpoints.shape[0]
    if e < 2:
        return np.zeros(e, dtype=bool)
    n_groups, label = _link_groups(midpoints, directions, spacing, link)
    count = np.bincount(label, minlength=n_groups).astype(float)
    centre = np.stack([np.bincount(label, midpoints[:, d], n_groups) for d in range(3)], axis=1) / count[:, None]
    q = midpoints - centre[label]
    cov = np.zeros((n_groups, 3, 3))
    for i in range(3):
        for j in range(i, 3):
            cov[:, i, j] = cov[:, j, i] = np.bincount(label, q[:, i] * q[:, j], n_groups)
    axis = np.linalg.eigh(cov)[1][:, :, -1]
    along = np.einsum("ei,ei->e", q, axis[label])
    lo = np.full(n_groups, np.inf)
    hi = np.full(n_groups, -np.inf)
    np.minimum.at(lo, label, along)
    np.maximum.at(hi, label, along)
    order = np.lexsort((spacing, label))
    start = np.searchsorted(label[order], np.arange(n_groups))
    median_h = spacing[order][start + (count.astype(np.int64) - 1) // 2]
    return ((hi - lo) >= min_extent * median_h)[label]


@numba.njit(cache=_CACHE)
def _frame(nx, ny, nz):
    """An orthonormal tangent basis (e1, e2) of the unit normal n."""
    if abs(nx) < 0.9:
        ax, ay, az = 1.0, 0.0, 0.0
    else:
        ax, ay, az = 0.0, 1.0, 0.0
    d = ax * nx + ay * ny + az * nz
    e1x, e1y, e1z = ax - d * nx, ay - d * ny, az - d * nz
    norm = np.sqrt(e1x * e1x + e1y * e1y + e1z * e1z)
    e1x, e1y, e1z = e1x / norm, e1y / norm, e1z / norm
    return e1x, e1y, e1z, ny * e1z - nz * e1y, nz * e1x - nx * e1z, nx * e1y - ny * e1x


@numba.njit(cache=_CACHE)
def _lined(xs, ys, cx, cy, ax, ay, bx, by, lo, hi, cover, h, half_length):
    """Whether neighbours line the strip on both sides beside both its far ends."""
    flanks = 0  # bit: near (u <= lo) or far side, positive or negative end
    for m in range(xs.shape[0]):
        u = xs[m] * bx + ys[m] * by
        v = (xs[m] - cx) * ax + (ys[m] - cy) * ay
        if abs(v) < FLANK_FROM * half_length or abs(v) > cover:
            continue
        if lo - FLANK_WIDTH * h < u <= lo:
            flanks |= 1 if v > 0 else 4
        elif hi <= u < hi + FLANK_WIDTH * h:
            flanks |= 2 if v > 0 else 8
        if flanks == 15:
            return True
    return False


@numba.njit(cache=_CACHE)
def _crosses_strip(qx, qy, xs, ys, reach, h, hw, min_width, margin, half_length, n_orient, lined=True):
    """The direction index of an empty strip of the neighbours (xs, ys) that 0 -> q crosses, or -1.

    ``half_length`` is in units of the local spacing ``h``, ``min_width`` in units of
    ``hw`` (at least ``h``: see :func:`slot_cut_graph`). With
    ``lined`` False the strip need not be lined by neighbours (the screen on the graph's
    two-ring, which does not reach the strip's ends).
    """
    half_length = half_length * h
    if qx * qx + qy * qy < (min_width * hw) ** 2:
        return -1
    cx, cy = 0.5 * qx, 0.5 * qy
    cn = np.sqrt(cx * cx + cy * cy)
    # Directions relative to the edge (the straight crossing first), not to the tangent
    # frame's axes: with the frame's, the slit's graded 100k slot was found in the raw pose
    # and missed in the unit pose the methods get (the cuts undone), a direction 3.75 degrees
    # off drifting a quarter spacing over the strip's half length.
    phi0 = np.arctan2(qy, qx) + 0.5 * np.pi
    for o in range(n_orient):
        phi = phi0 + np.pi * o / n_orient
        ax, ay = np.cos(phi), np.sin(phi)
        bx, by = -ay, ax
        delta = qx * bx + qy * by
        if delta < 0:
            bx, by, delta = -bx, -by, -delta
        if delta < min_width * hw:
            continue
        # The neighbours cover the strip this far each way from the edge's midpoint.
        cover = np.sqrt(max(reach * reach - delta * delta, 0.0)) - cn
        if cover < half_length:
            continue
        lo, hi = margin * delta, (1.0 - margin) * delta
        # Empty: no neighbour inside the strip within half_length of the edge (the nearest
        # neighbours come first, and most strips are refuted by one of them).
        empty = True
        for m in range(xs.shape[0]):
            u = xs[m] * bx + ys[m] * by
            if lo < u < hi and abs((xs[m] - cx) * ax + (ys[m] - cy) * ay) < half_length:
                empty = False
                break
        if empty and (not lined or _lined(xs, ys, cx, cy, ax, ay, bx, by, lo, hi, cover, h, half_length)):
            return o
    return -1


@numba.njit(parallel=True, cache=_CACHE)
def _two_ring_screen(points, normals, indices, a, b, h, hw, min_width, margin, half_length, n_orient, out):
    k = indices.shape[1]
    for e in numba.prange(a.shape[0]):
        i, j = a[e], b[e]
        e1x, e1y, e1z, e2x, e2y, e2z = _frame(normals[i, 0], normals[i, 1], normals[i, 2])
        xs = np.empty(k + k * k)
        ys = np.empty(k + k * k)
        m = 0
        for s in range(k):
            q = indices[i, s]
            for t in range(-1, k):
                w = q if t < 0 else indices[q, t]
                if w == i:
                    continue
                dx, dy, dz = points[w, 0] - points[i, 0], points[w, 1] - points[i, 1], points[w, 2] - points[i, 2]
                xs[m] = dx * e1x + dy * e1y + dz * e1z
                ys[m] = dx * e2x + dy * e2y + dz * e2z
                m += 1
        dx, dy, dz = points[j, 0] - points[i, 0], points[j, 1] - points[i, 1], points[j, 2] - points[i, 2]
        out[e] = _crosses_strip(dx * e1x + dy * e1y + dz * e1z, dx * e2x + dy * e2y + dz * e2z, xs[:m], ys[:m],
                                np.inf, h[i], hw[i], min_width, margin, half_length, n_orient, False) >= 0


@numba.njit(cache=_CACHE)
def _in_frame(points, i, members, e1x, e1y, e1z, e2x, e2y, e2z):
    """Tangent coordinates (x, y) of ``points[members] - points[i]`` in the frame (e1, e2)."""
    xs = np.empty(members.shape[0])
    ys = np.empty(members.shape[0])
    for m in range(members.shape[0]):
        j = members[m]
        dx, dy, dz = points[j, 0] - points[i, 0], points[j, 1] - points[i, 1], points[j, 2] - points[i, 2]
        xs[m] = dx * e1x + dy * e1y + dz * e1z
        ys[m] = dx * e2x + dy * e2y + dz * e2z
    return xs, ys


@numba.njit(parallel=True, cache=_CACHE)
def _strip_crossings(points, normals, rows, pool, around, reach, h, hw, min_width, margin, half_length, n_orient,
                     out):
    for r in numba.prange(rows.shape[0]):
        i = rows[r]
        e1x, e1y, e1z, e2x, e2y, e2z = _frame(normals[i, 0], normals[i, 1], normals[i, 2])
        xs, ys = _in_frame(points, i, around[r], e1x, e1y, e1z, e2x, e2y, e2z)
        px, py = _in_frame(points, i, pool[r], e1x, e1y, e1z, e2x, e2y, e2z)
        n_pool = pool.shape[1]
        for c in range(n_pool):
            o = _crosses_strip(px[c], py[c], xs, ys, reach[r], h[i], hw[i], min_width, margin, half_length, n_orient)
            out[r, c] = o >= 0


def strip_crossings(points: np.ndarray, normals: np.ndarray, rows: np.ndarray, pool: np.ndarray,
                    around: np.ndarray, reach: np.ndarray, h: np.ndarray,
                    h_width: np.ndarray | None = None, length: float = STRIP_LENGTH) -> np.ndarray:
    """Which edges ``rows[r] -> pool[r, c]`` cross an empty strip (see the module docstring).

    Parameters
    ----------
    points, normals : (N, 3) numpy.ndarray of float64
        Points and unit normals (the tangent planes the strips lie in).
    rows : (R,) numpy.ndarray of int64
        The points examined.
    pool : (R, C) numpy.ndarray of int64
        Their candidate neighbours.
    around : (R, M) numpy.ndarray of int64
        Their nearest neighbours, on which emptiness is judged.
    reach : (R,) numpy.ndarray of float64
        Distance of each row's farthest member of ``around``: no strip is judged beyond it.
    h : (N,) numpy.ndarray of float64
        Local spacing: the unit of the strip's length.
    h_width : (N,) numpy.ndarray of float64, optional
        The unit of the strip's width; ``h`` when omitted.
    length : float
        The strip's length, in units of ``h``.

    Returns
    -------
    (R, C) numpy.ndarray of bool
    """
    out = np.zeros(pool.shape, dtype=bool)
    if rows.size:
        _strip_crossings(points, normals, rows, pool, around, reach, h, h if h_width is None else h_width, MIN_WIDTH,
                         MARGIN, 0.5 * float(length), N_ORIENTATIONS, out)
    return out


def slot_cut_graph(points: np.ndarray, graph: KnnGraph, normals: np.ndarray, h: np.ndarray,
                   h_ring: np.ndarray | None = None) -> tuple[KnnGraph, dict, np.ndarray | None]:
    """The K nearest neighbours without the edges that cross a slot.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    graph : KnnGraph
        K nearest neighbours (any graph whose rows are nearest first).
    normals : (N, 3) numpy.ndarray of float64
        Unit normals (orientation does not matter).
    h : (N,) numpy.ndarray of float64
        Local spacing of each point (smooth: the unit of lengths).
    h_ring : (N,) numpy.ndarray of float64, optional
        ``local_spacing(graph, passes=1)`` when the caller has it (computed otherwise).

    Returns
    -------
    graph : KnnGraph
        ``graph`` itself when no edge crosses a slot; otherwise the rows of the points
        whose edges were cut hold their K nearest candidates (of
        :data:`POOL_FACTOR` K) that cross no slot, nearest first.
    diagnostics : dict
        ``n_void_edges`` (screen 1, undirected), ``n_short_strips`` (screen 1b),
        ``n_examined_points`` (after screen 2), ``widespread`` (True when the ends of the
        screen 1b edges or the examined points are more than :data:`MAX_EXAMINED_SHARE`
        of the points: nothing is cut),
        ``n_lone_crossings`` (crossings of a strip that did not line up with others over
        :data:`MIN_CUT_EXTENT` spacings nor cross one :data:`LONE_STRIP_LENGTH` long:
        left), ``n_scattered_crossings`` (edges screen 2 left out that cross a strip
        :data:`LONE_STRIP_LENGTH` long: cut), ``n_tip_edges`` (edges cut near the slots'
        ends, :func:`_tip_crossings`), ``n_slot_edges`` (distinct edges cut).
    lips : (N,) numpy.ndarray of bool or None
        The ends of the cut edges (the slots' lips); None when none was cut.
    """
    n, k = graph.indices.shape
    # A smoothed spacing lags behind where the density changes fast (graded samplings):
    # on the sparse side it is too small, and the sampling's own gaps there look like
    # strips (bump, graded 2k: 26 edges cut, the map worse). Widths are measured against
    # the larger of it and the spacing over one ring, which follows the density closely;
    # lengths against the smooth one (128 neighbours reach 4 of them).
    h_width = np.maximum(h, local_spacing(graph, passes=1) if h_ring is None else h_ring)
    share = in_plane_share(points, graph, normals)
    h, h_width = h * share, h_width * share
    void = void_edges(points, graph, h_width)
    r, c = np.nonzero(void)
    j = graph.indices[r, c]
    # Each undirected edge once (the screen is symmetric up to the two ends' spacings).
    first = np.unique(np.minimum(r, j) * n + np.maximum(r, j), return_index=True)[1]
    r, j = r[first], j[first]
    diagnostics = {"n_void_edges": int(r.size), "n_short_strips": 0, "n_examined_points": 0, "n_lone_crossings": 0,
                   "n_scattered_crossings": 0, "n_tip_edges": 0, "n_slot_edges": 0, "widespread": False}
    # Screen 1b: a shorter strip, empty among the points two graph steps from r: a
    # necessary condition of the strip test that needs no kd-tree search.
    short = np.zeros(r.size, dtype=bool)
    _two_ring_screen(points, normals, graph.indices, r, j, h, h_width, MIN_WIDTH, MARGIN, SCREEN_HALF_LENGTH,
                     N_ORIENTATIONS, short)
    r, j = r[short], j[short]
    diagnostics["n_short_strips"] = int(r.size)
    if r.size == 0:
        return graph, diagnostics, None
    if np.unique(np.concatenate([r, j])).size > MAX_EXAMINED_SHARE * n:
        diagnostics["widespread"] = True
        return graph, diagnostics, None
    grouped = _edge_groups(points, r, j, h, MIN_EXTENT)
    rows = np.unique(np.concatenate([r[grouped], j[grouped]]))
    diagnostics["n_examined_points"] = int(rows.size)
    diagnostics["widespread"] = bool(rows.size > MAX_EXAMINED_SHARE * n)
    m = min(n - 1, STRIP_NEIGHBOURS)
    if m <= k or diagnostics["widespread"]:
        return graph, diagnostics, None
    tree = cKDTree(points)
    c_pool = min(m, POOL_FACTOR * k)
    a, b, n_lone, la, lb, pool, pool_dist = _examined_crossings(points, normals, tree, rows, h, h_width, m, c_pool)
    # Screen 2 left out the edges with no other beside them: where the K nearest
    # neighbours bridge a slot only here and there (slit, jittered 20k), a crossing is cut
    # when its strip is long and another crossing lies along it.
    scattered = np.flatnonzero(~grouped)
    long = _long_strips(points, normals, tree, r[scattered], j[scattered], h, h_width)
    sa, sb = r[scattered][long], j[scattered][long]
    la, lb = np.concatenate([la, sa]), np.concatenate([lb, sb])
    supported = _supported(points, a, b, la, lb, h)
    n_examined_long = la.size - sa.size
    diagnostics["n_lone_crossings"] = n_lone - int(supported[:n_examined_long].sum())
    diagnostics["n_scattered_crossings"] = int(supported[n_examined_long:].sum())
    a, b = np.concatenate([a, la[supported]]), np.concatenate([b, lb[supported]])
    if a.size == 0:
        return graph, diagnostics, None
    ta, tb = _tip_crossings(points, tree, a, b, h, h_width, c_pool)
    diagnostics["n_tip_edges"] = int(ta.size)
    a, b = np.concatenate([a, ta]), np.concatenate([b, tb])
    ends = np.concatenate([a, b])
    pairs = np.unique(np.concatenate([a * n + b, b * n + a]))
    diagnostics["n_slot_edges"] = int(pairs.size // 2)
    # The cut is symmetric: an end that was not examined gets its own candidates.
    touched = np.unique(ends)
    extra = np.setdiff1d(touched, rows)
    if extra.size:
        x_dist, x_near = tree.query(points[extra], k=c_pool + 1, workers=-1)
        rows = np.concatenate([rows, extra])
        pool = np.concatenate([pool, x_near[:, 1:]])
        pool_dist = np.concatenate([pool_dist, x_dist[:, 1:]])
    at = np.searchsorted(rows, touched, sorter=np.argsort(rows))
    at = np.argsort(rows)[at]
    lips = np.zeros(n, dtype=bool)
    lips[touched] = True
    return _refilled(graph, touched, pool[at], pool_dist[at], pairs), diagnostics, lips


def slots_on_loops(lips: np.ndarray, graph: KnnGraph, boundary: np.ndarray, *,
                   min_share: float = MIN_ON_LOOP) -> bool:
    """Whether the boundary found on the cut graph runs along the cuts.

    Parameters
    ----------
    lips : (N,) numpy.ndarray of bool
        Ends of the cut edges (:func:`slot_cut_graph`).
    graph : KnnGraph
        The cut graph.
    boundary : (N,) numpy.ndarray of bool
        Points on the boundary loops found with ``graph``.
    min_share : float
        Share of the cut edges' ends that must lie on a loop or next to one (a kNN
        neighbour on it).

    Returns
    -------
    bool
        True when at least ``min_share`` of the cut ends are on or next to a loop (or
        nothing was cut).
    """
    ends = np.flatnonzero(lips)
    if ends.size == 0:
        return True
    near = boundary[ends] | boundary[graph.indices[ends]].any(axis=1)
    return bool(near.mean() >= min_share)


def cut_ends(before: KnnGraph, after: KnnGraph) -> np.ndarray:
    """Points that lost a kNN edge in the cut, and the other ends of those edges.

    Unlike the cut's ``lips`` (:func:`slot_cut_graph`, which also holds the ends of the
    cut candidates beyond the K nearest: the lips' second rows), these are the points
    whose own neighbourhoods reached across, the slot's front rows.

    Parameters
    ----------
    before, after : KnnGraph
        The graph before and after :func:`slot_cut_graph`.

    Returns
    -------
    (N,) numpy.ndarray of bool
    """
    removed = ~(before.indices[:, :, None] == after.indices[:, None, :]).any(axis=2)
    ends = removed.any(axis=1)
    ends[before.indices[removed]] = True
    return ends


def _tip_crossings(points: np.ndarray, tree: cKDTree, a: np.ndarray, b: np.ndarray, h: np.ndarray,
                   h_width: np.ndarray, n_pool: int) -> tuple[np.ndarray, np.ndarray]:
    """Edges across a slot within its last strip half-length, where the strip test cannot see.

    The strip test wants the strip empty :data:`STRIP_LENGTH` / 2 each way, so the last
    4 spacings of a slot at each end keep their edges across: the boundary walk then
    loses the lips there (recall) or wanders off at the end. Near each end of a group of
    cut edges (from :data:`TIP_REACH` spacings before it to :data:`TIP_EXTENT` beyond),
    an edge is cut too when its ends lie on the
    two sides of the group's line (fitted to the cut edges' midpoints within
    :data:`TIP_REACH` of the end), its midpoint is on that line (within half a
    spacing), before the first point on the line beyond the last cut (within
    :data:`TIP_BLOCK` of the slot's width: where the slot ends), and no point lies
    within :data:`TIP_CLEARANCE` of the width of the midpoint. The edges examined are
    each nearby point's ``n_pool`` nearest.

    Returns
    -------
    a, b : (T,) numpy.ndarray of int64
        Ends of the further edges to cut.
    """
    direction = points[b] - points[a]
    direction /= np.linalg.norm(direction, axis=1)[:, None]
    mid = 0.5 * (points[a] + points[b])
    # The cut edges are slot crossings already: where the K nearest neighbours bridge a
    # slot only here and there, they lie up to a long strip apart along it.
    n_groups, label = _link_groups(mid, direction, 0.5 * (h[a] + h[b]), link=LONE_STRIP_LENGTH)
    found_a, found_b = [], []
    for g in range(n_groups):
        members = np.flatnonzero(label == g)
        if members.size < 2:
            continue
        hg = float(np.median(h[a[members]]))
        m = mid[members]
        axis = np.linalg.eigh((m - m.mean(0)).T @ (m - m.mean(0)))[1][:, -1]
        t = (m - m.mean(0)) @ axis
        for end, sign in ((np.argmax(t), 1.0), (np.argmin(t), -1.0)):
            near_end = np.abs(t - t[end]) <= TIP_REACH * hg
            local = m[near_end]
            line_axis = axis if local.shape[0] < 3 else np.linalg.eigh(
                (local - local.mean(0)).T @ (local - local.mean(0)))[1][:, -1]
            line_axis = line_axis * np.sign(line_axis @ axis) * sign  # towards the tip
            lean = direction[members][near_end]
            across = lean * np.sign(lean @ direction[members[end]])[:, None]
            across = across.mean(0) - (across.mean(0) @ line_axis) * line_axis
            across /= np.linalg.norm(across)
            origin = local.mean(0)
            edges = members[near_end]
            width = float(np.median(np.abs((points[b[edges]] - points[a[edges]]) @ across)))
            rows = np.asarray(tree.query_ball_point(m[end], (TIP_EXTENT + TIP_REACH) * hg), dtype=np.int64)
            if rows.size < 2:
                continue
            # The slot ends at the first point on its line beyond the last cut.
            ahead = (points[rows] - m[end]) @ line_axis
            on_line = (np.abs((points[rows] - origin) @ across) < TIP_BLOCK * width) & (ahead > 0)
            tip = float(ahead[on_line].min()) if on_line.any() else TIP_EXTENT * hg
            k = min(points.shape[0] - 1, n_pool)
            _, pool = tree.query(points[rows], k=k + 1)
            i = np.repeat(rows, k)
            j = pool[:, 1:].ravel()
            side_i = (points[i] - origin) @ across
            side_j = (points[j] - origin) @ across
            c = 0.5 * (points[i] + points[j])
            off_line = np.abs((c - origin) @ across)
            along = (c - m[end]) @ line_axis
            ok = ((side_i * side_j < 0) & (off_line <= 0.5 * hg) & (along > -TIP_REACH * hg)
                  & (along < min(tip, TIP_EXTENT * hg)))
            if not ok.any():
                continue
            i, j, c = i[ok], j[ok], c[ok]
            dist, idx = tree.query(c, k=3)
            nearest = np.where((idx[:, 0] == i) | (idx[:, 0] == j),
                               np.where((idx[:, 1] == i) | (idx[:, 1] == j), dist[:, 2], dist[:, 1]), dist[:, 0])
            clear = nearest >= TIP_CLEARANCE * width
            found_a.append(i[clear])
            found_b.append(j[clear])
    if not found_a:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    return np.concatenate(found_a), np.concatenate(found_b)


def _examined_crossings(points: np.ndarray, normals: np.ndarray, tree: cKDTree, rows: np.ndarray, h: np.ndarray,
                        h_width: np.ndarray, m: int, c_pool: int):
    """The strip test on the examined points' nearest ``c_pool``.

    Returns the crossings (a, b) that line up over :data:`MIN_CUT_EXTENT`, how many do
    not, those of them that cross a strip :data:`LONE_STRIP_LENGTH` long (la, lb), and the
    pools (rows x ``c_pool`` indices and distances).
    """
    empty = np.zeros(0, dtype=np.int64)
    if rows.size == 0:
        return empty, empty, 0, empty, empty, np.zeros((0, c_pool), dtype=np.int64), np.zeros((0, c_pool))
    dist, near = tree.query(points[rows], k=m + 1, workers=-1)
    around, reach = np.ascontiguousarray(near[:, 1:]), dist[:, -1]
    pool, pool_dist = np.ascontiguousarray(around[:, :c_pool]), dist[:, 1:c_pool + 1]
    cr, cc = np.nonzero(strip_crossings(points, normals, rows, pool, around, reach, h, h_width))
    a, b = rows[cr], pool[cr, cc]
    # A slot gives crossings all along it; one empty strip of a random sampling (at the
    # threshold, a chance of about e^-11 per place and direction) gives a short run.
    lined_up = _edge_groups(points, a, b, h, MIN_CUT_EXTENT) if a.size else np.zeros(0, dtype=bool)
    la, lb = a[~lined_up], b[~lined_up]
    long = _long_strips(points, normals, tree, la, lb, h, h_width)
    return a[lined_up], b[lined_up], int(la.size), la[long], lb[long], pool, pool_dist


def _supported(points: np.ndarray, a: np.ndarray, b: np.ndarray, la: np.ndarray, lb: np.ndarray,
               h: np.ndarray) -> np.ndarray:
    """Which long-strip crossings ``la``-``lb`` have another crossing along their strip.

    A random sampling does leave a strip :data:`LONE_STRIP_LENGTH` long empty now and
    then (cap and saddle, random 20k seed 1: one edge each, 24-94 spacings from the
    boundary), but not two on one line: a crossing is kept when, linked with all the
    others (``a``-``b`` and the long ones) as :func:`elongated_groups` links them but
    over the long strip's length, its group's midpoints span :data:`MIN_SUPPORT_EXTENT`
    spacings.
    """
    if la.size == 0:
        return np.zeros(0, dtype=bool)
    ea, eb = np.concatenate([a, la]), np.concatenate([b, lb])
    direction = points[eb] - points[ea]
    direction /= np.linalg.norm(direction, axis=1)[:, None]
    spread = elongated_groups(0.5 * (points[ea] + points[eb]), direction, 0.5 * (h[ea] + h[eb]),
                              link=LONE_STRIP_LENGTH, min_extent=MIN_SUPPORT_EXTENT)
    return spread[a.size:]


def _long_strips(points: np.ndarray, normals: np.ndarray, tree: cKDTree, a: np.ndarray, b: np.ndarray, h: np.ndarray,
                 h_width: np.ndarray) -> np.ndarray:
    """Which edges ``a[e]``-``b[e]`` cross a strip :data:`LONE_STRIP_LENGTH` long (judged from ``a``)."""
    if a.size == 0:
        return np.zeros(0, dtype=bool)
    m = min(points.shape[0] - 1, LONE_NEIGHBOURS)
    dist, near = tree.query(points[a], k=m + 1, workers=-1)
    return strip_crossings(points, normals, a, np.ascontiguousarray(b[:, None]), np.ascontiguousarray(near[:, 1:]),
                           dist[:, -1], h, h_width, length=LONE_STRIP_LENGTH)[:, 0]


def _edge_groups(points: np.ndarray, a: np.ndarray, b: np.ndarray, h: np.ndarray, min_extent: float) -> np.ndarray:
    """:func:`elongated_groups` of the edges ``a[e]``-``b[e]``."""
    direction = points[b] - points[a]
    direction /= np.linalg.norm(direction, axis=1)[:, None]
    return elongated_groups(0.5 * (points[a] + points[b]), direction, 0.5 * (h[a] + h[b]), min_extent=min_extent)


def _refilled(graph: KnnGraph, rows: np.ndarray, pool: np.ndarray, pool_dist: np.ndarray,
              pairs: np.ndarray) -> KnnGraph:
    """``graph`` whose ``rows`` lose their edges in ``pairs`` and fill up from ``pool``.

    A row keeps its uncut members and takes pool members beyond its farthest one (so the
    edges a gap-aware graph left out stay out), its K nearest in all. A row left with
    fewer than K fills up with its nearest cut edges (the graph stays K-regular).
    """
    n, k = graph.indices.shape
    indices, distances = graph.indices.copy(), graph.distances.copy()
    cand = np.concatenate([indices[rows], pool], axis=1)
    dist = np.concatenate([distances[rows], pool_dist], axis=1)
    beyond = np.concatenate([np.ones((rows.size, k), dtype=bool), pool_dist > distances[rows, -1:]], axis=1)
    cut = np.isin(rows[:, None] * n + cand, pairs)
    rank = np.where(beyond & ~cut, 0, np.where(beyond, 1, 2))  # kept, then cut, never skipped pool members
    order = np.lexsort((dist, rank), axis=1)[:, :k]
    sel, sel_dist = np.take_along_axis(cand, order, axis=1), np.take_along_axis(dist, order, axis=1)
    resort = np.argsort(sel_dist, axis=1, kind="stable")
    indices[rows] = np.take_along_axis(sel, resort, axis=1)
    distances[rows] = np.take_along_axis(sel_dist, resort, axis=1)
    return KnnGraph(indices=indices, distances=distances, mean_spacing=float(distances.mean()))
