"""Discrete exponential map (DEM, Eq. 8) and its upwind average (Eq. 9), for every point.

For each centre s a Dijkstra front walks the neighbourhood graph (edge length = Euclidean
distance). Every point p it finalises gets tangent coordinates at s, evaluated in-line:

* plain DEM (Eq. 8): ``T_s p = T_s q + M_qs T_q p`` with q the Dijkstra predecessor of p;
* upwind average (Eq. 9): the same estimate from every already-finalised graph
  neighbour q_i of p, averaged with weights ``w = 1 / (|p - q_i|^2 + 1e-6 l^2)`` (the
  small offset only guards near-coincident points).

``M_qs`` is the minimal rotation taking q's normal to s's normal, followed by the
tangent frame of s (:func:`parambench.methods.pointset.normals.tangent_frames`). As in the authors'
code, an estimate whose squared length is off by more than 75% from the squared front
distance is rescaled to that distance (a guard against catastrophic propagation).

Two refinements, both on by default and both switchable back to the paper's form
(``projection="length"``, ``front_weight=False``):

* ``projection="midpoint"``: ``T_q p`` projects ``p - q`` onto the plane normal to
  ``n_q + n_p`` (then rotates from that normal to ``n_s``) instead of onto q's tangent
  plane rescaled to ``|p - q|``. On a smooth surface the chord is perpendicular to the
  bisecting normal, so its length is kept just as by the paper's length-preserving
  projection, but a normal offset from noise is dropped instead of being turned into
  tangential length (the paper's rescaling inflates short noisy edges, which the
  1/d^2 upwind weights favour).
* ``front_weight=True``: each upwind weight is multiplied by
  ``(d_s(p) - d_s(q_i)) / |p - q_i|`` in [0, 1], the cosine between the edge and the
  front's direction of travel, so neighbours on the same front (lateral, not upwind)
  count little; the Dijkstra predecessor always has factor 1. On curved surfaces
  lateral estimates carry a curvature bias that plain averaging spreads.

Measured RMS error against the exact log map, relative to the ball radius, on a quarter
cylinder and spherical caps (tests/methods/pointset/test_dem.py): with the refinements
and normal smoothing, the upwind average is never less accurate than the paper's plain
DEM, 10-50% more accurate than the plain DEM with the midpoint projection on jittered,
random or noisy samplings (within +3% of it on clean regular grids), and 2-4x more
accurate than the paper's form under normal noise (where the paper's own upwind
average is up to 1.8x worse than its plain DEM).

A third kind, ``dem="projected"``, keeps the balls and gives each member the plain
projection of ``p - s`` onto the centre's tangent plane, with no propagation: it differs
from the log map by O(curvature^2 radius^3), negligible on balls of 2.5 spacings (``ocp``'s
QC the same to 3e-4 on clean generated surfaces), but under normal noise it carries only
the centre normal's error instead of the error every step of a front adds (short noisy
edges, which the upwind weights favour). The front end chooses it for noisy samplings with
close pairs (:func:`parambench.methods.pointset.frontend.resolved_dem`).

The geodesic K-eps ball of s (paper Sec. 6: K = 6, eps = 2.5 l) is defined here as: the
points in Dijkstra order, s excluded, whose graph distance is <= eps, extended to the K
nearest when fewer than K are that close, and truncated at ``max_ball`` points (default
64, about twice the ball size on a regular sampling; truncation is counted in the
diagnostics). Points are stored nearest first.
"""

from __future__ import annotations

import queue
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numba
import numpy as np
import scipy.sparse as sp

from parambench.datasets_gen.errors import InvalidInputError

from ..numba_cache import configure_numba_cache
from .normals import tangent_frames
from .row_chunks import for_each_chunk

__all__ = ["GeodesicBalls", "dem_balls", "DEM_KINDS", "PROJECTIONS", "DEFAULT_MAX_BALL"]

# On-disk kernel cache where one is writable, none otherwise (see parambench.methods.numba_cache).
_CACHE, _ = configure_numba_cache(Path(__file__).resolve().parent)

DEM_KINDS = ("upwind", "plain", "projected")

#: Centres per chunk of :func:`_projected_coords` (bounded (chunk, B, 3) temporaries).
_PROJECTED_CHUNK = 16384

PROJECTIONS = ("midpoint", "length")

