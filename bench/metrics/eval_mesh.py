"""An evaluation mesh for point sets: Delaunay triangulation of the uv layout."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from parambench.datasets_gen.errors import InvalidInputError, TooFewPointsError
from parambench.datasets_gen.surface import DEGENERATE_AREA_TOL, validate_points
from parambench.methods.pointset.uv_triangulation import delaunay_faces

from ._inputs import check_uv
from .orientation import collapsed_mask, triangle_signed_areas

__all__ = ["uv_delaunay_faces", "keep_valid_ccw", "KNN_EDGE_K"]

#: Neighbours per point used for the reference edge length.
KNN_EDGE_K = 6


def uv_delaunay_faces(points, uv, max_edge_factor: float = 3.0) -> np.ndarray:
    """Delaunay triangulation of ``uv``, without the triangles that do not lie on the surface.

    The Delaunay triangulation of the uv layout fills its convex hull, so it bridges holes
    and concavities; those bridging triangles are long in 3D. A triangle is dropped when its
    longest 3D edge exceeds ``max_edge_factor`` times the mean 3D distance to the
    ``KNN_EDGE_K`` = 6 nearest neighbours (over all points). Triangles with (numerically)
    zero area in uv or in 3D, which qhull can emit, are dropped too.

    Every returned face is counter-clockwise in uv, so foldovers measured on this mesh are
    0 by construction: for a point set a fold shows as dropped or stretched triangles
    (high QC), not as flipped ones.

    Parameters
    ----------
    points : (N, 3) array_like of float64
    uv : (N, 2) array_like of float64
    max_edge_factor : float
        Positive.

    Returns
    -------
    (M, 3) numpy.ndarray of int64
        Possibly with some points in no face (points coinciding in uv, or isolated).

    Raises
    ------
    InvalidInputError
        Bad shapes, NaN/inf, a non-positive factor, all uv points collinear, or no triangle left.
    TooFewPointsError
        Fewer than ``KNN_EDGE_K + 1`` points.
    """
    pts = validate_points(points, min_points=KNN_EDGE_K + 1)
    uv = check_uv(uv, pts.shape[0])
    if not max_edge_factor > 0:
        raise InvalidInputError(f"max_edge_factor must be positive, got {max_edge_factor}.")
    if pts.shape[0] < KNN_EDGE_K + 1:  # pragma: no cover - validate_points enforces it
        raise TooFewPointsError(f"need at least {KNN_EDGE_K + 1} points.")
    try:
        tri = delaunay_faces(uv)
    except InvalidInputError as exc:
        raise InvalidInputError(f"{exc} Record the run as a failure.") from None

    dist, _ = cKDTree(pts).query(pts, k=KNN_EDGE_K + 1)
    ref_edge = float(dist[:, 1:].mean())  # column 0 is the point itself

    edge_len = _edge_lengths_3d(pts, tri)
    keep = edge_len.max(axis=1) <= max_edge_factor * ref_edge
    tri = keep_valid_ccw(pts, uv, tri, keep, edge_len)
    if tri is None:
        raise InvalidInputError(
            "no uv Delaunay triangle has 3D edges shorter than max_edge_factor x the mean neighbour distance; "
            "the map scrambles neighbourhoods, or max_edge_factor is too small."
        )
    return tri


def _edge_lengths_3d(pts: np.ndarray, tri: np.ndarray) -> np.ndarray:
    p = pts[tri]  # (M, 3, 3)
    edges = np.roll(p, -1, axis=1) - p
    return np.sqrt(np.einsum("ijk,ijk->ij", edges, edges))


def keep_valid_ccw(pts: np.ndarray, uv: np.ndarray, tri: np.ndarray, keep: np.ndarray,
                   edge_len: np.ndarray | None = None) -> np.ndarray | None:
    """The triangles selected by ``keep`` that are valid evaluation faces, counter-clockwise in uv.

    Drops faces with (numerically) zero 3D area, by the rule and scale of
    :func:`parambench.datasets_gen.surface.validate_faces` applied to the kept faces (so the result
    always passes validation), and faces collapsed in uv.

    Parameters
    ----------
    pts : (N, 3) numpy.ndarray of float64
    uv : (N, 2) numpy.ndarray of float64
    tri : (M, 3) numpy.ndarray of int64
        Candidate triangles (e.g. qhull's, in arbitrary vertex order).
    keep : (M,) numpy.ndarray of bool
        Preselection.
    edge_len : (M, 3) numpy.ndarray of float64, optional
        3D edge lengths of ``tri`` if already computed.

    Returns
    -------
    (K, 3) numpy.ndarray of int64, or None when no triangle is left.
    """
    if edge_len is None:
        edge_len = _edge_lengths_3d(pts, tri)
    keep = keep.copy()
    if keep.any():
        p = pts[tri]
        area2_3d = np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
        signed_uv = triangle_signed_areas(uv, tri)
        scale = max(float(np.mean(edge_len[keep, 0])) ** 2, np.finfo(float).tiny)
        keep &= area2_3d > DEGENERATE_AREA_TOL * scale
        keep &= ~collapsed_mask(signed_uv)
    if not keep.any():
        return None
    tri, signed_uv = tri[keep], signed_uv[keep]
    flip = signed_uv < 0
    tri[flip] = tri[flip][:, ::-1]  # qhull's vertex order is arbitrary; make every face CCW in uv
    return np.ascontiguousarray(tri)
