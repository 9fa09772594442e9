"""Neighbourhoods that stay on the surface across narrow gaps (lips, slits, folds).

Where two parts of a surface come within a few spacings of each other, a point's
Euclidean K nearest neighbours include points of the other part: every later stage
(normals, DEM fronts, weights, boundary) then bridges the gap. A neighbour across a gap
lies off the point's tangent plane (along the normal), while a neighbour on the surface
lies in it up to curvature and noise. So candidates (more than K Euclidean neighbours)
are kept only while their offset from the tangent plane, fitted on the nearest few
neighbours (which lie on the point's own sheet), is small against the in-plane distance
or within the noise level measured over the whole set; the K nearest kept candidates
form the graph. Normals are refitted on the kept neighbours and the test is repeated once.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from .neighbourhoods import KnnGraph
from .normals import pca_normals

__all__ = ["surface_knn_graph", "CANDIDATE_FACTOR", "MAX_SLOPE"]

#: Euclidean candidates examined per point, in units of K.
CANDIDATE_FACTOR = 2

#: Largest slope |offset along normal| / |offset in plane| of a neighbour on the surface
#: (tan 35 degrees: curvature radius >= ~1.4 neighbour distances).
MAX_SLOPE = np.tan(np.deg2rad(35.0))

#: Plane fits use this many nearest neighbours (the point's own sheet even across a gap
#: of two spacings).
_FIT_K = 6

#: Offsets up to this many robust standard deviations of all offsets count as noise.
_NOISE_SIGMAS = 3.0


def _keep_mask(points, cand, normals, noise_level):
    d = points[cand] - points[:, None, :]
    along = np.abs(np.einsum("nki,ni->nk", d, normals))
    in_plane = np.sqrt(np.maximum(np.einsum("nki,nki->nk", d, d) - along**2, 0.0))
    return along <= np.maximum(MAX_SLOPE * in_plane, noise_level)


def _noise_level(points, cand, normals):
    # Robust scale of the out-of-plane offsets of the nearest neighbours: curvature and
    # noise, not gaps (a gap affects few points).
    d = points[cand[:, :_FIT_K]] - points[:, None, :]
    along = np.abs(np.einsum("nki,ni->nk", d, normals))
    return _NOISE_SIGMAS * 1.4826 * float(np.median(along))


def _first_kept(cand, dist, keep, k):
    # Stable sort puts kept candidates first, each group in distance order; rows with
    # fewer than k kept candidates are filled with their nearest rejected ones (they
    # cannot be told apart from the surface at this sampling).
    order = np.argsort(~keep, axis=1, kind="stable")[:, :k]
    idx = np.take_along_axis(cand, order, axis=1)
    dst = np.take_along_axis(dist, order, axis=1)
    resort = np.argsort(dst, axis=1, kind="stable")
    return np.take_along_axis(idx, resort, axis=1), np.take_along_axis(dst, resort, axis=1)


def surface_knn_graph(points: np.ndarray, k: int = 8) -> tuple[KnnGraph, dict]:
    """K neighbours per point taken along the surface, not across narrow gaps.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
        Validated, duplicate-free points, N > k.
    k : int
        Neighbours per point.

    Returns
    -------
    graph : KnnGraph
        Rows nearest first, self excluded.
    diagnostics : dict
        ``n_points_with_rejected`` (points where a Euclidean K-nearest neighbour was
        replaced), ``noise_level`` (offset tolerance, length units).
    """
    n = points.shape[0]
    m = min(n - 1, CANDIDATE_FACTOR * k)
    dist, idx = cKDTree(points).query(points, k=m + 1, workers=-1)
    cand = np.ascontiguousarray(idx[:, 1:], dtype=np.int64)
    dist = np.ascontiguousarray(dist[:, 1:], dtype=np.float64)
    normals = pca_normals(points, cand[:, :min(_FIT_K, m)])
    noise = _noise_level(points, cand, normals)
    keep = _keep_mask(points, cand, normals, noise)
    sel, _ = _first_kept(cand, dist, keep, k)
    normals = pca_normals(points, sel)
    keep = _keep_mask(points, cand, normals, noise)
    sel, sel_dist = _first_kept(cand, dist, keep, k)
    replaced = np.any(~keep[:, :k], axis=1)
    graph = KnnGraph(indices=np.ascontiguousarray(sel), distances=np.ascontiguousarray(sel_dist),
                     mean_spacing=float(sel_dist.mean()))
    return graph, {"n_points_with_rejected": int(replaced.sum()), "noise_level": noise}
