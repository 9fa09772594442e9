"""Per-point Delaunay one-rings in the tangent plane, and the cotangent weights they carry.

Each point's candidates (its k nearest neighbours, plus any extra columns such as its
neighbours along a boundary loop) are projected to the point's PCA tangent plane, and the
one-ring of the point in the 2D Delaunay triangulation of that local set is kept.

The one-ring is found without building the whole local triangulation: with the point at
the origin, inversion ``d -> d / |d|^2`` maps circles through the origin to lines, so a
candidate is a Delaunay neighbour exactly when its image is a vertex of the convex hull of
the images and the origin, and consecutive hull vertices (the origin excluded) span the
one-ring's triangles (a circle through the point and two candidates is empty iff their
images' line leaves every other image on the origin's side). One compiled loop computes a
monotone-chain hull of k + 1 points per point: O(N k log k), no Python loop over points.

Cocircular ties (grid samplings) are broken by rounding; either diagonal of a cocircular
quad has cotangent weight 0 and leaves the spokes' weights unchanged, so the weights of
:func:`one_ring_cotangent_weights` do not depend on how ties were broken.
"""

from __future__ import annotations

from pathlib import Path

import numba
import numpy as np
import scipy.sparse as sp

from parambench.datasets_gen.errors import InvalidInputError

from ..numba_cache import configure_numba_cache
from .normals import tangent_frames
from .row_chunks import for_each_chunk

__all__ = ["local_delaunay_rings", "tangent_plane_rings", "drop_outside_boundary", "one_ring_cotangent_weights"]

_CACHE, _ = configure_numba_cache(Path(__file__).resolve().parent)

#: Points per block of the tangent-coordinate temporaries (bounds memory at 1M points).
_BLOCK = 65536

#: Relative area below which a one-ring triangle counts as flat and is left out.
_FLAT = 1e-12


@numba.njit(cache=_CACHE, nogil=True)
def _cross(ox, oy, ax, ay, bx, by):
    return (ax - ox) * (by - oy) - (ay - oy) * (bx - ox)


@numba.njit(cache=_CACHE, nogil=True, inline="always")
def _inverted_sorted(coords, valid, i, xs, ys, ids):
    """Point i's inverted candidates ``d / |d|^2`` plus the origin (id -1), sorted by (x, y).

    Fills ``xs``, ``ys`` and ``ids`` (the candidate's column) and returns how many there
    are; candidates at the point itself are skipped. Insertion sort: m is small.
    """
    m = valid.shape[1]
    cnt = 0
    for j in range(m + 1):
        if j == m:
            x, y, ident = 0.0, 0.0, -1
        else:
            if not valid[i, j]:
                continue
            dx, dy = coords[i, j, 0], coords[i, j, 1]
            r2 = dx * dx + dy * dy
            if not r2 > 0.0:
                continue
            x, y, ident = dx / r2, dy / r2, j
        pos = cnt
        while pos > 0 and (xs[pos - 1] > x or (xs[pos - 1] == x and ys[pos - 1] > y)):
            xs[pos] = xs[pos - 1]
            ys[pos] = ys[pos - 1]
            ids[pos] = ids[pos - 1]
            pos -= 1
        xs[pos] = x
        ys[pos] = y
        ids[pos] = ident
        cnt += 1
    return cnt


@numba.njit(cache=_CACHE, nogil=True, inline="always")
def _monotone_hull(xs, ys, cnt, hull):
    """Andrew's monotone chain over the first ``cnt`` (x, y)-sorted points; returns the vertex count.

    ``hull[:h]`` holds the positions of the hull vertices, counter-clockwise; collinear
    points are dropped (strict turns only).
    """
    h = 0
    for s in range(cnt):
        while h >= 2 and _cross(xs[hull[h - 2]], ys[hull[h - 2]], xs[hull[h - 1]], ys[hull[h - 1]],
                                xs[s], ys[s]) <= 0.0:
            h -= 1
        hull[h] = s
        h += 1
    lower = h + 1
    for s in range(cnt - 2, -1, -1):
        while h >= lower and _cross(xs[hull[h - 2]], ys[hull[h - 2]], xs[hull[h - 1]], ys[hull[h - 1]],
                                    xs[s], ys[s]) <= 0.0:
            h -= 1
        hull[h] = s
        h += 1
    return h - 1  # the last vertex repeats the first


