"""Point normals: PCA fit, consistent orientation, smoothing (paper Sec. 3, 3.1).

Orientation rule (documented once, used everywhere): normals are first made consistent
by propagation along a minimum spanning tree of the kNN graph, then the global sign is
chosen so that the sum of all normals ``m`` has a non-negative component along its own
largest-magnitude axis (for the generated surfaces, whose normals point roughly to +z,
this means ``m_z >= 0``). When the normals nearly cancel (``|m| < 0.05 N``, a closed or
strongly curved surface) the sign is chosen so that normals point away from the
centroid on average.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import breadth_first_order, minimum_spanning_tree

from parambench.datasets_gen.errors import InconsistentNormalsError, InvalidInputError

__all__ = [
    "pca_normals",
    "orient_normals",
    "consistent_signs",
    "smooth_normals",
    "SMOOTHING_KINDS",
    "check_user_normals",
    "tangent_frames",
]

#: Rows per batch of covariance matrices (bounds temporary memory to ~100 MB).
_PCA_CHUNK = 200_000

#: Weight of the off-tangent-plane term of the orientation tree's edge weights.
_OFF_PLANE_WEIGHT = 3.0

#: Below this ``|sum of normals| / N`` the global sign falls back to "away from the centroid".
_CANCEL_TOL = 0.05


def pca_normals(points: np.ndarray, knn_indices: np.ndarray) -> np.ndarray:
    """Unoriented normals from PCA of each point's K-neighbourhood (the point included).

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    knn_indices : (N, K) numpy.ndarray of int64

    Returns
    -------
    (N, 3) numpy.ndarray of float64
        Unit eigenvectors of the smallest eigenvalue of each neighbourhood covariance;
        signs arbitrary.
    """
    n = points.shape[0]
    out = np.empty((n, 3))
    for start in range(0, n, _PCA_CHUNK):
        stop = min(start + _PCA_CHUNK, n)
        nbh = np.concatenate([points[start:stop, None, :], points[knn_indices[start:stop]]], axis=1)
        nbh = nbh - nbh.mean(axis=1, keepdims=True)
        cov = np.einsum("nki,nkj->nij", nbh, nbh)
        _, vecs = np.linalg.eigh(cov)  # eigenvalues ascending
        out[start:stop] = vecs[:, :, 0]
    return out / np.linalg.norm(out, axis=1, keepdims=True)


def consistent_signs(points: np.ndarray, normals: np.ndarray, knn_indices: np.ndarray) -> np.ndarray:
    """Signs (+1/-1) making normals agree along a minimum spanning tree of the kNN graph.

    Edge weights are ``1 - |n_i . n_j| + 3 (|n_i . e| + |n_j . e|)``, e the unit edge
    direction: the first term is Hoppe et al.'s (1992), so signs are decided across the
    most parallel pairs first; the second keeps the tree off edges that leave the tangent
    planes, which is what an edge across a thin part of the surface does (its two ends
    have anti-parallel normals, |n_i . n_j| ~ 1, and plain Hoppe weights would prefer
    it). Measured on the real meshes: the mesh vertex normals of camelhead disagreed with
    the propagation at 466 of 11381 points with plain Hoppe weights, at none with these.
    Each point's sign is the product of the edge flips on its tree path to the root,
    computed by pointer doubling (O(N log depth), no Python loop over points).

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    normals : (N, 3) numpy.ndarray of float64
        Unit normals, arbitrary signs.
    knn_indices : (N, K) numpy.ndarray of int64
        A connected neighbourhood graph.

    Returns
    -------
    (N,) numpy.ndarray of float64
        ``signs * normals`` is consistently oriented (root point keeps its sign; every
        tree component has its own root if the graph is disconnected).
    """
    n, k = knn_indices.shape
    rows = np.repeat(np.arange(n, dtype=np.int64), k)
    cols = knn_indices.ravel()
    dots = np.einsum("ij,ij->i", normals[rows], normals[cols])
    edge = points[cols] - points[rows]
    edge /= np.linalg.norm(edge, axis=1, keepdims=True)
    off_plane = np.abs(np.einsum("ij,ij->i", normals[rows], edge)) + np.abs(np.einsum("ij,ij->i", normals[cols], edge))
    # csgraph treats explicit zeros as missing edges: keep every weight strictly positive.
    weights = 1.0 - np.abs(dots) + _OFF_PLANE_WEIGHT * off_plane + 1e-9
    graph = sp.csr_matrix((weights, (rows, cols)), shape=(n, n))
    tree = minimum_spanning_tree(graph)
    tree = tree + tree.T
    parent = np.arange(n, dtype=np.int64)
    visited = np.zeros(n, dtype=bool)
    for root in range(n):  # one iteration per tree component: one for connected input
        if visited[root]:
            continue
        order, pred = breadth_first_order(tree, root, directed=False, return_predecessors=True)
        visited[order] = True
        child = order[1:]
        parent[child] = pred[child]
        if visited.all():
            break
    flip = np.where(np.einsum("ij,ij->i", normals, normals[parent]) < 0.0, -1.0, 1.0)
    flip[parent == np.arange(n)] = 1.0
    # Pointer doubling: after r rounds flip[i] is the product over 2^r ancestors.
    while True:
        grand = parent[parent]
        flip = flip * flip[parent]
        if np.array_equal(grand, parent):
            break
        parent = grand
    return flip


def _global_sign(points: np.ndarray, normals: np.ndarray) -> float:
    total = normals.sum(axis=0)
    if np.linalg.norm(total) >= _CANCEL_TOL * normals.shape[0]:
        axis = int(np.argmax(np.abs(total)))
        return 1.0 if total[axis] >= 0 else -1.0
    outward = np.einsum("ij,ij->", normals, points - points.mean(axis=0))
    return 1.0 if outward >= 0 else -1.0


def orient_normals(points: np.ndarray, normals: np.ndarray, knn_indices: np.ndarray) -> np.ndarray:
    """Consistently oriented normals with the module's global sign rule.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    normals : (N, 3) numpy.ndarray of float64
        Unit normals, arbitrary signs (e.g. from :func:`pca_normals`).
    knn_indices : (N, K) numpy.ndarray of int64

    Returns
    -------
    (N, 3) numpy.ndarray of float64
    """
    oriented = normals * consistent_signs(points, normals, knn_indices)[:, None]
    return oriented * _global_sign(points, oriented)


SMOOTHING_KINDS = ("linear", "average")


def smooth_normals(points: np.ndarray, normals: np.ndarray, knn_indices: np.ndarray,
                   knn_distances: np.ndarray, mean_spacing: float, *, method: str = "linear") -> np.ndarray:
    """Distance-weighted smoothing of normals over the K-neighbourhood (Sec. 3.1).

    Weights are ``1 / (|p - q| + 1e-4 l)`` over the K neighbours q; the point itself is
    left out, as in the authors' DEM code (the small offset only guards near-coincident
    points). The paper evaluates this in-line with the DEM; since it does not depend on
    the DEM centre, it is computed once here, which gives the same normals.

    ``method="average"`` is the paper's weighted mean of the neighbours' normals. On a
    curved surface a one-sided neighbourhood (every boundary point) tilts that mean
    towards the neighbours' side by about (offset x curvature), which costs DEM accuracy
    near the boundary. ``method="linear"`` (default) fits the same weighted data with a
    linear model ``n(q) = a + J (q - p)`` in p's tangent plane and keeps ``a``: the
    weighted average corrected for that first-order tilt (local-linear instead of
    local-constant regression). It smooths noise about as much and has no boundary tilt.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    normals : (N, 3) numpy.ndarray of float64
        Consistently oriented unit normals.
    knn_indices, knn_distances : (N, K) numpy.ndarray
    mean_spacing : float
        ``l``.
    method : {"linear", "average"}

    Returns
    -------
    (N, 3) numpy.ndarray of float64
        Unit normals.

    Raises
    ------
    InvalidInputError
        Unknown ``method``.
    """
    if method not in SMOOTHING_KINDS:
        raise InvalidInputError(f"normal smoothing must be one of {', '.join(SMOOTHING_KINDS)}, got {method!r}.")
    n = normals.shape[0]
    avg = np.empty_like(normals)
    for start in range(0, n, _PCA_CHUNK):
        sl = slice(start, min(start + _PCA_CHUNK, n))
        idx = knn_indices[sl]
        w = 1.0 / (knn_distances[sl] + 1e-4 * mean_spacing)
        nbr = normals[idx]
        if method == "average":
            avg[sl] = np.einsum("nk,nkj->nj", w, nbr)
            continue
        e1, e2 = tangent_frames(normals[sl])
        d = points[idx] - points[sl, None, :]
        design = np.stack([np.ones(idx.shape), np.einsum("nki,ni->nk", d, e1), np.einsum("nki,ni->nk", d, e2)],
                          axis=-1)
        lhs = np.einsum("nk,nki,nkj->nij", w, design, design)
        # A tiny ridge on the slopes keeps collinear neighbourhoods solvable; their
        # intercept then tends to the plain weighted average.
        ridge = 1e-9 * np.einsum("nii->n", lhs)[:, None, None] * np.diag([0.0, 1.0, 1.0])
        rhs = np.einsum("nk,nki,nkj->nij", w, design, nbr)
        avg[sl] = np.linalg.solve(lhs + ridge, rhs)[:, 0, :]
    norm = np.linalg.norm(avg, axis=1, keepdims=True)
    # A neighbourhood whose normals cancel exactly cannot be averaged: keep the original.
    bad = norm[:, 0] < 1e-12
    norm[bad] = 1.0
    avg[bad] = normals[bad]
    return avg / norm


def check_user_normals(points: np.ndarray, normals: np.ndarray, fitted: np.ndarray, knn_indices: np.ndarray) -> None:
    """Raise when user-supplied normals are inconsistently oriented or off the surface.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    normals : (N, 3) numpy.ndarray of float64
        The user's unit normals.
    fitted : (N, 3) numpy.ndarray of float64
        PCA normals of the same points (any signs).
    knn_indices : (N, K) numpy.ndarray of int64

    Raises
    ------
    InconsistentNormalsError
        Some normals point to the other side of the surface than the rest (a
        consistent field needs no sign change under MST propagation), or the normals are
        mostly far from perpendicular to the point set (median ``|n . n_pca| < 0.5``,
        i.e. more than 60 degrees off).
    """
    n = normals.shape[0]
    signs = consistent_signs(points, normals, knn_indices)
    flipped = int((signs < 0).sum())
    minority = min(flipped, n - flipped)
    if minority > 0:
        odd = np.flatnonzero(signs < 0) if flipped <= n - flipped else np.flatnonzero(signs > 0)
        raise InconsistentNormalsError(
            f"{minority} of {n} given normals point to the other side of the surface than their "
            f"neighbours (first: point {int(odd[0])}); fix their orientation, or omit normals to let "
            "parambench estimate them."
        )
    align = np.abs(np.einsum("ij,ij->i", normals, fitted))
    if np.median(align) < 0.5:
        raise InconsistentNormalsError(
            f"the given normals are far from perpendicular to the point set (median |cos| to the fitted "
            f"normals {np.median(align):.2f}); fix them, or omit normals to let parambench estimate them."
        )


def tangent_frames(normals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A right-handed orthonormal tangent frame per normal, continuous away from n_z = -1.

    Uses the branchless construction of Duff et al. (2017), so ``e1 x e2 = n``.

    Parameters
    ----------
    normals : (N, 3) numpy.ndarray of float64
        Unit normals.

    Returns
    -------
    e1, e2 : (N, 3) numpy.ndarray of float64
    """
    x, y, z = normals[:, 0], normals[:, 1], normals[:, 2]
    sign = np.where(z >= 0.0, 1.0, -1.0)
    a = -1.0 / (sign + z)
    b = x * y * a
    e1 = np.stack([1.0 + sign * x * x * a, sign * b, -sign * x], axis=1)
    e2 = np.stack([b, sign + y * y * a, -y], axis=1)
    return e1, e2