#: Default cap on points per ball (see the module docstring).
DEFAULT_MAX_BALL = 64

#: Centres processed per call of the compiled kernel (bounds the temporary output).
_BLOCK = 32768

#: Pieces per worker each block of centres is cut into (handed out dynamically).
_PIECES_PER_WORKER = 8

#: Relative offset of the upwind weights, in units of l^2.
_UPWIND_EPS = 1e-6

#: Largest accepted relative error of |T|^2 against the squared front distance.
_MAX_LENGTH_ERR = 0.75


@dataclass(frozen=True, eq=False)
class GeodesicBalls:
    """Tangent coordinates of every point's geodesic ball.

    Attributes
    ----------
    indices : (N, B) numpy.ndarray of int64
        Ball members of each centre, nearest (in graph distance) first, padded with -1.
    coords : (N, B, 2) numpy.ndarray of float64
        Their tangent coordinates ``T_s p`` in the centre's tangent frame; 0 at padding.
    sizes : (N,) numpy.ndarray of int64
        Members per ball (the centre itself is not a member).
    graph_dist : (N, B) numpy.ndarray of float64
        Dijkstra distances from the centre; +inf at padding.
    n_truncated : int
        Balls cut at ``max_ball`` members.
    """

    indices: np.ndarray
    coords: np.ndarray
    sizes: np.ndarray
    graph_dist: np.ndarray
    n_truncated: int

    @property
    def mask(self) -> np.ndarray:
        """(N, B) bool, True at real members."""
        return self.indices >= 0


@numba.njit(cache=_CACHE, nogil=True)
def _heap_push(keys, vals, size, key, val):
    i = size
    keys[i] = key
    vals[i] = val
    while i > 0:
        parent = (i - 1) >> 1
        if keys[parent] <= keys[i]:
            break
        keys[parent], keys[i] = keys[i], keys[parent]
        vals[parent], vals[i] = vals[i], vals[parent]
        i = parent
    return size + 1


@numba.njit(cache=_CACHE, nogil=True)
def _heap_pop(keys, vals, size):
    key = keys[0]
    val = vals[0]
    size -= 1
    keys[0] = keys[size]
    vals[0] = vals[size]
    i = 0
    while True:
        left = 2 * i + 1
        if left >= size:
            break
        child = left
        if left + 1 < size and keys[left + 1] < keys[left]:
            child = left + 1
        if keys[i] <= keys[child]:
            break
        keys[child], keys[i] = keys[i], keys[child]
        vals[child], vals[i] = vals[i], vals[child]
        i = child
    return key, val, size


@numba.njit(cache=_CACHE, nogil=True)
def _chord(points, normals, q, p, midpoint):
    """The centre-free half of ``M_qs T_q p``: T_q p in 3D and the unit normal a it is tangent to.

    ``midpoint`` False: T_q p is the projection of p - q onto q's tangent plane, rescaled
    to |p - q| (the paper's length-preserving projection), and a = n_q.
    ``midpoint`` True: p - q is projected onto the plane normal to a = n_q + n_p
    (normalised). On a smooth surface the chord is perpendicular to the bisecting normal
    up to third order, so this keeps its length like the paper's projection, but a
    normal offset from noise is dropped instead of being turned into tangential length.
    Returns (tx, ty, tz, ax, ay, az); all zero for a degenerate edge.
    """
    rx = points[p, 0] - points[q, 0]
    ry = points[p, 1] - points[q, 1]
    rz = points[p, 2] - points[q, 2]
    nqx, nqy, nqz = normals[q, 0], normals[q, 1], normals[q, 2]
    if midpoint:
        nqx += normals[p, 0]
        nqy += normals[p, 1]
        nqz += normals[p, 2]
        nn = np.sqrt(nqx * nqx + nqy * nqy + nqz * nqz)
        if nn <= 0.0:
            return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
        nqx /= nn
        nqy /= nn
        nqz /= nn
    rn = rx * nqx + ry * nqy + rz * nqz
    tx, ty, tz = rx - rn * nqx, ry - rn * nqy, rz - rn * nqz
    if not midpoint:
        lt = np.sqrt(tx * tx + ty * ty + tz * tz)
        if lt <= 0.0:
            return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
        scale = np.sqrt(rx * rx + ry * ry + rz * rz) / lt
        tx *= scale
        ty *= scale
        tz *= scale
    return tx, ty, tz, nqx, nqy, nqz


