"""A triangulation of a point set's uv layout with its boundary loops kept (paper Sec. 6).

Constrained Delaunay in the plane (the ``triangle`` package, Shewchuk's Triangle) with
every detected boundary loop as a chain of constraint segments; of the triangles, those
inside the outer loop and outside every hole loop are kept (non-zero total winding number
of the loops).
The classification floods the triangle adjacency without crossing a constraint segment,
so each region between loops is classified by one point-in-polygon test.

When the constraints cannot be honoured as given (a self-intersecting uv boundary, which
Triangle resolves by inserting new vertices, or coincident uv points, which it drops) the fallback is
scipy's unconstrained Delaunay with every triangle classified by its centroid.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from scipy.spatial import Delaunay, QhullError

from parambench.datasets_gen.errors import InvalidInputError

from ..geometry2d import triangle_signed_areas

__all__ = ["UvTriangulation", "triangulate_uv"]


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


def _winding(query: np.ndarray, polygon: np.ndarray, max_pairs: int = 4_000_000) -> np.ndarray:
    """Winding number of a closed polygon around each query point (crossing rule).

    An edge from a to b can only count for queries with y in [min(a_y, b_y), max(a_y,
    b_y)): with the queries sorted by y, those are one slice per edge, so the work is
    the number of (edge, query) pairs in a band, about twice the queries for a simple
    loop, not queries x edges (a folded 200k-point map's fallback classification took
    20 s that way).
    """
    a, b = polygon, np.roll(polygon, -1, axis=0)
    out = np.zeros(query.shape[0], dtype=np.int64)
    order = np.argsort(query[:, 1], kind="stable")
    ys = query[order, 1]
    start = np.searchsorted(ys, np.minimum(a[:, 1], b[:, 1]), side="left")
    stop = np.searchsorted(ys, np.maximum(a[:, 1], b[:, 1]), side="left")
    counts = stop - start
    ends = np.cumsum(counts)  # pairs up to and including each edge
    edge = 0
    while edge < len(polygon):  # blocks of edges with at most max_pairs pairs (at least one edge)
        before = ends[edge - 1] if edge else 0
        last = max(edge + 1, int(np.searchsorted(ends, before + max_pairs, side="right")))
        block, edge = np.arange(edge, last), last
        n_pairs = int(ends[last - 1] - before)
        if n_pairs == 0:
            continue
        e = np.repeat(block, counts[block])
        q = order[start[e] + np.arange(n_pairs) - (np.repeat(ends[block] - counts[block], counts[block]) - before)]
        qx, qy = query[q, 0], query[q, 1]
        ax, ay, bx, by = a[e, 0], a[e, 1], b[e, 0], b[e, 1]
        cross = (bx - ax) * (qy - ay) - (by - ay) * (qx - ax)
        up = (ay <= qy) & (by > qy) & (cross > 0)
        down = (ay > qy) & (by <= qy) & (cross < 0)
        out += np.bincount(q, weights=up.astype(np.int64) - down.astype(np.int64),
                           minlength=query.shape[0]).astype(np.int64)
    return out


def _inside(query: np.ndarray, uv: np.ndarray, loops: list[np.ndarray]) -> np.ndarray:
    """Non-zero total winding of the loops: inside the outer loop and outside the holes.

    Holes turn against the outer loop, so their windings cancel the outer one inside a
    hole, under a global mirror too; a boundary that winds twice still has its inside.
    """
    total = np.zeros(query.shape[0], dtype=np.int64)
    for lp in loops:
        total += _winding(query, uv[lp])
    return total != 0


def _ccw(uv: np.ndarray, faces: np.ndarray) -> np.ndarray:
    cw = triangle_signed_areas(uv, faces) < 0
    faces = faces.copy()
    faces[cw] = faces[cw][:, [0, 2, 1]]
    return faces


def _regions(faces: np.ndarray, neighbours: np.ndarray, segments: np.ndarray, n: int) -> np.ndarray:
    """Label of each face: faces sharing an edge that is not a segment get the same label.

    ``neighbours[t, i]`` is Triangle's face across the edge opposite corner i of face t
    (-1 on the hull). Only edges between two loop points can be segments, so only those
    few are looked up (at 200k points this replaced a sort of all 3M edge keys: 0.44 s).
    """
    m = faces.shape[0]
    owner = np.repeat(np.arange(m), 3)
    other = neighbours.ravel()
    a = faces[:, [1, 2, 0]].ravel()  # the edge opposite corner i runs from corner i+1 to i+2
    b = faces[:, [2, 0, 1]].ravel()
    on_loop = np.zeros(n, dtype=bool)
    on_loop[segments.ravel()] = True
    open_edge = other >= 0
    maybe = np.flatnonzero(open_edge & on_loop[a] & on_loop[b])
    if maybe.size:
        key = np.minimum(a[maybe], b[maybe]).astype(np.int64) * n + np.maximum(a[maybe], b[maybe])
        seg_key = (np.minimum(segments[:, 0], segments[:, 1]).astype(np.int64) * n
                   + np.maximum(segments[:, 0], segments[:, 1]))
        open_edge[maybe[np.isin(key, seg_key)]] = False
    adj = sp.coo_matrix((np.ones(int(open_edge.sum()), dtype=np.int8), (owner[open_edge], other[open_edge])),
                        shape=(m, m))
    return connected_components(adj, directed=False)[1]


def _cdt(uv: np.ndarray, segments: np.ndarray) -> tuple[np.ndarray | None, np.ndarray | None, bool]:
    """Constrained Delaunay faces and their neighbours (None when Triangle failed or had to
    change the input vertices), and whether it added vertices (crossing segments: the uv
    boundary self-intersects)."""
    import triangle

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
        try:
            faces = Delaunay(uv).simplices.astype(np.int64)
        except QhullError:
            raise InvalidInputError("the uv points cannot be triangulated (all collinear or coincident): "
                                    "the map collapsed.") from None
    # Labels before the orientation fix: swapping two corners would misalign Triangle's neighbours.
    labels = _regions(faces, neighbours, segments, n) if kind == "cdt" else None
    faces = _ccw(uv, faces)
    if not loops:
        return UvTriangulation(faces=faces, kind=kind, n_removed=0)
    centroids = uv[faces].mean(axis=1)
    if kind == "cdt":
        first = np.unique(labels, return_index=True)[1]
        inside = _inside(centroids[first], uv, loops)[labels]
    else:
        inside = _inside(centroids, uv, loops)
    if not inside.any():
        raise InvalidInputError("no uv triangle lies inside the detected boundary loops: the map collapsed.")
    return UvTriangulation(faces=faces[inside], kind=kind, n_removed=int((~inside).sum()), boundary_crosses=crosses)
