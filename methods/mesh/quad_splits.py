"""Quads whose diagonal a triangulation could take either way, and weights that do not choose.

A mesh made from a uv map (the refinement of :mod:`parambench.methods.pointset.mesh_refine`)
is the map's Delaunay triangulation. Where four points are nearly cocircular in uv (every
cell of a lattice: an elevation raster, a range image, a grid sampling), the diagonal is a
coin toss; another tool's mesh of the same points takes the other one as often. A
cotangent map solved on one split can leave such a quad non-convex, which flips a triangle
of the other split: on pymeshlab's fractal terrain at height 0.3 (129 x 129, knife-edge
ridges) cotangent SCP on its own mesh folds 0 of its triangles and 1 of the other split's,
and the map solved on the other split folds 1 of the mesh's.

Averaging the two splits' cotangent weights on such quads gives a Dirichlet energy that
belongs to neither: cotangent SCP on that terrain with every cell's two splits averaged
folds 0 triangles of either split, and on ordinary rasters the refined maps come nearer
conformal on both splits (:data:`SPLIT_TOLERANCE_DEG`). It is still
at least the image area on every quad (each split's energy is, and both splits' images
cover the same quadrilateral), so the conformal energy keeps the non-negativity from
k = 1 that cotangent weights have.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from parambench.datasets_gen.surface import DEGENERATE_AREA_TOL, flat_faces

from .topology import interior_edges
from .weights import mesh_weights

__all__ = ["SPLIT_TOLERANCE_DEG", "ambiguous_quads", "split_averaged_cotangent"]

#: A quad's diagonal counts as a coin toss when the two angles opposite it (in uv) sum to
#: within this many degrees of 180 (exactly 180: cocircular, either diagonal is Delaunay;
#: every cell of a lattice's map comes near). Measured, ``ocp``'s refined maps of lattices,
#: QC over scp-igl's on the mesh's split / on the other diagonal of every cell, none -> 10
#: degrees: matplotlib's jacksboro DEM (every second sample) 1.0016 / 1.0015 -> 1.0010 /
#: 1.0010, pymeshlab's fractal terrain at height 0.2 1.0034 / 1.0029 -> 1.0021 / 1.0022; at
#: height 0.3 (knife-edge ridges) 1.0107 / 1.0129 -> 1.0100 / 1.0197 with foldovers 1 / 2
#: -> 0 / 3: a wash there; the generated grid samplings at 2k within 2e-4 (the cap's
#: distance from its exact map 8.8e-5 -> 9.5e-5 of the diameter). Wider tolerances pair
#: more of a distorted map's cells (terrain h0.3: 7,108 of 16,384 at 10 degrees, 15,318 at
#: 45; foldovers 0 / 1 from 30 degrees on) but average in splits far from Delaunay: the
#: grid-sampled cap at 20k points, 6.3e-6 of the diameter from its exact map without,
#: 6.1e-6 at 10, 9.1e-6 at 20, 1.5e-4 at 45 degrees (requiring the flipped split to be
#: Delaunay in 3D kept the cap but lost the terrains' gains: h0.3 1.018x with 1 foldover).
SPLIT_TOLERANCE_DEG = 10.0

#: Rounds of the matching in :func:`ambiguous_quads` (each takes every quad that is the most
#: ambiguous of all the candidate quads its two triangles belong to).
_MATCH_ROUNDS = 8


def ambiguous_quads(points: np.ndarray, faces: np.ndarray, uv: np.ndarray,
                    tolerance_deg: float = SPLIT_TOLERANCE_DEG) -> tuple[np.ndarray, np.ndarray]:
    """Pairs of triangles whose shared diagonal is nearly a Delaunay tie in uv, and their flips.

    Each triangle belongs to at most one pair (the most ambiguous diagonal first). A quad is
    left out where its flipped triangles would have no area in 3D, or would face the other
    way in uv (a non-convex quad).

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    faces : (M, 3) numpy.ndarray of int64
        Consistently oriented triangles.
    uv : (N, 2) numpy.ndarray of float64
        The map whose triangulation ``faces`` is.
    tolerance_deg : float
        Largest distance (degrees) of the two opposite angles' sum from 180.

    Returns
    -------
    split : (2 Q, 3) numpy.ndarray of int64
        The quads' triangles as in ``faces``, two rows per quad.
    flipped : (2 Q, 3) numpy.ndarray of int64
        The same quads split along the other diagonal, oriented as ``faces``.
    """
    edges, pair, opposite = interior_edges(faces)
    a, b = edges[:, 0], edges[:, 1]
    c, d = opposite[:, 0], opposite[:, 1]
    gap = np.abs(_angle(uv, a, b, c) + _angle(uv, a, b, d) - np.pi)
    candidate = np.flatnonzero(gap <= np.radians(tolerance_deg))
    # The new triangles (a, d, c) and (d, b, c): a -> b runs in the first face, so c lies
    # left of it and d right; both keep the faces' orientation.
    new = np.stack([np.column_stack([a, d, c]), np.column_stack([d, b, c])], axis=1)[candidate]
    solid = ~flat_faces(points, new.reshape(-1, 3), DEGENERATE_AREA_TOL).reshape(-1, 2).any(axis=1)
    # A near tie can still be a non-convex quad (an angle near 180 degrees at a or b): its
    # other split would fold in uv, so it is no triangulation of the map.
    side = np.sign(_doubled_area(uv, faces[pair[candidate, 0]]))[:, None]
    convex = (np.sign(_doubled_area(uv, new.reshape(-1, 3))).reshape(-1, 2) == side).all(axis=1)
    keep = solid & convex
    candidate, new = candidate[keep], new[keep]
    chosen = _matching(pair[candidate], gap[candidate], faces.shape[0])
    split = faces[pair[candidate[chosen]]].reshape(-1, 3)
    return split.astype(np.int64), new[chosen].reshape(-1, 3).astype(np.int64)


def _doubled_area(uv: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Twice the signed uv area of each face (positive counter-clockwise)."""
    e1, e2 = uv[faces[:, 1]] - uv[faces[:, 0]], uv[faces[:, 2]] - uv[faces[:, 0]]
    return e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]


