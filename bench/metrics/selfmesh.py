"""Scoring a point-set map without ground truth, on the evaluation's own uv triangulation.

The method's detected boundary loops bound the domain in uv: the Delaunay triangulation of
the uv points is cut back to the triangles whose centroid lies inside the loops (even-odd
rule, so holes stay open), and the usual metrics are computed on that mesh. This is the
judge's own code; it deliberately does not reuse the methods' constrained triangulation
(``methods/pointset/uv_triangulation.py``), so that a bug there cannot hide here.
"""

from __future__ import annotations

import numpy as np

from parambench.datasets_gen.errors import InvalidInputError
from parambench.datasets_gen.surface import validate_points
from parambench.methods.pointset.uv_triangulation import delaunay_faces, loop_winding_numbers

from ..schema import SELFMESH_KEYS
from ._inputs import check_uv
from .eval_mesh import keep_valid_ccw
from .evaluate import evaluate

__all__ = ["SELFMESH_KEYS", "points_in_loops", "uv_loop_faces", "self_scored"]


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
    return loop_winding_numbers(query, uv, loops) % 2 == 1


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
    tri = delaunay_faces(uv)
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
