"""A triangulation of a point set's uv layout with its boundary loops kept (paper Sec. 6).

Constrained Delaunay in the plane (the ``triangle`` package, Shewchuk's Triangle) with
every detected boundary loop as a chain of constraint segments; of the triangles, those
inside the outer loop and outside every hole loop are kept (non-zero total winding number
of the loops).
The classification floods the triangle adjacency without crossing a constraint segment (compiled),
so each region between loops is classified by one point-in-polygon test.

When the constraints cannot be honoured as given (a self-intersecting uv boundary, which
Triangle resolves by inserting new vertices, or coincident uv points, which it drops) the fallback is
the unconstrained Delaunay triangulation of the distinct points (:func:`delaunay_faces`, also
Triangle) with every triangle classified by its centroid.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numba
import numpy as np

from parambench.datasets_gen.errors import InvalidInputError

from ..geometry2d import crossing_segment_pairs, triangle_signed_areas
from ..numba_cache import configure_numba_cache
from .row_chunks import for_each_chunk, worker_count

__all__ = ["UvTriangulation", "triangulate_uv", "delaunay_faces", "loop_winding_numbers"]

_CACHE, _ = configure_numba_cache(Path(__file__).resolve().parent)

#: Triangles per chunk of the orientation test (on worker threads).
_CHUNK = 65536


@dataclass(frozen=True, eq=False)
class UvTriangulation:
    """Triangles of a uv layout.

    Attributes
    ----------
    faces : (M, 3) numpy.ndarray of int64
        Indices into the input points; counter-clockwise in uv.
    kind : str
        ``"cdt"`` (constrained Delaunay, loops as segments), ``"delaunay"`` (no loops
        given) or ``"delaunay-fallback"`` (constraints failed, classified by centroid).
    n_removed : int
        Triangles dropped as outside the outer loop or inside a hole.
    boundary_crosses : bool
        The loops' images cross each other or themselves (Triangle had to insert
        vertices where constraint segments meet): the boundary is folded in uv.
    """

    faces: np.ndarray
    kind: str
    n_removed: int
    boundary_crosses: bool = False


def _loop_segments(loops: list[np.ndarray]) -> np.ndarray:
    segs = [np.stack([lp, np.roll(lp, -1)], axis=1) for lp in loops if len(lp) >= 3]
    return np.concatenate(segs).astype(np.int32) if segs else np.empty((0, 2), np.int32)


def _edges_winding(query: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Total winding number of the directed edges a -> b around each query (crossing rule).

    An edge can only count for queries with y in [min(a_y, b_y), max(a_y, b_y)): with the
    queries sorted by y, those are one slice per edge, so the work is the number of
    (edge, query) pairs in a band, about twice the queries for a simple loop. A collapsed
    or folded map's loops cross the whole layout many times, and the pairs then number
    up to edges x queries, so they are counted in a compiled loop with no temporaries
    (170k queries against 3.5k edges scattered over the layout: 1.1-1.4 s, against
    8.2-9.2 s for the blocked numpy version it replaced).

    Parameters
    ----------
    query : (Q, 2) numpy.ndarray of float64
    a, b : (E, 2) numpy.ndarray of float64
        Edge starts and ends (the loops' points and their successors).

    Returns
    -------
    (Q,) numpy.ndarray of int64
    """
    order = np.argsort(query[:, 1], kind="stable")
    qx = np.ascontiguousarray(query[order, 0])
    qy = np.ascontiguousarray(query[order, 1])
    start = np.searchsorted(qy, np.minimum(a[:, 1], b[:, 1]), side="left")
    stop = np.searchsorted(qy, np.maximum(a[:, 1], b[:, 1]), side="left")
    counted = np.zeros(query.shape[0], dtype=np.int64)
    a = np.ascontiguousarray(a, dtype=np.float64)
    b = np.ascontiguousarray(b, dtype=np.float64)

    def rows_of(rows: slice) -> None:  # disjoint slices of the sorted queries: no locking
        _band_crossings(qx, qy, a, b, start, stop, rows.start, rows.stop, counted)

    for_each_chunk(rows_of, query.shape[0], max(1, -(-query.shape[0] // (4 * worker_count()))))
    out = np.empty_like(counted)
    out[order] = counted
    return out


@numba.njit(cache=_CACHE, nogil=True)
def _band_crossings(qx, qy, a, b, start, stop, lo, hi, out):  # pragma: no cover - compiled
    """Add each edge's signed crossings to the y-sorted queries of its band within [lo, hi)."""
    for e in range(a.shape[0]):
        first, last = max(start[e], lo), min(stop[e], hi)
        if first >= last:
            continue
        ax, ay, bx, by = a[e, 0], a[e, 1], b[e, 0], b[e, 1]
        dx, dy = bx - ax, by - ay
        for j in range(first, last):
            y = qy[j]
            cross = dx * (y - ay) - dy * (qx[j] - ax)
            if ay <= y < by:
                if cross > 0:
                    out[j] += 1
            elif by <= y < ay:
                if cross < 0:
                    out[j] -= 1


def loop_winding_numbers(query: np.ndarray, uv: np.ndarray, loops) -> np.ndarray:
    """Total winding number of closed uv loops around each query point (crossing rule).

    Parameters
    ----------
    query : (Q, 2) numpy.ndarray of float64
    uv : (N, 2) numpy.ndarray of float64
    loops : sequence of (L_i,) array_like of int
        Closed polygons as indices into ``uv``; loops under 3 points are ignored.

    Returns
    -------
    (Q,) numpy.ndarray of int64
        The sum over the loops; its parity is the even-odd rule's inside.
    """
    loops = [np.asarray(lp, dtype=np.int64) for lp in loops if len(lp) >= 3]
    if not loops or not query.shape[0]:
        return np.zeros(query.shape[0], dtype=np.int64)
    a = np.concatenate([uv[lp] for lp in loops])
    b = np.concatenate([uv[np.roll(lp, -1)] for lp in loops])
    return _edges_winding(np.asarray(query, dtype=np.float64), a, b)


def _inside(query: np.ndarray, uv: np.ndarray, loops: list[np.ndarray]) -> np.ndarray:
    """Non-zero total winding of the loops: inside the outer loop and outside the holes.

    Holes turn against the outer loop, so their windings cancel the outer one inside a
    hole, under a global mirror too; a boundary that winds twice still has its inside.
    """
    return loop_winding_numbers(query, uv, loops) != 0


def delaunay_faces(uv: np.ndarray) -> np.ndarray:
    """Delaunay triangles of a uv layout's distinct points (Triangle, exact predicates).

    Coincident rows are one vertex, the first of them; the others are in no face (as
    Qhull drops them). Triangle rather than ``scipy.spatial.Delaunay``: Qhull merged facets
    for more than ten minutes on a collapsed map's clusters (a range scan's 85k points,
    34k of them within 1e-6 of the layout's extent of another; Triangle: 0.14 s), and on
    a million random points it takes 15 s against Triangle's 1 s.

    Parameters
    ----------
    uv : (N, 2) numpy.ndarray of float64

    Returns
    -------
    (F, 3) numpy.ndarray of int64
        Rows of ``uv``, in either orientation.

    Raises
    ------
    InvalidInputError
        Fewer than three distinct points, or all of them on one line (a collapsed map).
    """
    import triangle

    uv = np.ascontiguousarray(uv, dtype=np.float64)
    first = np.arange(uv.shape[0])
    if _has_coincident(uv):
        _, first = np.unique(uv, axis=0, return_index=True)
    tris = None
    if first.size >= 3:
        try:
            tris = triangle.triangulate({"vertices": uv[first]}, "Q").get("triangles")
        except Exception:  # Triangle's C code reports bad input only by failing
            tris = None
    if tris is None or not len(tris):
        raise InvalidInputError("the uv points cannot be triangulated (all collinear or coincident): "
                                "the map collapsed.")
    return first[np.asarray(tris, dtype=np.int64)]


def _ccw(uv: np.ndarray, faces: np.ndarray) -> np.ndarray:
    cw = np.empty(faces.shape[0], dtype=bool)

    def rows_of(rows: slice) -> None:
        cw[rows] = triangle_signed_areas(uv, faces[rows]) < 0

    for_each_chunk(rows_of, faces.shape[0], _CHUNK)
    faces = faces.copy()
    faces[cw] = faces[cw][:, [0, 2, 1]]
    return faces


@numba.njit(cache=_CACHE, nogil=True)
def _flood(faces, neighbours, on_loop, segment_keys, n, labels, seeds):
    """Label faces by flooding across shared edges that are not loop segments.

    Faces are visited in index order and each unlabelled one starts a region, so a
    region's seed is its lowest face index. Writes ``labels`` (-1 on entry) and
    ``seeds``; returns the number of regions.
    """
    m = faces.shape[0]
    stack = np.empty(m, dtype=np.int64)
    n_regions = 0
    for first in range(m):
        if labels[first] >= 0:
            continue
        labels[first] = n_regions
        seeds[n_regions] = first
        stack[0] = first
        top = 1
        while top > 0:
            top -= 1
            t = stack[top]
            for i in range(3):
                other = neighbours[t, i]
                if other < 0 or labels[other] >= 0:
                    continue
                # The edge opposite corner i runs from corner i+1 to corner i+2.
                a, b = faces[t, (i + 1) % 3], faces[t, (i + 2) % 3]
                if on_loop[a] and on_loop[b]:
                    key = min(a, b) * n + max(a, b)
                    j = np.searchsorted(segment_keys, key)
                    if j < segment_keys.size and segment_keys[j] == key:
                        continue
                labels[other] = n_regions
                stack[top] = other
                top += 1
        n_regions += 1
    return n_regions


def _regions(faces: np.ndarray, neighbours: np.ndarray, segments: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Label of each face (faces sharing an edge that is not a segment share it) and each
    region's first face.

    ``neighbours[t, i]`` is Triangle's face across the edge opposite corner i of face t
    (-1 on the hull); Triangle's adjacency is symmetric. One compiled flood over it (at a
    million points 0.1 s against 2 s for a sparse graph's connected components).
    """
    on_loop = np.zeros(n, dtype=bool)
    on_loop[segments.ravel()] = True
    keys = np.unique(np.minimum(segments[:, 0], segments[:, 1]).astype(np.int64) * n
                     + np.maximum(segments[:, 0], segments[:, 1]))
    labels = np.full(faces.shape[0], -1, dtype=np.int64)
    seeds = np.empty(faces.shape[0], dtype=np.int64)
    n_regions = _flood(np.ascontiguousarray(faces, dtype=np.int64), np.ascontiguousarray(neighbours, dtype=np.int64),
                       on_loop, keys, np.int64(n), labels, seeds)
    return labels, seeds[:n_regions]


def _cdt(uv: np.ndarray, segments: np.ndarray) -> tuple[np.ndarray | None, np.ndarray | None, bool]:
    """Constrained Delaunay faces and their neighbours (None when Triangle failed or had to
    change the input vertices), and whether the segments cross (the uv boundary
    self-intersects).

    Crossing segments are found before Triangle sees them: Triangle splits them with
    vertices of its own, and on some inputs never returned (a map of 15,656 points whose
    755 loop segments crossed in 219 pairs ran for 18 minutes), or printed "Internal error
    in segmentintersection()" on stdout.
    """
    import triangle

    if crossing_segment_pairs(uv, segments).size:
        return None, None, True
    try:
        out = triangle.triangulate({"vertices": uv, "segments": segments}, "pcQn")
    except Exception:  # Triangle's C code reports bad input only by failing
        return None, None, False
    verts = out.get("vertices")
    tris = out.get("triangles")
    if verts is None or tris is None or out.get("neighbors") is None:
        return None, None, False
    if verts.shape[0] != uv.shape[0] or not np.array_equal(verts, uv):
        return None, None, bool(verts.shape[0] > uv.shape[0])  # Steiner points where segments cross
    return np.asarray(tris, dtype=np.int64), np.asarray(out["neighbors"], dtype=np.int64), False


def _has_coincident(uv: np.ndarray) -> bool:
    """Whether two rows of uv are equal (Triangle cannot keep coincident vertices).

    Sorting u alone settles it where no two u are equal, the usual case (at 200k points
    3 ms against 0.28 s for ``np.unique(uv, axis=0)``).
    """
    u = np.sort(uv[:, 0])
    if not (u[1:] == u[:-1]).any():
        return False
    return np.unique(uv, axis=0).shape[0] != uv.shape[0]


def triangulate_uv(uv: np.ndarray, loops: list | None = None) -> UvTriangulation:
    """Triangulate a uv layout, keeping the domain bounded by the loops.

    Parameters
    ----------
    uv : (N, 2) numpy.ndarray of float64
        One row per point.
    loops : list of (L_i,) array_like of int, optional
        Boundary loops (point indices in order), outer first, holes turning against the
        outer loop (as the front end returns them); all loops are constraints and a
        triangle is kept where their total winding number is non-zero. None or empty: the Delaunay triangulation of the
        whole convex hull.

    Returns
    -------
    UvTriangulation

    Raises
    ------
    InvalidInputError
        The uv points cannot be triangulated at all (all collinear or coincident: a
        collapsed map), or no triangle lies inside the loops.
    """
    uv = np.ascontiguousarray(uv, dtype=np.float64)
    n = uv.shape[0]
    loops = [np.asarray(lp, dtype=np.int64) for lp in (loops or []) if len(lp) >= 3]
    faces, crosses = None, False
    segments = _loop_segments(loops)
    neighbours = None
    if loops and not _has_coincident(uv):
        faces, neighbours, crosses = _cdt(uv, segments)
    kind = "cdt" if faces is not None else ("delaunay-fallback" if loops else "delaunay")
    if faces is None:
        faces = delaunay_faces(uv)
    # Labels before the orientation fix: swapping two corners would misalign Triangle's neighbours.
    labels, first = _regions(faces, neighbours, segments, n) if kind == "cdt" else (None, None)
    faces = _ccw(uv, faces)
    if not loops:
        return UvTriangulation(faces=faces, kind=kind, n_removed=0)
    if kind == "cdt":
        inside = _inside(uv[faces[first]].mean(axis=1), uv, loops)[labels]
    else:
        inside = _inside(uv[faces].mean(axis=1), uv, loops)
    if not inside.any():
        raise InvalidInputError("no uv triangle lies inside the detected boundary loops: the map collapsed.")
    return UvTriangulation(faces=faces[inside], kind=kind, n_removed=int((~inside).sum()), boundary_crosses=crosses)
