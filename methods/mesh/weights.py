"""Edge weights W (the off-diagonal of a mesh Laplacian L = D - W) of Sec. 2 and Sec. 5.

Conventions: ``W[i, j]`` is the weight of spoke i -> j in vertex i's row; the diagonal is
zero; rows of non-symmetric kinds (authalic, mean-value, uniform, hybrid, every
normalized kind) are not mirrored. The scale is the one of libigl's cotangent matrix,
``w_ij = (cot a_ij + cot b_ij) / 2``, for which ``E_D(u) = 1/2 u^T L u`` is exactly the
Dirichlet energy of the piecewise-linear map, so that ``E_D >= A`` with equality for a
conformal map and k_opt = 1 in the k search.

Kinds
-----
cotangent
    ``(cot a_ij + cot b_ij) / 2`` from :func:`igl.cotmatrix` (a, b the angles opposite
    the edge; one term on boundary edges). Symmetric.
uniform
    The cotangent weights of a *regular* one-ring with vertex i's connectivity (Sec. 5:
    "scaled cotangent weights on regular polygons"). Each face corner at vertex i is taken
    as an isosceles triangle with apex angle ``theta_i`` and contributes
    ``tan(theta_i / 2) / 2`` to both of its spokes. Interior vertex with m faces:
    ``theta_i = 2 pi / m``, so every spoke gets ``tan(pi / m)`` (``1/sqrt(3)`` at valence
    6, exactly the cotangent weight of an equilateral lattice). Boundary vertex with m
    faces: the fan is a regular *half* polygon over a straight boundary,
    ``theta_i = pi / max(m, 2)``; its two boundary spokes lie in one face and get half the
    weight of its interior spokes, as cotangent weights do. (m = 1, a corner with one
    face, would give a flat triangle; it is treated as m = 2, a right-angled corner.)
    The per-vertex rows are then symmetrised, ``w_ij = (c_i->j + c_j->i) / 2``, so the
    weights define an energy (``u^T L u`` only sees the symmetric part anyway) and the
    conformal operator is Hermitian; where neighbouring valences agree nothing changes.
    Unsymmetrised rows make the k landscape erratic (measured: k_opt 1.34 instead of
    1.00 on a lattice saddle whose sides have valence-5 vertices). On a triangular
    lattice these weights equal the cotangent weights exactly.
authalic
    Desbrun, Meyer & Alliez 2002: ``(cot g_ij + cot d_ij) / |x_i - x_j|^2`` with g, d the
    angles *at x_j* in the faces beside edge ij, halved to the cotangent scale. Any angle
    at x_j above 90 degrees makes a weight negative. With ``uniform_at`` the rows of those
    vertices are replaced by the *uniform authalic* weights ``u_ij / |x_i - x_j|^2``, with
    ``u_ij`` the uniform weights below before their symmetrisation (``tan(theta_i / 2) / 2``
    per face beside the edge, theta_i vertex i's regular apex angle): on a regular
    one-ring the angles at x_j are the base angles ``(pi - theta_i) / 2``, whose cotangent
    is ``tan(theta_i / 2)``, so these are the authalic formula on the regular one-ring of
    vertex i's valence, with the true edge lengths (the authalic scale, unlike plain
    uniform weights), and positive. Only rows change (the authalic weights are not
    symmetric anyway). ``uniform_at="negative"``: every vertex with
    a negative authalic weight in its row. The mesh methods use this only as a fallback
    where the plain authalic weights give no regular map
    (:mod:`parambench.methods.mesh.fallbacks`).
mean-value
    Floater 2003: ``(tan(g_ij / 2) + tan(d_ij / 2)) / |x_i - x_j|`` with g, d the angles
    *at x_i* in the faces beside edge ij, halved likewise.
hybrid
    Cotangent weights, except uniform weights on every edge at a vertex of
    ``uniform_at`` (its row and, to keep W symmetric, its column). Which vertices is the
    point of Sec. 5 / Fig. 12: uniform weights only where negative cotangent weights fold
    the map. That needs the map, so the plugins' default ``uniform_at="auto"`` is the
    fold-driven rule of :mod:`parambench.methods.mesh.hybrid` (solve with cotangent weights, make
    the vertices around flipped triangles uniform, solve again), which calls this
    function with a vertex mask. Here ``uniform_at`` is a vertex set (indices, a
    ``"3,17,42"`` string or a boolean mask) or ``"negative"`` (also the default, None):
    every vertex with a negative cotangent weight in its row, so no negative weight is
    left (on a noisy scan that can be half the mesh: measured on ``real/camelhead``, 51 %
    of the vertices, QC 1.073 -> 2.017). (Replacing rows only, the literal reading, gives a
    non-symmetric operator whose k landscape is erratic and whose optimum had *more*
    foldovers than plain cotangent SCP in our trials.)

``normalized=True`` divides each row by its sum (the rows of I - W then sum to zero and
the diagonal is 1); a row whose sum is <= 0 (authalic weights between obtuse triangles)
is divided by the sum of its absolute values instead.
"""

