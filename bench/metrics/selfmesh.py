"""Scoring a point-set map without ground truth, on the evaluation's own uv triangulation.

The method's detected boundary loops bound the domain in uv: the Delaunay triangulation of
the uv points is cut back to the triangles whose centroid lies inside the loops (even-odd
rule, so holes stay open), and the usual metrics are computed on that mesh. This is the
judge's own code; it deliberately does not reuse the methods' constrained triangulation
(``methods/pointset/uv_triangulation.py``), so that a bug there cannot hide here.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import Delaunay, QhullError

from parambench.datasets_gen.errors import InvalidInputError
from parambench.datasets_gen.surface import validate_points

from ..schema import SELFMESH_KEYS
from ._inputs import check_uv
from .eval_mesh import keep_valid_ccw
from .evaluate import evaluate

__all__ = ["SELFMESH_KEYS", "points_in_loops", "uv_loop_faces", "self_scored"]

#: Point-edge pairs tested at once by :func:`points_in_loops` (bounds its memory).
_PAIRS_PER_CHUNK = 20_000_000


def _loop_edges(uv: np.ndarray, loops) -> tuple[np.ndarray, np.ndarray]:
    starts, ends = [], []
    for loop in loops:
        idx = np.asarray(loop, dtype=np.int64)
        if idx.size < 3:
            continue
        starts.append(uv[idx])
        ends.append(uv[np.roll(idx, -1)])
    if not starts:
        return np.zeros((0, 2)), np.zeros((0, 2))
    return np.concatenate(starts), np.concatenate(ends)


def points_in_loops(query: np.ndarray, uv: np.ndarray, loops) -> np.ndarray:
    """Even-odd point-in-polygon test against all loops together.

    A query point is inside when a ray to +x crosses the loops' edges an odd number of
    times: inside the outer loop and outside every hole, for non-crossing loops.

    Parameters
    ----------
    query : (Q, 2) numpy.ndarray of float64
    uv : (N, 2) numpy.ndarray of float64
    loops : list of (L_i,) array_like of int
        Closed polygons as indices into ``uv`` (loops under 3 points are ignored).

    Returns
    -------
    (Q,) numpy.ndarray of bool
    """
    a, b = _loop_edges(uv, loops)
    inside = np.zeros(query.shape[0], dtype=bool)
    if not a.shape[0] or not query.shape[0]:
        return inside
    order = np.argsort(query[:, 1], kind="stable")
    qy = query[order, 1]
    qx = query[order, 0]
    ylo, yhi = np.minimum(a[:, 1], b[:, 1]), np.maximum(a[:, 1], b[:, 1])
    # Half-open [ylo, yhi): a ray through a shared vertex is counted once, horizontal edges never.
    lo = np.searchsorted(qy, ylo, side="left")
    hi = np.searchsorted(qy, yhi, side="left")
    counts = hi - lo
    # Only the points in an edge's y band can cross it: the work is (points x crossings per
    # horizontal line), processed in chunks of edges to bound memory on folded maps.
    parity = np.zeros(query.shape[0], dtype=np.int64)
    cum = np.cumsum(counts)
    start = 0
    while start < a.shape[0]:
        done = int(cum[start - 1]) if start else 0
        stop = max(int(np.searchsorted(cum, done + _PAIRS_PER_CHUNK, side="right")), start + 1)
        e = np.arange(start, stop)
        start = stop
        c = counts[e]
        if not c.sum():
            continue
        edge = np.repeat(e, c)
        pt = lo[edge] + np.arange(c.sum()) - np.repeat(np.cumsum(c) - c, c)
        ax, ay, bx, by = a[edge, 0], a[edge, 1], b[edge, 0], b[edge, 1]
        x_cross = ax + (qy[pt] - ay) * (bx - ax) / (by - ay)
        parity += np.bincount(pt[qx[pt] < x_cross], minlength=query.shape[0])
    inside[order] = parity % 2 == 1
    return inside


def uv_loop_faces(points, uv, loops) -> np.ndarray:
    """Delaunay triangulation of ``uv`` cut back to the inside of the detected loops.

    Parameters
    ----------
    points : (N, 3) array_like of float64
        Surface points (used only to drop faces that are degenerate in 3D).
    uv : (N, 2) array_like of float64
    loops : list of (L_i,) array_like of int
        The method's detected boundary loops (``diagnostics["boundary_loops"]``), outer and holes.

    Returns
    -------
    (M, 3) numpy.ndarray of int64
        Counter-clockwise in uv.

    Raises
    ------
    InvalidInputError
        Bad shapes, NaN/inf, no loop of 3 or more points, collinear uv points, or no
        triangle inside the loops.
    """
    pts = validate_points(points, min_points=3)
    uv = check_uv(uv, pts.shape[0])
    loops = [np.asarray(lp, dtype=np.int64) for lp in loops]
    if not any(lp.size >= 3 for lp in loops):
        raise InvalidInputError("no boundary loop of 3 or more points; pass the method's detected loops "
                                "(diagnostics['boundary_loops']) to build the self mesh.")
    if any(lp.size and (lp.min() < 0 or lp.max() >= pts.shape[0]) for lp in loops):
        raise InvalidInputError(f"boundary loop indices must lie in [0, {pts.shape[0] - 1}]; indices are 0-based.")
    try:
        tri = Delaunay(uv).simplices.astype(np.int64)
    except QhullError as exc:
        raise InvalidInputError("the uv points cannot be triangulated (all collinear or coincident): the map "
                                f"collapsed. Qhull said: {str(exc).splitlines()[0]}") from exc
    inside = points_in_loops(uv[tri].mean(axis=1), uv, loops)
    faces = keep_valid_ccw(pts, uv, tri, inside)
    if faces is None:
        raise InvalidInputError("no uv Delaunay triangle lies inside the detected boundary loops; the loops "
                                "collapsed in uv or do not bound the map.")
    return faces


def self_scored(points, uv, loops) -> dict:
    """Metrics of a point-set map on its own uv triangulation, without ground truth.

    Parameters
    ----------
    points : (N, 3) array_like of float64
    uv : (N, 2) array_like of float64
    loops : list of (L_i,) array_like of int
        The method's detected boundary loops.

    Returns
    -------
    dict
        ``selfmesh_<key>`` for every key of :data:`SELFMESH_KEYS`, values as in
        :func:`parambench.bench.metrics.evaluate`.

    Raises
    ------
    InvalidInputError
        See :func:`uv_loop_faces`.
    """
    faces = uv_loop_faces(points, uv, loops)
    metrics = evaluate(points, faces, uv, boundary_loops=loops)
    return {f"selfmesh_{k}": metrics[k] for k in SELFMESH_KEYS}