@numba.njit(cache=_CACHE, nogil=True)
def _rotate_to(tx, ty, tz, ax, ay, az, ns, e1s, e2s):
    """A vector t tangent to the unit normal a, carried to the centre's frame: (u, v).

    Minimal rotation a -> n_s applied to t (perpendicular to a):
    R t = t - (t . n_s) / (1 + a . n_s) * (a + n_s).
    """
    c = 1.0 + ax * ns[0] + ay * ns[1] + az * ns[2]
    tn = tx * ns[0] + ty * ns[1] + tz * ns[2]
    if c > 1e-12:
        f = tn / c
        tx -= f * (ax + ns[0])
        ty -= f * (ay + ns[1])
        tz -= f * (az + ns[2])
    else:  # opposite normals: no unique rotation, fall back to projection into s's plane
        tx -= tn * ns[0]
        ty -= tn * ns[1]
        tz -= tn * ns[2]
    return tx * e1s[0] + ty * e1s[1] + tz * e1s[2], tx * e2s[0] + ty * e2s[1] + tz * e2s[2]


@numba.njit(cache=_CACHE, nogil=True)
def _transport(points, normals, q, p, ns, e1s, e2s, midpoint):
    """M_qs T_q p in the centre's frame: (u, v) (:func:`_chord`, then :func:`_rotate_to`)."""
    tx, ty, tz, ax, ay, az = _chord(points, normals, q, p, midpoint)
    if ax == 0.0 and ay == 0.0 and az == 0.0:
        return 0.0, 0.0
    return _rotate_to(tx, ty, tz, ax, ay, az, ns, e1s, e2s)


@numba.njit(cache=_CACHE, nogil=True)
def _chord_rows(points, normals, indptr, nbrs, midpoint, chords, lo, hi):
    """:func:`_chord` of every graph edge of rows lo:hi: row e of ``chords`` gets (t, a) for
    the edge from ``nbrs[e]`` to its row's point (what the upwind average transports)."""
    for v in range(lo, hi):
        for e in range(indptr[v], indptr[v + 1]):
            chords[e, 0], chords[e, 1], chords[e, 2], chords[e, 3], chords[e, 4], chords[e, 5] = _chord(
                points, normals, nbrs[e], v, midpoint)


class _Cloud(NamedTuple):
    """The point set and its neighbourhood graph, read-only in the kernel.

    ``indptr``/``nbrs``/``lens`` are the CSR rows of the symmetric adjacency (edge length
    = Euclidean distance); ``e1``/``e2`` the tangent frames of ``normals``; ``chords`` row e
    the :func:`_chord` of edge e towards its row's point (upwind average only, see
    :func:`_graph_cloud`).
    """

    points: np.ndarray
    normals: np.ndarray
    e1: np.ndarray
    e2: np.ndarray
    indptr: np.ndarray
    nbrs: np.ndarray
    lens: np.ndarray
    chords: np.ndarray


class _BallRule(NamedTuple):
    """What a ball is (K, per-centre radius, cap) and how its members are estimated."""

    ball_k: int
    radii: np.ndarray
    max_ball: int
    upwind: bool
    w_eps: float
    midpoint: bool
    front_weight: bool


class _BallBlock(NamedTuple):
    """Output rows of one block of centres: members, tangent coordinates, distances, sizes."""

    idx: np.ndarray
    uv: np.ndarray
    dist: np.ndarray
    size: np.ndarray


class _Scratch(NamedTuple):
    """Per-worker Dijkstra state over all points, stamped with the row number k (see _dem_range).

    ``seen[v] == k``: v has a tentative distance ``dist[v]`` (via ``pred[v]``) in this
    row's front; ``frozen[v] == k``: v is final and ``uv[v]`` holds its ``T_s v``.
    ``ball_idx``/``ball_uv``/``ball_dist`` (``max_ball`` entries) collect the current
    row's members until its size says where the row goes.
    """

    seen: np.ndarray
    frozen: np.ndarray
    dist: np.ndarray
    pred: np.ndarray
    uv: np.ndarray
    heap_keys: np.ndarray
    heap_vals: np.ndarray
    ball_idx: np.ndarray
    ball_uv: np.ndarray
    ball_dist: np.ndarray