from __future__ import annotations

from typing import Any

import igl
import numpy as np
import scipy.sparse as sp

from parambench.datasets_gen.errors import InvalidInputError, UnknownNameError


__all__ = ["WEIGHT_KINDS", "UNIFORM_AT_KINDS", "mesh_weights", "laplacian", "negative_cotangent_vertices",
           "negative_weight_rows", "uniform_vertex_mask", "corner_angles"]

#: Accepted values of ``kind``.
WEIGHT_KINDS = ("uniform", "cotangent", "authalic", "mean-value", "hybrid")
#: Kinds that take ``uniform_at`` (vertices whose weights are made uniform).
UNIFORM_AT_KINDS = ("hybrid", "authalic")


def corner_angles(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Interior angle of every face corner.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    faces : (M, 3) numpy.ndarray of int64

    Returns
    -------
    (M, 3) numpy.ndarray of float64
        ``angles[f, c]`` is the angle at vertex ``faces[f, c]``, in radians.
    """
    p = points[faces]                                   # (M, 3 corners, 3 coords)
    e_next = np.roll(p, -1, axis=1) - p                 # corner c -> c+1
    e_prev = np.roll(p, 1, axis=1) - p                  # corner c -> c-1
    cross = np.linalg.norm(np.cross(e_next, e_prev), axis=2)
    dot = np.einsum("fck,fck->fc", e_next, e_prev)
    # atan2 is accurate for angles near 0 and pi, unlike arccos of the cosine.
    return np.arctan2(cross, dot)


def _directed_spokes(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For every face corner c: its vertex i, the next vertex j and the previous vertex k."""
    i = faces
    j = np.roll(faces, -1, axis=1)
    k = np.roll(faces, 1, axis=1)
    return i, j, k


def _assemble(n: int, rows: np.ndarray, cols: np.ndarray, vals: np.ndarray) -> sp.csr_matrix:
    w = sp.csr_matrix((vals.ravel(), (rows.ravel(), cols.ravel())), shape=(n, n))
    w.sum_duplicates()
    return w


def _cotangent(points: np.ndarray, faces: np.ndarray) -> sp.csr_matrix:
    w = sp.csr_matrix(igl.cotmatrix(points, faces))
    w.setdiag(0.0)
    w.eliminate_zeros()
    return w


def _vertex_face_counts(faces: np.ndarray, n: int) -> np.ndarray:
    return np.bincount(faces.ravel(), minlength=n)


def _boundary_vertex_mask(faces: np.ndarray, n: int) -> np.ndarray:
    mask = np.zeros(n, dtype=bool)
    for loop in igl.boundary_loop_all(np.ascontiguousarray(faces, dtype=np.int64)):
        mask[np.asarray(loop, dtype=np.int64)] = True
    return mask


def _uniform_rows(faces: np.ndarray, n: int) -> sp.csr_matrix:
    """Row i: the cotangent weights of a regular one-ring with vertex i's connectivity (not symmetrised)."""
    m = _vertex_face_counts(faces, n).astype(np.float64)
    on_boundary = _boundary_vertex_mask(faces, n)
    apex = np.where(on_boundary, np.pi / np.maximum(m, 2.0), 2.0 * np.pi / np.maximum(m, 1.0))
    corner_w = 0.5 * np.tan(0.5 * apex)                 # per vertex, per face corner
    i, j, k = _directed_spokes(faces)
    cw = corner_w[i]
    return _assemble(n, np.concatenate([i, i]), np.concatenate([j, k]), np.concatenate([cw, cw]))


def _uniform(faces: np.ndarray, n: int) -> sp.csr_matrix:
    rows = _uniform_rows(faces, n)
    return sp.csr_matrix(0.5 * (rows + rows.T))


def _authalic(points: np.ndarray, faces: np.ndarray) -> sp.csr_matrix:
    ang = corner_angles(points, faces)
    i, j, k = _directed_spokes(faces)
    ang_next = np.roll(ang, -1, axis=1)                 # angle at j, for corner (i; j, k)
    ang_prev = np.roll(ang, 1, axis=1)                  # angle at k
    len2_ij = np.sum((points[j] - points[i]) ** 2, axis=2)
    len2_ik = np.sum((points[k] - points[i]) ** 2, axis=2)
    # In face (i, j, k), spoke i->j sees the angle at j, spoke i->k the angle at k.
    w_ij = 0.5 / np.tan(ang_next) / len2_ij
    w_ik = 0.5 / np.tan(ang_prev) / len2_ik
    return _assemble(points.shape[0], np.concatenate([i, i]), np.concatenate([j, k]), np.concatenate([w_ij, w_ik]))


def _authalic_uniform_rows(points: np.ndarray, faces: np.ndarray, chosen: np.ndarray) -> sp.csr_matrix:
    """Authalic weights, with the uniform authalic weights ``w^uni_ij / |x_i - x_j|^2`` in the rows of ``chosen``."""
    n = points.shape[0]
    w = _authalic(points, faces).tocoo()
    swap = chosen[w.row]
    if not swap.any():
        return w.tocsr()
    # vertex i's own regular one-ring, unsymmetrised: the row is i's, like the authalic row it replaces
    uni = _uniform_rows(faces, n)
    rows, cols = w.row[swap], w.col[swap]
    vals = w.data.copy()
    vals[swap] = np.asarray(uni[rows, cols]).ravel() / np.sum((points[cols] - points[rows]) ** 2, axis=1)
    return sp.csr_matrix((vals, (w.row, w.col)), shape=(n, n))


def _mean_value(points: np.ndarray, faces: np.ndarray) -> sp.csr_matrix:
    ang = corner_angles(points, faces)
    i, j, k = _directed_spokes(faces)
    half_tan = 0.5 * np.tan(0.5 * ang)                  # angle at i, shared by both spokes of the corner
    len_ij = np.linalg.norm(points[j] - points[i], axis=2)
    len_ik = np.linalg.norm(points[k] - points[i], axis=2)
    return _assemble(points.shape[0], np.concatenate([i, i]), np.concatenate([j, k]),
                     np.concatenate([half_tan / len_ij, half_tan / len_ik]))


def negative_cotangent_vertices(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Vertices with at least one negative cotangent weight in their row.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    faces : (M, 3) numpy.ndarray of int64

    Returns
    -------
    (N,) numpy.ndarray of bool
    """
    w = _cotangent(points, faces).tocoo()
    mask = np.zeros(points.shape[0], dtype=bool)
    mask[w.row[w.data < 0]] = True
    return mask


def negative_weight_rows(weights: sp.spmatrix) -> np.ndarray:
    """Rows of a weight matrix with at least one negative entry.

    Parameters
    ----------
    weights : (N, N) scipy.sparse matrix of float64

    Returns
    -------
    (N,) numpy.ndarray of bool
    """
    w = sp.coo_matrix(weights)
    mask = np.zeros(w.shape[0], dtype=bool)
    mask[w.row[w.data < 0]] = True
    return mask


def uniform_vertex_mask(uniform_at: Any, points: np.ndarray, faces: np.ndarray, kind: str = "hybrid") -> np.ndarray:
    """The vertices a ``uniform_at`` value selects.

    Parameters
    ----------
    uniform_at : None, "negative", str, array of int or (N,) array of bool
        See :func:`mesh_weights`.
    points : (N, 3) numpy.ndarray of float64
    faces : (M, 3) numpy.ndarray of int64
    kind : {"hybrid", "authalic"}
        Whose negative weights ``"negative"`` (and, for hybrid, None) means: the cotangent
        weights for hybrid, the authalic ones for authalic.

    Returns
    -------
    (N,) numpy.ndarray of bool

    Raises
    ------
    InvalidInputError
        ``"auto"`` (the plugins' fold-driven rule needs a solve: see
        :mod:`parambench.methods.mesh.hybrid`), an unparsable string, indices out of range or a
        boolean mask of the wrong length.
    """
    n = points.shape[0]
    if uniform_at is None or (isinstance(uniform_at, str) and uniform_at == "negative"):
        if kind == "authalic":
            return negative_weight_rows(_authalic(points, faces))
        return negative_cotangent_vertices(points, faces)
    if isinstance(uniform_at, str) and uniform_at == "auto":
        raise InvalidInputError(
            "uniform_at='auto' is the fold-driven rule of the scp and dncp-opt methods (it needs their solve, "
            "see parambench.methods.mesh.hybrid); mesh_weights takes 'negative' or a vertex set."
        )
    if isinstance(uniform_at, str):
        try:
            idx = np.array([int(s) for s in uniform_at.replace(";", ",").split(",") if s.strip()], dtype=np.int64)
        except ValueError:
            raise InvalidInputError(
                f"uniform_at={uniform_at!r} is neither 'auto', 'negative' nor a comma-separated list of vertex indices."
            ) from None
    else:
        arr = np.asarray(uniform_at)
        if arr.dtype == bool:
            if arr.shape != (n,):
                raise InvalidInputError(f"a boolean uniform_at must have shape ({n},), got {arr.shape}.")
            return arr.copy()
        idx = arr.astype(np.int64).ravel()
    if idx.size and (idx.min() < 0 or idx.max() >= n):
        raise InvalidInputError(f"uniform_at indices must lie in [0, {n - 1}]; got range [{idx.min()}, {idx.max()}].")
    mask = np.zeros(n, dtype=bool)
    mask[idx] = True
    return mask


def _hybrid(points: np.ndarray, faces: np.ndarray, uniform_at: Any) -> sp.csr_matrix:
    n = points.shape[0]
    chosen = uniform_vertex_mask(uniform_at, points, faces)
    cot = _cotangent(points, faces).tocoo()
    uni = _uniform(faces, n).tocsr()
    # Every edge touching a chosen vertex (its row and its column) becomes uniform, so W
    # stays symmetric and, with "negative", no negative cotangent weight survives (both
    # ends of a negative edge are chosen).
    swap = chosen[cot.row] | chosen[cot.col]
    vals = cot.data.copy()
    vals[swap] = np.asarray(uni[cot.row[swap], cot.col[swap]]).ravel()
    return sp.csr_matrix((vals, (cot.row, cot.col)), shape=(n, n))


def _normalize_rows(w: sp.csr_matrix, kind: str) -> sp.csr_matrix:
    """Each row divided by its sum, or by the sum of its absolute values where the sum is <= 0.

    Authalic weights (cotangents of the angles at the *far* vertices) can sum to zero or
    less at a vertex between obtuse triangles: 5 rows of ``real/camelhead``, 18 of
    ``real/bunny10k``. Such a row cannot be divided by its sum; dividing it by
    ``sum_j |w_ij|`` (positive for any vertex with an edge) keeps the rows of the Laplacian
    summing to zero (any positive row scale does) and the row's scale at most 1, where
    the other rows have diagonal exactly 1.
    """
    sums = np.asarray(w.sum(axis=1)).ravel()
    bad = ~(sums > 0)
    if bad.any():
        sums[bad] = np.asarray(abs(w).sum(axis=1)).ravel()[bad]
        if not np.all(sums > 0):
            raise InvalidInputError(f"the {kind} weights have an empty row (vertex "
                                    f"{int(np.flatnonzero(~(sums > 0))[0])} is on no edge) and cannot be normalized.")
    return sp.csr_matrix(sp.diags(1.0 / sums) @ w)


def mesh_weights(points: np.ndarray, faces: np.ndarray, kind: str, normalized: bool = False,
                 uniform_at: Any = None) -> sp.csr_matrix:
    """Edge weight matrix W of a triangle mesh.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    faces : (M, 3) numpy.ndarray of int64
    kind : {"uniform", "cotangent", "authalic", "mean-value", "hybrid"}
        See the module docstring for each formula and its scale.
    normalized : bool
        Divide each row by its sum.
    uniform_at : None, "negative", str, array of int or (N,) array of bool
        For ``kind="hybrid"``: vertices whose edges are uniform. None or ``"negative"``:
        the vertices with a negative cotangent weight; ``"3,17,42"`` or an index array:
        those vertices; a boolean mask: the True ones. (``"auto"``, the methods' default,
        is resolved by :func:`parambench.methods.mesh.hybrid.fold_driven_hybrid` before this call.)
        For ``kind="authalic"``: vertices whose row holds the uniform authalic weights
        (module docstring); None: none (plain authalic weights), ``"negative"``: the vertices
        with a negative authalic weight, or a vertex set as for hybrid.

    Returns
    -------
    (N, N) scipy.sparse.csr_matrix of float64
        Zero diagonal; ``W[i, j] != 0`` only for mesh edges ij.

    Raises
    ------
    UnknownNameError
        ``kind`` is not one of :data:`WEIGHT_KINDS`.
    InvalidInputError
        Bad ``uniform_at``; ``uniform_at`` given for another kind; an empty row with
        ``normalized=True``; non-finite weights (degenerate triangles).
    """
    if kind not in WEIGHT_KINDS:
        raise UnknownNameError(f"unknown weight kind {kind!r}; choose one of {', '.join(WEIGHT_KINDS)}.")
    if uniform_at is not None and kind not in UNIFORM_AT_KINDS:
        raise InvalidInputError(f"uniform_at only applies to kind='hybrid' or 'authalic', not {kind!r}; drop it or "
                                "use 'hybrid'.")
    n = points.shape[0]
    if kind == "cotangent":
        w = _cotangent(points, faces)
    elif kind == "uniform":
        w = _uniform(faces, n)
    elif kind == "authalic" and uniform_at is None:
        w = _authalic(points, faces)
    elif kind == "authalic":
        w = _authalic_uniform_rows(points, faces, uniform_vertex_mask(uniform_at, points, faces, kind="authalic"))
    elif kind == "mean-value":
        w = _mean_value(points, faces)
    else:
        w = _hybrid(points, faces, uniform_at)
    if not np.all(np.isfinite(w.data)):
        raise InvalidInputError(f"{kind} weights are not finite (zero-length edges or flat triangles); "
                                "remove degenerate faces first.")
    if normalized:
        w = _normalize_rows(w, kind)
    return w


def laplacian(weights: sp.spmatrix) -> sp.csr_matrix:
    """Graph Laplacian L = D - W with D = diag(row sums of W).

    Parameters
    ----------
    weights : (N, N) scipy.sparse matrix of float64, zero diagonal

    Returns
    -------
    (N, N) scipy.sparse.csr_matrix of float64
        Rows sum to zero, so constants are in the null space (translations).
    """
    w = sp.csr_matrix(weights)
    return sp.csr_matrix(sp.diags(np.asarray(w.sum(axis=1)).ravel()) - w)