@numba.njit(cache=_CACHE, nogil=True, inline="always")
def _emit_ring(xs, ys, ids, hull, h, out, i):
    """``out[i, t] = (a, b)`` for consecutive hull vertices a, b: the one-ring triangles, CCW.

    Edges through the origin and (nearly) flat triangles are left out.
    """
    t = 0
    for s in range(h):
        a = hull[s]
        b = hull[(s + 1) % h]
        if ids[a] < 0 or ids[b] < 0:
            continue  # an edge through the origin: the open side of a point on its local hull
        ax, ay, bx, by = xs[a], ys[a], xs[b], ys[b]
        # Same turn in the inverted plane as in the original one (directions are kept).
        if ax * by - ay * bx <= _FLAT * (ax * ax + ay * ay + bx * bx + by * by):
            continue
        out[i, t, 0] = ids[a]
        out[i, t, 1] = ids[b]
        t += 1


# The three stages above are inlined into the kernel (inline="always"): as separate
# compiled calls per point the kernel measured about 4% slower (bump, 20k points, 12-NN).
@numba.njit(cache=_CACHE, nogil=True)
def _rings_kernel(coords, valid, out):
    """``out[i, t] = (a, b)``: columns of the one-ring triangles of point i, CCW; -1 padding."""
    n, m = valid.shape
    xs = np.empty(m + 1)
    ys = np.empty(m + 1)
    ids = np.empty(m + 1, dtype=np.int64)
    hull = np.empty(2 * (m + 1) + 2, dtype=np.int64)
    for i in range(n):
        cnt = _inverted_sorted(coords, valid, i, xs, ys, ids)
        if cnt < 3:
            continue
        h = _monotone_hull(xs, ys, cnt, hull)
        _emit_ring(xs, ys, ids, hull, h, out, i)


def local_delaunay_rings(points: np.ndarray, normals: np.ndarray, candidates: np.ndarray) -> np.ndarray:
    """Each point's one-ring in the Delaunay triangulation of its candidates on its tangent plane.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
        Duplicate-free positions.
    normals : (N, 3) numpy.ndarray of float64
        Unit normals of the tangent planes (e.g. PCA normals,
        :func:`parambench.methods.pointset.normals.pca_normals`); signs do not matter.
    candidates : (N, C) numpy.ndarray of int64
        Candidate neighbours of each point (e.g. its k nearest neighbours), -1 padding;
        a point's own index and repeated entries are ignored.

    Returns
    -------
    rings : (N, C, 2) numpy.ndarray of int64
        ``rings[i, t] = (a, b)``: the triangle ``(i, a, b)`` (point indices), counter-
        clockwise around i on i's tangent plane; rows padded with -1. Interior points have
        a closed fan, points on the hull of their local set an open one.

    Raises
    ------
    InvalidInputError
        Shapes disagree or an index is out of range.
    """
    pts = np.ascontiguousarray(points, dtype=np.float64)
    cand = np.ascontiguousarray(candidates, dtype=np.int64)
    n = pts.shape[0]
    if cand.ndim != 2 or cand.shape[0] != n:
        raise InvalidInputError(f"candidates must have shape ({n}, C), got {cand.shape}.")
    if cand.size and (cand.max() >= n or cand.min() < -1):
        raise InvalidInputError(f"candidate indices must lie in [-1, {n - 1}].")
    if np.shape(normals) != (n, 3):
        raise InvalidInputError(f"normals must have shape ({n}, 3), got {np.shape(normals)}.")
    cand = _unique_candidates(cand)
    e1, e2 = tangent_frames(np.asarray(normals, dtype=np.float64))
    valid = cand >= 0
    rings = np.full(cand.shape + (2,), -1, dtype=np.int64)

    def block(sl: slice) -> None:
        offsets = pts[np.where(valid[sl], cand[sl], 0)] - pts[sl, None, :]
        coords = np.stack([np.einsum("nkd,nd->nk", offsets, e1[sl]), np.einsum("nkd,nd->nk", offsets, e2[sl])],
                          axis=-1)
        local = np.full(cand[sl].shape + (2,), -1, dtype=np.int64)
        _rings_kernel(np.ascontiguousarray(coords), np.ascontiguousarray(valid[sl]), local)
        ok = local >= 0
        rings[sl] = np.where(ok, np.take_along_axis(cand[sl], np.where(ok, local, 0).reshape(len(local), -1),
                                                    axis=1).reshape(local.shape), -1)

    for_each_chunk(block, n, _BLOCK)  # blocks write disjoint rows; the kernel releases the GIL
    return rings