@numba.njit(cache=_CACHE, nogil=True)
def _dem_range(centres, start, stop, cloud, rule, store, spill, spill_offset, work):
    """DEM balls of centres[start:stop] into rows k of ``store``; returns the truncated count.

    A ball that fits the store's width is written to its row, padded; a wider one goes
    to row ``k - spill_offset`` of ``spill`` instead (unpadded) and :func:`_run_blocks`
    widens the store. ``store.size[k]`` gets every ball's size. Writing the rows here,
    on the workers, instead of copying a block buffer over afterwards saves a pass over
    the balls (~1.3 GB at a million points) and a wait for the slower worker per block.
    The scratch arrays of ``work`` are stamped with the row number k, unique per call
    even when a centre repeats, so they never need resetting.
    """
    # Unpacked once, and the loop body kept in one function: reading the arrays from the
    # tuples inside the loops, or splitting the body into kernels taking the tuples, was
    # measured 1.3-1.6x slower in CPU time (bump, 20k points).
    points, normals, e1, e2, indptr, nbrs, lens, chords = cloud
    ball_k, radii, max_ball, upwind, w_eps, midpoint, front_weight = rule
    s_idx, s_uv, s_dist, sizes = store
    p_idx, p_uv, p_dist, _ = spill
    width = s_idx.shape[1]
    seen, frozen, dist, pred, uv, heap_keys, heap_vals, ball_idx, ball_uv, ball_dist = work
    n_trunc = 0
    for k in range(start, stop):
        s = centres[k]
        radius = radii[s]
        ns = normals[s]
        e1s = e1[s]
        e2s = e2[s]
        seen[s] = k
        frozen[s] = k
        dist[s] = 0.0
        uv[s, 0] = 0.0
        uv[s, 1] = 0.0
        size = 0
        for e in range(indptr[s], indptr[s + 1]):
            u = nbrs[e]
            seen[u] = k
            dist[u] = lens[e]
            pred[u] = s
            size = _heap_push(heap_keys, heap_vals, size, lens[e], u)
        nb = 0
        while size > 0:
            d, v, size = _heap_pop(heap_keys, heap_vals, size)
            if frozen[v] == k:
                continue  # stale heap entry
            if nb >= ball_k and d > radius:
                break
            if nb >= max_ball:
                n_trunc += 1
                break
            frozen[v] = k
            if upwind:
                su = 0.0
                sv = 0.0
                wsum = 0.0
                for e in range(indptr[v], indptr[v + 1]):
                    q = nbrs[e]
                    if frozen[q] != k:
                        continue
                    du, dv = _rotate_to(chords[e, 0], chords[e, 1], chords[e, 2], chords[e, 3], chords[e, 4],
                                        chords[e, 5], ns, e1s, e2s)
                    w = 1.0 / (lens[e] * lens[e] + w_eps)
                    if front_weight:
                        w *= (d - dist[q]) / lens[e]
                    su += w * (uv[q, 0] + du)
                    sv += w * (uv[q, 1] + dv)
                    wsum += w
                tu = su / wsum
                tv = sv / wsum
            else:
                q = pred[v]
                du, dv = _transport(points, normals, q, v, ns, e1s, e2s, midpoint)
                tu = uv[q, 0] + du
                tv = uv[q, 1] + dv
            len2 = tu * tu + tv * tv
            if abs(len2 / (d * d) - 1.0) > _MAX_LENGTH_ERR and len2 > 0.0:
                f = d / np.sqrt(len2)
                tu *= f
                tv *= f
            uv[v, 0] = tu
            uv[v, 1] = tv
            ball_idx[nb] = v
            ball_uv[nb, 0] = tu
            ball_uv[nb, 1] = tv
            ball_dist[nb] = d
            nb += 1
            for e in range(indptr[v], indptr[v + 1]):
                u = nbrs[e]
                if frozen[u] == k:
                    continue
                nd = d + lens[e]
                if nd > radius and nb >= ball_k:
                    continue  # could only pop after the ball is complete: never a member
                if seen[u] != k or nd < dist[u]:
                    seen[u] = k
                    dist[u] = nd
                    pred[u] = v
                    size = _heap_push(heap_keys, heap_vals, size, nd, u)
        sizes[k] = nb
        if nb <= width:
            _put_row(s_idx, s_uv, s_dist, k, ball_idx, ball_uv, ball_dist, nb, width)
        else:
            _put_row(p_idx, p_uv, p_dist, k - spill_offset, ball_idx, ball_uv, ball_dist, nb, nb)
    return n_trunc