def _angle(uv: np.ndarray, a: np.ndarray, b: np.ndarray, apex: np.ndarray) -> np.ndarray:
    """The angle (radians) at ``apex`` of the uv triangles (a, b, apex)."""
    u, v = uv[a] - uv[apex], uv[b] - uv[apex]
    return np.arctan2(np.abs(u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]), np.einsum("ij,ij->i", u, v))


def _matching(pair: np.ndarray, gap: np.ndarray, n_faces: int) -> np.ndarray:
    """Indices of candidate quads such that no two share a triangle, most ambiguous first.

    Each round takes every candidate that ranks first among the candidates of both its
    triangles (ties broken by order), then drops the candidates of the triangles taken.
    """
    rank = np.empty(gap.size, dtype=np.int64)
    rank[np.argsort(gap, kind="stable")] = np.arange(gap.size)
    alive = np.ones(gap.size, dtype=bool)
    used = np.zeros(n_faces, dtype=bool)
    chosen = []
    for _ in range(_MATCH_ROUNDS):
        live = np.flatnonzero(alive)
        if live.size == 0:
            break
        best = np.full(n_faces, np.iinfo(np.int64).max)
        np.minimum.at(best, pair[live, 0], rank[live])
        np.minimum.at(best, pair[live, 1], rank[live])
        win = live[(best[pair[live, 0]] == rank[live]) & (best[pair[live, 1]] == rank[live])]
        chosen.append(win)
        used[pair[win].ravel()] = True
        alive &= ~used[pair].any(axis=1)
    return np.concatenate(chosen) if chosen else np.empty(0, dtype=np.int64)


def split_averaged_cotangent(points: np.ndarray, weights: sp.spmatrix, split: np.ndarray,
                             flipped: np.ndarray) -> sp.csr_matrix:
    """Cotangent weights with each quad's two splits averaged.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    weights : (N, N) scipy.sparse matrix of float64
        Cotangent weights of a mesh holding the triangles ``split``.
    split, flipped : (2 Q, 3) numpy.ndarray of int64
        From :func:`ambiguous_quads`.

    Returns
    -------
    (N, N) scipy.sparse.csr_matrix of float64
        ``weights`` with half of each quad's own triangles' weights replaced by half of its
        flipped triangles' (zero diagonal; the flipped diagonals become edges).
    """
    if split.shape[0] == 0:
        return sp.csr_matrix(weights)
    out = sp.csr_matrix(weights + 0.5 * (mesh_weights(points, flipped, "cotangent")
                                         - mesh_weights(points, split, "cotangent")))
    out.setdiag(0.0)
    out.eliminate_zeros()
    return out