def tangent_plane_rings(coords: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """One-rings from coordinates already in each point's tangent plane (e.g. DEM coordinates).

    The kernel of :func:`local_delaunay_rings` without its projection: used where the
    coordinates exist already (the Neumann Laplacian's boundary cells, from the DEM balls).

    Parameters
    ----------
    coords : (N, C, 2) numpy.ndarray of float64
        Candidates' coordinates relative to their centre (the centre at the origin).
    valid : (N, C) numpy.ndarray of bool
        True at real candidates (no repeats; a candidate at the origin is skipped).

    Returns
    -------
    (N, C, 2) numpy.ndarray of int64
        ``rings[i, t] = (a, b)``: columns of the triangle ``(centre, a, b)``,
        counter-clockwise; -1 padding. An open fan where the centre is on the hull of its
        candidates.

    Raises
    ------
    InvalidInputError
        Shapes disagree.
    """
    coords = np.ascontiguousarray(coords, dtype=np.float64)
    valid = np.ascontiguousarray(valid, dtype=bool)
    if coords.ndim != 3 or coords.shape[2] != 2 or valid.shape != coords.shape[:2]:
        raise InvalidInputError(f"coords must be (N, C, 2) and valid (N, C); got {coords.shape} and {valid.shape}.")
    rings = np.full(valid.shape + (2,), -1, dtype=np.int64)
    if valid.size:
        _rings_kernel(coords, valid, rings)
    return rings


def _unique_candidates(cand: np.ndarray) -> np.ndarray:
    """-1 in place of self-references and repeats (the first occurrence is kept)."""
    out = cand.copy()
    out[out == np.arange(len(out))[:, None]] = -1
    order = np.argsort(out, axis=1, kind="stable")
    srt = np.take_along_axis(out, order, axis=1)
    repeat = np.zeros_like(srt, dtype=bool)
    repeat[:, 1:] = (srt[:, 1:] == srt[:, :-1]) & (srt[:, 1:] >= 0)
    np.put_along_axis(out, order, np.where(repeat, -1, srt), axis=1)
    return out


def drop_outside_boundary(rings: np.ndarray, points: np.ndarray, normals: np.ndarray, loops,
                          candidates: np.ndarray) -> np.ndarray:
    """Remove the one-ring triangles of boundary points that lie outside the boundary.

    At a boundary point p with loop neighbours q (next) and r (previous), the directions to
    q and r split p's tangent plane into two sectors, "left" (counter-clockwise from q to
    r about the normal) and "right"; the surface lies on one side of the whole loop. Each
    loop's side is decided by a vote over all its points: a point votes for the sector
    holding more of its candidates (the other side is a hole or the outside, which holds
    none, or only the few points of a strongly curved boundary). A ring triangle is kept
    when the direction halfway between its two spokes lies in the surface sector. The
    vote makes the rule independent of the loops' orientation convention, so it serves
    detected and given loops alike; a per-point vote is not enough (measured: at a hole
    of 30 points the next boundary points outnumber the one interior ring vertex).

    Parameters
    ----------
    rings : (N, C, 2) numpy.ndarray of int64
        From :func:`local_delaunay_rings`.
    points : (N, 3) numpy.ndarray of float64
    normals : (N, 3) numpy.ndarray of float64
        Unit normals, oriented consistently along each loop (e.g. the front end's).
    loops : list of (L_i,) array_like of int
        Ordered boundary loops; loops of fewer than 3 points are ignored.
    candidates : (N, C) numpy.ndarray of int64
        The candidates the rings were built from (-1 padding).

    Returns
    -------
    (N, C, 2) numpy.ndarray of int64
        A copy of ``rings`` with the dropped triangles set to -1.
    """
    out = rings.copy()
    two_pi = 2.0 * np.pi
    for loop in loops:
        p = np.asarray(loop, dtype=np.int64)
        if p.size < 3:
            continue
        q, r = np.roll(p, -1), np.roll(p, 1)
        e1, e2 = tangent_frames(normals[p])

        def rel_angle(idx, th0):
            """CCW angle in [0, 2 pi) of ``points[idx]`` seen from p, from direction th0."""
            d = points[idx] - points[p].reshape((len(p),) + (1,) * (idx.ndim - 1) + (3,))
            th = np.arctan2(np.einsum("n...d,nd->n...", d, e2), np.einsum("n...d,nd->n...", d, e1))
            return np.mod(th - th0.reshape((len(p),) + (1,) * (idx.ndim - 1)), two_pi)

        th_q = rel_angle(q, np.zeros(len(p)))
        span = rel_angle(r, th_q)[:, None]  # CCW extent of the left sector, from q to r
        cand = candidates[p]
        has_c = (cand >= 0) & (cand != q[:, None]) & (cand != r[:, None])
        rel_c = rel_angle(np.where(has_c, cand, q[:, None]), th_q)
        left = (has_c & (rel_c < span)).sum(axis=1)
        right = (has_c & (rel_c > span)).sum(axis=1)
        surface_left = np.sign(left - right).sum() >= 0
        tri = out[p]
        has = tri[..., 0] >= 0
        rel_a = rel_angle(np.where(has, tri[..., 0], q[:, None]), th_q)
        rel_b = rel_angle(np.where(has, tri[..., 1], q[:, None]), th_q)
        # Triangles are counter-clockwise with less than pi between their spokes.
        mid = np.mod(rel_a + 0.5 * np.mod(rel_b - rel_a, two_pi), two_pi)
        keep = has & ((mid < span) if surface_left else (mid > span))
        tri[~keep] = -1
        out[p] = tri
    return out


def one_ring_cotangent_weights(points: np.ndarray, rings: np.ndarray) -> sp.csr_matrix:
    """Cotangent weights accumulated over the one-rings, symmetrised.

    Row i collects, from i's own one-ring, ``cot(angle opposite the spoke) / 2`` of every
    ring triangle holding the spoke i-j (two triangles inside, one on an open side), with
    angles measured on the 3D triangles. ``W = (W_rings + W_rings^T) / 2``: where the
    one-rings of i and j agree this is the mesh cotangent weight of libigl's scale
    (``E_D = u^T (D - W) u / 2`` is the Dirichlet energy, k = 1 is conformal).

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    rings : (N, C, 2) numpy.ndarray of int64
        One-ring triangles ``(i, a, b)``, -1 padding.

    Returns
    -------
    (N, N) scipy.sparse.csr_matrix of float64
        Symmetric, zero diagonal; entries may be negative (obtuse angles).
    """
    n = points.shape[0]
    centre = np.broadcast_to(np.arange(n)[:, None], rings.shape[:2])
    has = rings[..., 0] >= 0
    i, a, b = centre[has], rings[..., 0][has], rings[..., 1][has]
    xi, xa, xb = points[i], points[a], points[b]
    twice_area = np.linalg.norm(np.cross(xa - xi, xb - xi), axis=1)
    twice_area = np.maximum(twice_area, np.finfo(float).tiny)
    cot_at_b = np.einsum("nd,nd->n", xi - xb, xa - xb) / twice_area  # opposite spoke i-a
    cot_at_a = np.einsum("nd,nd->n", xi - xa, xb - xa) / twice_area  # opposite spoke i-b
    rows = np.concatenate([i, i])
    cols = np.concatenate([a, b])
    vals = 0.5 * np.concatenate([cot_at_b, cot_at_a])
    w = sp.csr_matrix((vals, (rows, cols)), shape=(n, n))  # duplicates are summed
    return ((w + w.T) * 0.5).tocsr()