@numba.njit(cache=_CACHE, nogil=True)
def _put_row(d_idx, d_uv, d_dist, row, b_idx, b_uv, b_dist, m, width):
    """The m members ``b_*`` (1-D, and (m, 2) coordinates) into row ``row`` of ``d_*``, padded to ``width`` columns."""
    for j in range(m):
        d_idx[row, j] = b_idx[j]
        d_uv[row, j, 0] = b_uv[j, 0]
        d_uv[row, j, 1] = b_uv[j, 1]
        d_dist[row, j] = b_dist[j]
    for j in range(m, width):
        d_idx[row, j] = -1
        d_uv[row, j, 0] = 0.0
        d_uv[row, j, 1] = 0.0
        d_dist[row, j] = np.inf


def dem_balls(points: np.ndarray, normals: np.ndarray, adjacency: sp.csr_matrix, mean_spacing: float, *,
              ball_k: int = 6, ball_eps_factor: float = 2.5, dem: str = "upwind",
              max_ball: int = DEFAULT_MAX_BALL, projection: str = "midpoint",
              front_weight: bool = True, centres: np.ndarray | None = None,
              local_spacing: np.ndarray | None = None) -> GeodesicBalls:
    """Geodesic K-eps balls of all points with their DEM tangent coordinates.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    normals : (N, 3) numpy.ndarray of float64
        Consistently oriented unit normals used for the frames (pass smoothed normals
        for the paper's "normal smoothing").
    adjacency : (N, N) scipy.sparse.csr_matrix
        Symmetric neighbourhood graph with Euclidean edge lengths
        (:func:`parambench.methods.pointset.neighbourhoods.symmetric_adjacency`).
    mean_spacing : float
        ``l``; the ball radius is ``ball_eps_factor * l``.
    ball_k : int
        Minimum members per ball (K).
    ball_eps_factor : float
        Geodesic radius in units of ``l``.
    dem : {"upwind", "plain", "projected"}
        Upwind-average DEM (Eq. 9), the plain DEM (Eq. 8), or each member's offset
        ``p - s`` projected onto the centre's tangent plane (no propagation; the same
        balls): see :func:`parambench.methods.pointset.frontend.resolved_dem` for where it
        is the better choice.
    max_ball : int
        Cap on members per ball.
    projection : {"midpoint", "length"}
        How ``T_q p`` is formed (see the module docstring); "length" is the paper's.
    front_weight : bool
        Scale upwind weights by the edge's alignment with the front (see the module
        docstring); False is the paper's Eq. 9.
    centres : (M,) array_like of int, optional
        Compute only these balls (rows of the result follow this order); all by default.
    local_spacing : (N,) numpy.ndarray of float64, optional
        Per-point spacing (:func:`parambench.methods.pointset.neighbourhoods.local_spacing`): ball i
        then has radius ``ball_eps_factor * local_spacing[i]``, so balls follow the local
        density; default: ``mean_spacing`` everywhere (the paper's global eps).

    Returns
    -------
    GeodesicBalls
        ``B`` is the largest ball found (at most ``max_ball``); one row per centre.

    Raises
    ------
    InvalidInputError
        Unknown ``dem`` or ``projection``, or non-positive sizes.
    """
    _check_options(dem, projection, ball_k, max_ball, ball_eps_factor)
    n = points.shape[0]
    centre_ids = _centre_ids(centres, n)
    # The compiled kernels release the GIL, so plain threads run them in parallel
    # (cheaper to compile than numba's parallel=True), as many as NUMBA_NUM_THREADS
    # (default: the number of cores). Read from the config, not from
    # numba.get_num_threads(), which would start a threading layer this code never uses
    # (and print a warning about TBB's version on every run).
    workers = max(1, int(numba.config.NUMBA_NUM_THREADS))
    cloud = _graph_cloud(points, normals, adjacency, midpoint=projection == "midpoint", upwind=dem == "upwind",
                         workers=workers)
    radii = (np.full(n, float(ball_eps_factor * mean_spacing)) if local_spacing is None
             else float(ball_eps_factor) * np.ascontiguousarray(local_spacing, dtype=np.float64))
    rule = _BallRule(ball_k=int(ball_k), radii=radii, max_ball=int(max_ball), upwind=dem == "upwind",
                     w_eps=_UPWIND_EPS * mean_spacing**2, midpoint=projection == "midpoint",
                     front_weight=bool(front_weight))
    scratch = _scratch(workers, n, _heap_capacity(cloud.indptr, rule.max_ball), rule.max_ball)
    sizes = np.zeros(centre_ids.size, dtype=np.int64)
    store, n_trunc = _run_blocks(centre_ids, cloud, rule, scratch, sizes)
    idx, coords, gdist = _assemble(store, sizes)
    if dem == "projected":  # the plain DEM's balls, its coordinates replaced
        _projected_coords(cloud, centre_ids, idx, coords)
    return GeodesicBalls(indices=idx, coords=coords, sizes=sizes, graph_dist=gdist, n_truncated=n_trunc)


