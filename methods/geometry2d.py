"""Planar geometry of the methods: polygon area and turning number, uv triangle orientation, segment crossings.

The methods' one definition of these (the turning-number penalty, the hybrid weights'
folds, the point-set self-check). The evaluation keeps its own
(:mod:`parambench.bench.metrics.loops`, :mod:`parambench.bench.metrics.orientation`) so that it does not share
code with what it judges; a test compares the two.
"""

from __future__ import annotations

import numpy as np

__all__ = ["signed_area_2d", "turning_number", "triangle_signed_areas", "flipped_triangles", "segments_cross",
           "crossing_segment_pairs", "COLLAPSE_REL_TOL"]

#: A triangle whose |uv area| is at most this share of the mean |uv area| has no orientation.
COLLAPSE_REL_TOL = 1e-12


def signed_area_2d(polygon: np.ndarray) -> float:
    """Signed area of a closed 2D polygon (shoelace formula), positive if counter-clockwise.

    Parameters
    ----------
    polygon : (L, 2) numpy.ndarray of float64
        Vertices in order; the closing edge from the last to the first is implied.
    """
    x, y = polygon[:, 0], polygon[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def turning_number(polygon: np.ndarray) -> float:
    """Turning number of a closed 2D polygon: total signed exterior angle over 2 pi.

    +1 for a simple counter-clockwise polygon, -1 for a clockwise one, 2 for a boundary
    that winds twice (the "spinning" of Sec. 4.2). Zero-length edges are skipped.

    Parameters
    ----------
    polygon : (L, 2) numpy.ndarray of float64
        Vertices in order; the closing edge is implied.

    Returns
    -------
    float
        Exact to rounding error for a closed polygon (an integer up to ~1e-12).
    """
    edges = np.roll(polygon, -1, axis=0) - polygon
    keep = np.hypot(edges[:, 0], edges[:, 1]) > 0
    edges = edges[keep]
    if len(edges) < 2:
        return 0.0
    nxt = np.roll(edges, -1, axis=0)
    cross = edges[:, 0] * nxt[:, 1] - edges[:, 1] * nxt[:, 0]
    dot = np.einsum("ij,ij->i", edges, nxt)
    return float(np.arctan2(cross, dot).sum() / (2.0 * np.pi))


def triangle_signed_areas(uv: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Signed area of every uv triangle, positive where its corners run counter-clockwise.

    Parameters
    ----------
    uv : (N, 2) numpy.ndarray of float64
    faces : (M, 3) numpy.ndarray of int64

    Returns
    -------
    (M,) numpy.ndarray of float64
        In the units of uv squared.
    """
    a = uv[faces[:, 0]]
    d1, d2 = uv[faces[:, 1]] - a, uv[faces[:, 2]] - a
    return 0.5 * (d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0])


def flipped_triangles(uv: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Triangles whose uv orientation opposes the majority (a global mirror is no flip).

    Parameters
    ----------
    uv : (N, 2) numpy.ndarray of float64
    faces : (M, 3) numpy.ndarray of int64

    Returns
    -------
    (M,) numpy.ndarray of bool
        Collapsed triangles (|area| at most ``COLLAPSE_REL_TOL`` of the mean) are not
        flipped and do not vote for the majority; a tie counts as counter-clockwise.
    """
    signed = triangle_signed_areas(uv, faces)
    live = np.abs(signed) > COLLAPSE_REL_TOL * np.abs(signed).mean()
    majority = 1.0 if np.count_nonzero(signed[live] > 0) >= np.count_nonzero(signed[live] < 0) else -1.0
    return live & (signed * majority < 0)


def _orientation(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Twice the signed area of triangles (a, b, c): 2D points in the last axis, broadcast."""
    return (b[..., 0] - a[..., 0]) * (c[..., 1] - a[..., 1]) - (b[..., 1] - a[..., 1]) * (c[..., 0] - a[..., 0])


def segments_cross(p: np.ndarray, q: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Whether segments pq and ab cross properly (each one's ends strictly on either side of the other).

    Segments that share an end, or only touch, do not cross.

    Parameters
    ----------
    p, q, a, b : (..., 2) numpy.ndarray of float64
        End points, broadcast against each other.

    Returns
    -------
    (...) numpy.ndarray of bool
    """
    return ((_orientation(p, q, a) * _orientation(p, q, b) < 0)
            & (_orientation(a, b, p) * _orientation(a, b, q) < 0))


def crossing_segment_pairs(uv: np.ndarray, segments: np.ndarray) -> np.ndarray:
    """The pairs of segments that cross properly (a uv boundary that self-intersects).

    Two crossing segments' midpoints lie within the longer one's length of each other, so
    only pairs of midpoints that close are tested.

    Parameters
    ----------
    uv : (N, 2) numpy.ndarray of float64
    segments : (S, 2) numpy.ndarray of int64
        Rows of ``uv`` each segment joins.

    Returns
    -------
    (P, 2) numpy.ndarray of int64
        Indices into ``segments``, each crossing pair once.
    """
    from scipy.spatial import cKDTree

    if len(segments) < 2:
        return np.zeros((0, 2), dtype=np.int64)
    p, q = uv[segments[:, 0]], uv[segments[:, 1]]
    reach = float(np.linalg.norm(q - p, axis=1).max())
    pairs = cKDTree(0.5 * (p + q)).query_pairs(reach, output_type="ndarray")
    if pairs.size == 0:
        return np.zeros((0, 2), dtype=np.int64)
    i, j = pairs[:, 0], pairs[:, 1]
    return pairs[segments_cross(p[i], q[i], p[j], q[j])].astype(np.int64)