def _projected_coords(cloud: _Cloud, centre_ids: np.ndarray, indices: np.ndarray, out: np.ndarray) -> None:
    """``out[r, b] = ((p - s) . e1_s, (p - s) . e2_s)`` for centre ``s = centre_ids[r]`` and member ``p = indices[r, b]``.

    The frame is the one the DEM kernel expresses its coordinates in, so the two kinds
    differ only in how each member's offset is found; padding stays 0.
    """
    def rows_of(rows: slice) -> None:
        s = centre_ids[rows]
        members = indices[rows]
        real = members >= 0
        d = cloud.points[np.where(real, members, 0)] - cloud.points[s][:, None, :]
        out[rows, :, 0] = np.where(real, np.einsum("nbi,ni->nb", d, cloud.e1[s]), 0.0)
        out[rows, :, 1] = np.where(real, np.einsum("nbi,ni->nb", d, cloud.e2[s]), 0.0)

    for_each_chunk(rows_of, centre_ids.size, _PROJECTED_CHUNK)


def _check_options(dem: str, projection: str, ball_k: int, max_ball: int, ball_eps_factor: float) -> None:
    """Raise InvalidInputError for an unknown ``dem``/``projection`` or inconsistent ball sizes."""
    if dem not in DEM_KINDS:
        raise InvalidInputError(f"dem must be one of {', '.join(DEM_KINDS)}, got {dem!r}.")
    if projection not in PROJECTIONS:
        raise InvalidInputError(f"projection must be one of {', '.join(PROJECTIONS)}, got {projection!r}.")
    if ball_k < 1 or max_ball < ball_k:
        raise InvalidInputError(f"need 1 <= ball_k <= max_ball, got ball_k={ball_k}, max_ball={max_ball}.")
    if ball_eps_factor < 0:
        raise InvalidInputError(f"ball_eps_factor must be >= 0, got {ball_eps_factor}.")


def _centre_ids(centres: np.ndarray | None, n: int) -> np.ndarray:
    """The centres as a contiguous int64 vector (all n points by default), checked to be point indices."""
    centre_ids = (np.arange(n, dtype=np.int64) if centres is None
                  else np.ascontiguousarray(centres, dtype=np.int64).ravel())
    if centre_ids.size and (centre_ids.min() < 0 or centre_ids.max() >= n):
        raise InvalidInputError(f"centres must be point indices in [0, {n - 1}].")
    return centre_ids


def _graph_cloud(points: np.ndarray, normals: np.ndarray, adjacency: sp.spmatrix, *, midpoint: bool = True,
                 upwind: bool = True, workers: int = 1) -> _Cloud:
    """The kernel's read-only inputs: points, float64 normals with their frames, int64 CSR graph,
    and for the upwind average each edge's :func:`_chord` (``chords``, (nnz, 6); (0, 6) otherwise).

    Every edge is transported once per ball holding both ends (~25 times at the default
    radius), but only the rotation to the centre's frame depends on the ball: the chord is
    computed once here, on ``workers`` threads, and the kernel's results are unchanged.
    """
    adjacency = adjacency.tocsr()
    normals = np.ascontiguousarray(normals, dtype=np.float64)
    e1, e2 = tangent_frames(normals)
    indptr = adjacency.indptr.astype(np.int64)
    nbrs = adjacency.indices.astype(np.int64)
    chords = np.empty((nbrs.size if upwind else 0, 6))
    if upwind and nbrs.size:
        bounds = np.linspace(0, indptr.size - 1, workers + 1).astype(np.int64)
        with ThreadPoolExecutor(max_workers=workers) as pool:
            list(pool.map(lambda t: _chord_rows(points, normals, indptr, nbrs, midpoint, chords, int(bounds[t]),
                                                int(bounds[t + 1])), range(workers)))
    return _Cloud(points=points, normals=normals, e1=e1, e2=e2, indptr=indptr, nbrs=nbrs,
                  lens=np.asarray(adjacency.data, dtype=np.float64), chords=chords)


def _heap_capacity(indptr: np.ndarray, max_ball: int) -> int:
    """Heap entries one ball can need.

    Every push relaxes an edge of the centre or of a finalised member (at most
    ``max_ball`` of them), so ``(max_ball + 1) * max_degree`` bounds the entries, stale
    ones included; one more degree and one entry are margin.
    """
    return (max_ball + 2) * int(np.diff(indptr).max()) + 1


def _scratch(workers: int, n: int, cap: int, max_ball: int) -> list[_Scratch]:
    """Dijkstra scratch per worker, stamped -1 (no row yet) so it never needs resetting (see _dem_range)."""
    seen = np.full((workers, n), -1, dtype=np.int64)
    frozen = np.full((workers, n), -1, dtype=np.int64)
    dist = np.empty((workers, n))
    pred = np.empty((workers, n), dtype=np.int64)
    uv = np.empty((workers, n, 2))
    heap_keys = np.empty((workers, cap))
    heap_vals = np.empty((workers, cap), dtype=np.int64)
    ball_idx = np.empty((workers, max_ball), dtype=np.int64)
    ball_uv = np.empty((workers, max_ball, 2))
    ball_dist = np.empty((workers, max_ball))
    return [_Scratch(seen[t], frozen[t], dist[t], pred[t], uv[t], heap_keys[t], heap_vals[t], ball_idx[t],
                     ball_uv[t], ball_dist[t]) for t in range(workers)]


def _run_blocks(centre_ids: np.ndarray, cloud: _Cloud, rule: _BallRule, scratch: list[_Scratch],
                sizes: np.ndarray) -> tuple[_BallBlock, int]:
    """Run the kernel over blocks of ``_BLOCK`` centres, each block's pieces shared out between the workers.

    Fills ``sizes``; returns the balls (the rows of :func:`_store_for`, padded with -1,
    0 and +inf) and the number of truncated balls. The store starts 0 columns wide, so
    the first block's balls all go to the spill rows and its widest ball sizes the
    store; a later block with a wider ball widens it again.
    """
    workers = len(scratch)
    n_out = centre_ids.size
    n_trunc = 0
    # One spill buffer, reused: a fresh full-width buffer per block was ~1 GB of newly
    # touched pages at a million points (slow first touches on this kind of VM). Only
    # the rows of balls wider than the store are written (all of the first block's).
    m0 = min(_BLOCK, n_out)
    spill = _BallBlock(idx=np.empty((m0, rule.max_ball), dtype=np.int64), uv=np.empty((m0, rule.max_ball, 2)),
                       dist=np.empty((m0, rule.max_ball)), size=sizes)
    store = _store_for(None, 0, 0, sizes, rule.max_ball)
    # Each task borrows a free worker's scratch (never more tasks run than scratches):
    # the stamps of _dem_range make any scratch valid for any centre.
    free = queue.SimpleQueue()
    for work in scratch:
        free.put(work)

    def run(store: _BallBlock, start: int, lo: int, hi: int) -> int:
        work = free.get()
        try:
            return int(_dem_range(centre_ids, lo, hi, cloud, rule, store, spill, start, work))
        finally:
            free.put(work)

    with ThreadPoolExecutor(max_workers=workers) as pool:
        for start in range(0, n_out, _BLOCK):
            stop = min(start + _BLOCK, n_out)
            # Balls cost unevenly (and a core may be busy elsewhere): small pieces handed
            # out as workers free up keep both busy until the block's end.
            pieces = np.linspace(start, stop, workers * _PIECES_PER_WORKER + 1).astype(np.int64)
            n_trunc += sum(pool.map(lambda ab, st=store, s0=start: run(st, s0, int(ab[0]), int(ab[1])),
                                    zip(pieces[:-1], pieces[1:])))
            wider = _store_for(store, int(sizes[start:stop].max()), start, sizes, rule.max_ball)
            if wider is not store:  # some balls spilled: this block's rows into the wider store
                bounds = np.linspace(0, stop - start, workers + 1).astype(np.int64)
                list(pool.map(lambda t, old=store, s0=start: _copy_rows(old, spill, wider, s0, int(bounds[t]),
                                                                         int(bounds[t + 1])), range(workers)))
                store = wider
    return store, n_trunc


#: Extra columns of the balls' first allocation, relative to the first block's widest
#: ball (later blocks are usually a little wider; a wider one reallocates).
_WIDTH_MARGIN = 0.25


def _store_for(store: _BallBlock | None, width: int, filled: int, sizes: np.ndarray, max_ball: int) -> _BallBlock:
    """The output rows, at least ``width`` columns wide: ``store`` itself, or a wider copy of its first ``filled`` rows.

    Allocated uninitialised (pages are touched only as rows are written) with
    ``_WIDTH_MARGIN`` spare columns, at most ``max_ball``; :func:`_assemble` cuts the
    spare columns off at the end. Without ``store``, a width of 0 gives a store of 0
    columns (every ball spills, see :func:`_run_blocks`).
    """
    if store is not None and width <= store.idx.shape[1]:
        return store
    n_out = sizes.size
    cols = 0 if store is None and width == 0 else min(max_ball, width + max(4, int(np.ceil(_WIDTH_MARGIN * width))))
    wider = _BallBlock(idx=np.empty((n_out, cols), dtype=np.int64), uv=np.empty((n_out, cols, 2)),
                       dist=np.empty((n_out, cols)), size=sizes)
    if store is not None and filled:
        old = store.idx.shape[1]
        for new, prev, pad in ((wider.idx, store.idx, -1), (wider.uv, store.uv, 0.0), (wider.dist, store.dist, np.inf)):
            new[:filled, :old] = prev[:filled]
            new[:filled, old:] = pad
    return wider


@numba.njit(cache=_CACHE, nogil=True)
def _copy_rows(old, spill, store, offset, lo, hi):
    """Rows ``offset + lo:offset + hi`` into the wider ``store``, padded: from ``spill`` (rows lo:hi) where
    the ball was wider than ``old``, the store they were written to, else from ``old``.

    ``store.size`` holds the balls' sizes.
    """
    o_idx, o_uv, o_dist, _ = old
    p_idx, p_uv, p_dist, _ = spill
    s_idx, s_uv, s_dist, size = store
    narrow = o_idx.shape[1]
    width = s_idx.shape[1]
    for r in range(lo, hi):
        row = offset + r
        m = size[row]
        if m > narrow:
            _put_row(s_idx, s_uv, s_dist, row, p_idx[r], p_uv[r], p_dist[r], m, width)
        else:
            _put_row(s_idx, s_uv, s_dist, row, o_idx[row], o_uv[row], o_dist[row], m, width)


@numba.njit(cache=_CACHE, nogil=True)
def _narrow_rows(idx, uv, dist, width):
    """Re-lay C-contiguous rows at ``width`` columns in place, ascending (each row moves towards the start)."""
    stride = idx.shape[1]
    f_idx = idx.reshape(-1)
    f_uv = uv.reshape(-1)
    f_dist = dist.reshape(-1)
    for r in range(idx.shape[0]):
        src = r * stride
        dst = r * width
        for j in range(width):
            f_idx[dst + j] = f_idx[src + j]
            f_dist[dst + j] = f_dist[src + j]
            f_uv[2 * (dst + j)] = f_uv[2 * (src + j)]
            f_uv[2 * (dst + j) + 1] = f_uv[2 * (src + j) + 1]


def _assemble(store: _BallBlock, sizes: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The balls as arrays exactly as wide as the largest ball (``store``'s buffers, narrowed in place).

    Rows are moved within the buffers and the spare tail is given back (``ndarray.resize``),
    so no second copy of the balls (~1.2 GB at a million points) is ever made.
    """
    n_out = sizes.size
    width = int(sizes.max()) if n_out else 0
    idx, uv, dist = store.idx, store.uv, store.dist
    if width < idx.shape[1]:
        _narrow_rows(idx, uv, dist, width)
        idx.resize((n_out, width), refcheck=False)
        uv.resize((n_out, width, 2), refcheck=False)
        dist.resize((n_out, width), refcheck=False)
    return idx, uv, dist
