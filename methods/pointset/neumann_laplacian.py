"""A point-set Laplacian whose quadratic form is the Dirichlet energy, boundary term included.

Why: OCP's ``L = I - W^tan`` (Sec. 4.2) has rows that reproduce linear functions at
*every* point, boundary points included. For a map z its energy ``z^H L z`` is then
missing the boundary term of Green's identity,

    int_S |grad u|^2 = - int_S u Lap u + oint_dS u d_nu u,

which for a (harmonic) conformal map is the whole Dirichlet energy. The single global k
of Eq. 15 compensates only on average (k_opt ~ 10-25 on the benchmark shapes) and the map
keeps a few per cent of extra conformal distortion, most of it near the boundary.

This module builds, from the front end's DEM balls,

    (L u)_i = s_i [(I - W) u]_i + [b_i . G_i u]        (b_i = 0 off the boundary)

* interior rows: W reproduces quadratics in the tangent plane (constraints sum w = 1,
  sum w t = 0, sum w (t_x^2 - t_y^2) = 0, sum w t_x t_y = 0, minimum weighted norm), so
  ``[(I - W) f]_i = -(q_i / 4) Lap f`` exactly for quadratic f with ``q_i = sum_j w_ij |t_j|^2``
  (Eq. 14 with a known per-point k_i = q_i / 2); the row scale ``s_i = 4 a_i / q_i`` turns
  it into ``-a_i Lap f``, a_i the area per point;
* boundary rows: W reproduces linear functions only (a half ball cannot carry the
  isotropy constraints without large negative weights), scaled the same way (a_i halved:
  half a cell), plus the Neumann term: the outward normal derivative from the
  least-squares tangent-plane gradient ``G_i``, times the outward "edge normal"
  ``b_i = R_{-90} (t_next - t_prev) / 2`` built from the two loop neighbours (for a planar
  boundary polygon ``sum_i x_i . b_i`` is exactly its area, so ``1/2 z^H L z`` equals the
  boundary area term of Eq. 7 for a linear map).

Boundary rows differ from interior ones in two more ways, both because the matrix is
not symmetric, so nothing keeps ``1/2 z^H L z`` above the enclosed area for every z (as
the cotangent Laplacian does): a boundary curve that curls at the sample scale (turning
number 3-15 at k = 1) can have negative conformal energy, and the k search then stops at
the k where those modes give way (k_opt 1.15-4.2, QC up to 2.4x cotangent SCP and folds
at the holes of graded and random samplings, measured on the 2k cases of
``bench/benchmarks/bench_realdata.py``). What keeps those modes out:

* the half cell's area ``a_i`` is measured, not modelled: a third of the area of the
  point's tangent-plane Delaunay fan inside the boundary (:func:`boundary_cell_areas`).
  The model ``area_factor * h^2 / 2`` with the spacing of interior neighbours was off by
  up to 4x where a boundary is sampled sparser than the inside next to it (graded
  samplings, real scans), and the row's stiffness against curling scales with ``a_i``;
* the linear weights of boundary rows use a narrower Gaussian
  (:data:`DEFAULT_BOUNDARY_WIDTH`): spread over two or three rings, they barely feel an
  oscillation of the boundary from one sample to the next, while the area term M sees it
  at full resolution.

Rows sum to zero. The matrix is not symmetric, but on a planar region every linear map
is an exact zero-energy solution of ``(L / 2 - M) z = 0`` (M: boundary area matrix), so
k_opt = 1 there and is close to 1 on curved surfaces: the k search of Eq. 16 then only
corrects the estimate of the area per point.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numba
import numpy as np
import scipy.sparse as sp

from parambench.datasets_gen.errors import InvalidInputError

from ..numba_cache import configure_numba_cache
from .local_fits import moment_rows
from .row_chunks import for_each_chunk

__all__ = [
    "DEFAULT_AREA_FACTOR",
    "DEFAULT_GAUSS_WIDTH",
    "DEFAULT_BOUNDARY_WIDTH",
    "BOUNDARY_AREAS",
    "boundary_cell_areas",
    "moment_weights",
    "gradient_stencils",
    "boundary_edge_normals",
    "stencil_matrix",
    "assembled_laplacian",
    "neumann_laplacian",
]

#: Area per sample in units of the mean kNN spacing l squared (K = 8). Measured as
#: (mesh area / N) / l^2 on the bump, cap and holes at 5k points: 0.58-0.63 for grid,
#: jittered and blue-noise samplings, 0.73-0.77 for uniform random ones.
DEFAULT_AREA_FACTOR = 0.65

#: Width of the Gaussian weighting of ball members, as a fraction of the squared ball
#: radius: omega_j = exp(-|t_j|^2 / (width * max_j |t_j|^2)).
DEFAULT_GAUSS_WIDTH = 0.5

#: Gaussian width of the boundary rows' linear weights (same units). Measured on the 20
#: random/graded 2k cases of bench_realdata.py (fold excluded), with measured boundary
#: areas: 0.08, 0.1, 0.15 and 0.2 all give 19 of 20 within 3 % of scp-igl with 0 folds
#: (the one left, protrusions/random, fails alike for every width); 0.25 leaves
#: holes-bumped/graded at +3.0 %, 0.5 (the interior width) holes/graded at +8.9 % with 2
#: folds and saddle/graded at +6.9 % with 3. 0.15 is the middle of the plateau.
DEFAULT_BOUNDARY_WIDTH = 0.15

#: ``boundary_area`` values of :func:`neumann_laplacian`: the measured half cell
#: (:func:`boundary_cell_areas`) or the spacing model ``area_factor * h^2 / 2``.
BOUNDARY_AREAS = ("fan", "spacing")

_MOMENTS = {"linear": 3, "quadratic": 5}

_CACHE, _ = configure_numba_cache(Path(__file__).resolve().parent)

#: Rows per chunk of :func:`assembled_laplacian` and of the balls' checks (on worker threads).
_ASSEMBLY_CHUNK = 65536


def _check_balls(coords: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    coords = np.asarray(coords, dtype=np.float64)
    mask = np.asarray(mask, dtype=bool)
    if coords.ndim != 3 or coords.shape[2] != 2 or mask.shape != coords.shape[:2]:
        raise InvalidInputError(f"coords must be (N, B, 2) and mask (N, B); got {coords.shape} and {mask.shape}.")
    # Checked in row chunks on threads, members only. Where the padding is zero already
    # (the front end's DEM coordinates) the coordinates are used as they are: at 1M
    # points a zero-padded copy was 0.7 GB, the largest array of ocp's Laplacian stage.
    n = coords.shape[0]
    finite, zero_padding = np.empty(n, dtype=bool), np.empty(n, dtype=bool)

    def rows_of(rows: slice) -> None:
        c, m = coords[rows], mask[rows, :, None]
        finite[rows] = np.isfinite(np.where(m, c, 0.0)).all(axis=(1, 2))
        zero_padding[rows] = ~(np.where(m, 0.0, c) != 0.0).any(axis=(1, 2))

    for_each_chunk(rows_of, n, _ASSEMBLY_CHUNK)
    if not finite.all():
        raise InvalidInputError("tangent coordinates contain NaN or inf.")
    return (coords if zero_padding.all() else np.where(mask[..., None], coords, 0.0)), mask


def _gaussian(coords: np.ndarray, mask: np.ndarray, width: float) -> np.ndarray:
    r2 = (coords**2).sum(-1)
    h2 = np.maximum(r2.max(axis=1, keepdims=True), np.finfo(float).tiny)
    return np.exp(-r2 / (width * h2)) * mask


def moment_weights(coords: np.ndarray, mask: np.ndarray, order: str = "quadratic", *,
                   width: float = DEFAULT_GAUSS_WIDTH, reg: float = 1e-10) -> np.ndarray:
    """Minimum-norm reconstruction weights with prescribed tangent-plane moments.

    Solves, per centre, ``min sum_j w_j^2 / omega_j`` subject to ``sum_j w_j = 1``,
    ``sum_j w_j t_j = 0`` and, for ``order="quadratic"``, ``sum_j w_j (t_x^2 - t_y^2) = 0``
    and ``sum_j w_j t_x t_y = 0`` (an isotropic second moment), with Gaussian
    ``omega_j``. Closed form ``w = Omega A^T (A Omega A^T)^{-1} e_1``, batched.

    Parameters
    ----------
    coords : (N, B, 2) numpy.ndarray of float64
        Tangent coordinates of the ball members relative to their centre (padding ignored).
    mask : (N, B) numpy.ndarray of bool
        True for real members.
    order : {"linear", "quadratic"}
    width : float
        Gaussian width (fraction of the squared ball radius).
    reg : float
        Relative Tikhonov term on the moment matrix (degenerate balls).

    Returns
    -------
    (N, B) numpy.ndarray of float64
        Weights, zero at padding, each row summing to 1.

    Raises
    ------
    InvalidInputError
        Bad shapes, non-finite coordinates, unknown order, or a ball with fewer members
        than constraints.
    """
    if order not in _MOMENTS:
        raise InvalidInputError(f"order must be one of {', '.join(_MOMENTS)}, got {order!r}.")
    t, m = _check_balls(coords, mask)
    n_con = _MOMENTS[order]
    if np.any(m.sum(axis=1) < n_con):
        raise InvalidInputError(f"{order} moment weights need balls of at least {n_con} members; "
                                "increase ball_k.")
    return _moment_rows(t, m, n_con, width, reg)


#: Centres per task of :func:`_moment_rows` (tasks are handed out to the worker threads).
_ROW_BLOCK = 16384


def _moment_rows(t: np.ndarray, m: np.ndarray, n_con: int, width: float, reg: float) -> np.ndarray:
    """:func:`moment_weights` on checked, padding-zeroed coordinates: the compiled kernel
    (:func:`parambench.methods.pointset.local_fits.moment_rows`) by row blocks on threads.

    numpy's batched 5x5 solves cost ~2 microseconds a matrix in LAPACK call overhead
    (3.1 s at a million points on two cores); the kernel needs no (rows, constraints, B)
    temporaries either.
    """
    out = np.empty(m.shape)
    coords = np.ascontiguousarray(t, dtype=np.float64)
    members = np.ascontiguousarray(m, dtype=np.bool_)
    for_each_chunk(lambda rows: moment_rows(coords, members, int(n_con), float(width), float(reg), rows.start,
                                            rows.stop, out), m.shape[0], _ROW_BLOCK)
    return out


def gradient_stencils(coords: np.ndarray, mask: np.ndarray, *, width: float | None = None,
                      reg: float = 1e-10) -> np.ndarray:
    """Weighted least-squares tangent-plane gradient at each centre.

    ``grad u(x_i) ~ sum_j P[i, :, j] (u_j - u_i)``, exact for linear u.

    Parameters
    ----------
    coords : (N, B, 2) numpy.ndarray of float64
    mask : (N, B) numpy.ndarray of bool
    width : float, optional
        Gaussian width as in :func:`moment_weights`; None (default): equal weights.
    reg : float
        As in :func:`moment_weights`.

    Returns
    -------
    (N, 2, B) numpy.ndarray of float64
        Zero at padding.

    Raises
    ------
    InvalidInputError
        Bad shapes or non-finite coordinates.
    """
    t, m = _check_balls(coords, mask)
    return _gradient_rows(t, m, width, reg)


def _gradient_rows(t: np.ndarray, m: np.ndarray, width: float | None, reg: float) -> np.ndarray:
    """:func:`gradient_stencils` on checked, padding-zeroed coordinates."""
    om = m.astype(np.float64) if width is None else _gaussian(t, m, width)
    mom = np.einsum("nb,nbp,nbq->npq", om, t, t)
    mom += reg * np.trace(mom, axis1=1, axis2=2)[:, None, None] * np.eye(2)
    return np.linalg.solve(mom, np.transpose(t * om[..., None], (0, 2, 1)))


def boundary_edge_normals(ball_indices: np.ndarray, coords: np.ndarray, loops: Sequence[np.ndarray]
                          ) -> tuple[np.ndarray, np.ndarray]:
    """Outward edge normals ``b_i`` of the boundary points, in each point's tangent frame.

    ``b_i = R_{-90} (t_next - t_prev) / 2`` from the DEM coordinates of the loop
    neighbours (the boundary lies to the right when walking a loop in its orientation:
    outer counter-clockwise, holes clockwise, seen from the normals). When a loop
    neighbour is not in the ball, ``b_i`` is the unit vector away from the ball's centroid
    times the mean 3D distance to the two loop neighbours... expressed via the ball; see
    the code.

    Parameters
    ----------
    ball_indices : (N, B) numpy.ndarray of int64
        Ball members, -1 padding.
    coords : (N, B, 2) numpy.ndarray of float64
        Their tangent coordinates.
    loops : sequence of (L_i,) numpy.ndarray of int64
        Oriented boundary loops.

    Returns
    -------
    points : (n_b,) numpy.ndarray of int64
        Boundary points, loop after loop.
    normals : (n_b, 2) numpy.ndarray of float64
        Their ``b_i`` (length ~ boundary length per point).
    """
    pts, vecs = [], []
    for loop in loops:
        loop = np.asarray(loop, dtype=np.int64)
        prv, nxt = np.roll(loop, 1), np.roll(loop, -1)
        members = ball_indices[loop]
        has_n, has_p = members == nxt[:, None], members == prv[:, None]
        t = coords[loop]
        tau = t[np.arange(loop.size), has_n.argmax(axis=1)] - t[np.arange(loop.size), has_p.argmax(axis=1)]
        b = 0.5 * np.column_stack([tau[:, 1], -tau[:, 0]])
        # Fallback (loop neighbour outside the ball): away from the ball's centroid, with
        # the length of the typical chord of this loop.
        ok = has_n.any(axis=1) & has_p.any(axis=1)
        if not ok.all():
            valid = members >= 0
            cen = (t * valid[..., None]).sum(axis=1) / np.maximum(valid.sum(axis=1), 1)[:, None]
            away = -cen / np.maximum(np.linalg.norm(cen, axis=1), np.finfo(float).tiny)[:, None]
            length = np.median(np.linalg.norm(b[ok], axis=1)) if ok.any() else 1.0
            b[~ok] = length * away[~ok]
        pts.append(loop)
        vecs.append(b)
    return np.concatenate(pts), np.concatenate(vecs)


def boundary_cell_areas(ball_indices: np.ndarray, coords: np.ndarray, loops: Sequence[np.ndarray]
                        ) -> tuple[np.ndarray, np.ndarray]:
    """Area of each boundary point's half cell, measured in its tangent plane.

    A third of the area of the point's one-ring in the Delaunay triangulation of its ball
    (DEM coordinates, :func:`parambench.methods.pointset.local_delaunay.tangent_plane_rings`),
    counting only the fan's triangles inside the boundary: those whose middle direction
    lies in the sector counter-clockwise from the next loop point to the previous one
    (the surface lies to the left of a loop walked in its orientation, see
    :func:`boundary_edge_normals`). That is the barycentric cell of a Delaunay mesh of
    the points; on the generated surfaces it matches the true mesh's boundary vertex areas
    to 1 % in the median. Why not ``area_factor * h^2 / 2``: a boundary sampled sparser than
    the inside next to it has larger cells than the interior spacing says (measured: up
    to 4x on graded samplings).

    Parameters
    ----------
    ball_indices : (N, B) numpy.ndarray of int64
        Ball members, -1 padding.
    coords : (N, B, 2) numpy.ndarray of float64
        Their tangent coordinates.
    loops : sequence of (L_i,) numpy.ndarray of int64
        Oriented boundary loops.

    Returns
    -------
    points : (n_b,) numpy.ndarray of int64
        Boundary points, loop after loop (as :func:`boundary_edge_normals`).
    areas : (n_b,) numpy.ndarray of float64
        Their half-cell areas; NaN where a loop neighbour is not in the ball or no fan
        triangle lies inside (the caller falls back to its model there).
    """
    from .local_delaunay import tangent_plane_rings  # local: local_delaunay is numba-heavy

    two_pi = 2.0 * np.pi
    pts, out = [], []
    for loop in loops:
        loop = np.asarray(loop, dtype=np.int64)
        members = ball_indices[loop]
        valid = members >= 0
        t = np.where(valid[..., None], coords[loop], 0.0)
        has_n = members == np.roll(loop, -1)[:, None]
        has_p = members == np.roll(loop, 1)[:, None]
        rows = np.arange(loop.size)
        theta = np.arctan2(t[..., 1], t[..., 0])
        th0 = theta[rows, has_n.argmax(axis=1)][:, None]
        span = np.mod(theta[rows, has_p.argmax(axis=1)][:, None] - th0, two_pi)
        rings = tangent_plane_rings(t, valid)
        a, b = rings[..., 0], rings[..., 1]
        has = a >= 0
        a, b = np.where(has, a, 0), np.where(has, b, 0)
        ta = np.take_along_axis(t, a[..., None], axis=1)
        tb = np.take_along_axis(t, b[..., None], axis=1)
        rel_a = np.mod(np.take_along_axis(theta, a, axis=1) - th0, two_pi)
        rel_b = np.mod(np.take_along_axis(theta, b, axis=1) - th0, two_pi)
        # Fan triangles are counter-clockwise with less than pi between their spokes.
        mid = np.mod(rel_a + 0.5 * np.mod(rel_b - rel_a, two_pi), two_pi)
        tri = 0.5 * (ta[..., 0] * tb[..., 1] - ta[..., 1] * tb[..., 0])
        area = np.where(has & (mid < span), tri, 0.0).sum(axis=1) / 3.0
        ok = has_n.any(axis=1) & has_p.any(axis=1) & (area > 0)
        pts.append(loop)
        out.append(np.where(ok, area, np.nan))
    if not pts:
        return np.zeros(0, dtype=np.int64), np.zeros(0)
    return np.concatenate(pts), np.concatenate(out)


def stencil_matrix(ball_indices: np.ndarray, values: np.ndarray, n: int,
                   rows: np.ndarray | None = None) -> sp.csr_matrix:
    """Sparse ``S`` with ``(S u)_i = sum_j values[i, j] (u[ball[i, j]] - u_i)`` (rows sum to 0).

    Parameters
    ----------
    ball_indices : (R, B) numpy.ndarray of int64
        -1 padding.
    values : (R, B) numpy.ndarray of float64
    n : int
    rows : (R,) numpy.ndarray of int64, optional
        The rows of S that ``ball_indices`` and ``values`` give (the others are zero);
        all n rows in order (R = n) when omitted.

    Returns
    -------
    (n, n) scipy.sparse.csr_matrix of float64
    """
    off = _off_diagonal(ball_indices, values, n, rows)
    return (off - sp.diags(_row_sums(off))).tocsr()


def _off_diagonal(ball_indices: np.ndarray, values: np.ndarray, n: int, rows: np.ndarray | None) -> sp.csr_matrix:
    """The off-diagonal part of :func:`stencil_matrix` (``values`` at the members, zeros kept)."""
    mask = ball_indices >= 0
    counts = np.zeros(n, dtype=np.int64)
    counts[slice(None) if rows is None else rows] = mask.sum(axis=1)
    if rows is not None and np.any(np.diff(rows) <= 0):  # CSR wants its rows in order
        order = np.argsort(rows)
        ball_indices, values, mask = ball_indices[order], values[order], mask[order]
    # Built as CSR directly: each row's members are already grouped (no COO sort; at
    # 300k points this was half the Laplacian's assembly time).
    indptr = np.concatenate([[0], np.cumsum(counts)])
    return sp.csr_matrix((values[mask], ball_indices[mask], indptr), shape=(n, n))


def _row_sums(off: sp.csr_matrix) -> np.ndarray:
    # scipy's own row sums: their rounding is the stencils' (a plain loop differs in the last bit).
    return np.asarray(off.sum(axis=1)).ravel()


@numba.njit(cache=_CACHE, nogil=True, inline="always")
def _row_entries(ball, w, flux, has_flux, lap_sum, flux_sum, i, cols, vals):
    """Row i of ``-S(w) + S(flux)`` (``flux`` only where ``has_flux``) in scipy's storage order.

    ``S(v) = off(v) - diag(rowsum off(v))`` and the sum of two such matrices as scipy's
    general (unsorted-index) binary operations build them: each keeps a row's columns
    in the reverse of their first insertion and drops entries that come out zero;
    ``lap_sum`` and ``flux_sum`` are the row sums of the two off-diagonal parts. Members
    are distinct and exclude i (DEM balls). Writes up to ``2 * B + 2`` entries; returns
    how many.
    """
    b = ball.shape[1]
    if not has_flux:
        cnt = 0
        for c in range(b):
            if ball[i, c] >= 0 and w[i, c] != 0.0:
                cols[cnt] = ball[i, c]
                vals[cnt] = -w[i, c]
                cnt += 1
        if lap_sum != 0.0:
            cols[cnt] = i
            vals[cnt] = lap_sum
            cnt += 1
        return cnt
    # Insertion order of the sum: the first matrix's row as stored ([i, m_k .. m_1]),
    # then the second's ([i, m_k .. m_1]) where new; the row comes out reversed.
    seq = np.empty(2 * b + 2, dtype=np.int64)  # -1: the diagonal, c >= 0: member c
    n_seq = 0
    if lap_sum != 0.0:
        seq[n_seq] = -1
        n_seq += 1
    for c in range(b - 1, -1, -1):
        if ball[i, c] >= 0 and w[i, c] != 0.0:
            seq[n_seq] = c
            n_seq += 1
    if flux_sum != 0.0 and lap_sum == 0.0:
        seq[n_seq] = -1
        n_seq += 1
    for c in range(b - 1, -1, -1):
        if ball[i, c] >= 0 and flux[c] != 0.0 and w[i, c] == 0.0:
            seq[n_seq] = c
            n_seq += 1
    cnt = 0
    for s in range(n_seq - 1, -1, -1):
        c = seq[s]
        if c < 0:
            value = lap_sum - flux_sum  # an entry missing from either part adds an exact zero
            col = i
        else:
            value = flux[c] - w[i, c]
            col = ball[i, c]
        if value != 0.0:
            cols[cnt] = col
            vals[cnt] = value
            cnt += 1
    return cnt


@numba.njit(cache=_CACHE, nogil=True)
def _assemble_kernel(ball, w, flux, flux_row, lap_sums, flux_sums, indptr, indices, data, count_only, lo, hi):
    b = ball.shape[1]
    cols = np.empty(2 * b + 2, dtype=np.int64)
    vals = np.empty(2 * b + 2)
    for i in range(lo, hi):
        r = flux_row[i]
        cnt = _row_entries(ball, w, flux[max(r, 0)], r >= 0, lap_sums[i], flux_sums[max(r, 0)], i, cols, vals)
        if count_only:
            indptr[i + 1] = cnt
        else:
            at = indptr[i]
            for e in range(cnt):
                indices[at + e] = cols[e]
                data[at + e] = vals[e]


def assembled_laplacian(ball_indices: np.ndarray, w: np.ndarray, flux_rows: np.ndarray,
                        flux: np.ndarray) -> sp.csr_matrix:
    """``-stencil_matrix(ball, w) + stencil_matrix(ball[flux_rows], flux, rows=flux_rows)`` in one pass.

    The same matrix, entry for entry and in the same storage order, as those two stencils
    and scipy's sparse negation and sum (:func:`_row_entries`), built by a compiled loop
    over row chunks on both cores: at a million points the sparse subtractions and sum took 4.5 s
    of the Laplacian's 8 s.

    Parameters
    ----------
    ball_indices : (N, B) numpy.ndarray of int64
        -1 padding; a row's members distinct and other than the row's own point.
    w : (N, B) numpy.ndarray of float64
    flux_rows : (R,) numpy.ndarray of int64
        Increasing rows that carry ``flux``.
    flux : (R, B) numpy.ndarray of float64

    Returns
    -------
    (N, N) scipy.sparse.csr_matrix of float64
    """
    n, b = ball_indices.shape
    ball = np.ascontiguousarray(ball_indices, dtype=np.int64)
    w = np.ascontiguousarray(w, dtype=np.float64)
    flux = np.ascontiguousarray(flux, dtype=np.float64).reshape(-1, b)
    flux_rows = np.asarray(flux_rows, dtype=np.int64)
    lap_sums = _row_sums(_off_diagonal(ball, w, n, None))
    flux_sums = _row_sums(_off_diagonal(ball[flux_rows], flux, n, flux_rows))[flux_rows]
    if flux.shape[0] == 0:
        flux, flux_sums = np.zeros((1, b)), np.zeros(1)
    flux_row = np.full(n, -1, dtype=np.int64)
    flux_row[flux_rows] = np.arange(len(flux_rows))
    indptr = np.zeros(n + 1, dtype=np.int64)
    indices, data = np.zeros(0, dtype=np.int64), np.zeros(0)

    def rows_of(rows: slice, count_only: bool) -> None:  # the kernel releases the GIL: chunks run on both cores
        _assemble_kernel(ball, w, flux, flux_row, lap_sums, flux_sums, indptr, indices, data, count_only,
                         rows.start, rows.stop)

    for_each_chunk(lambda rows: rows_of(rows, True), n, _ASSEMBLY_CHUNK)
    np.cumsum(indptr, out=indptr)
    indices, data = np.empty(indptr[-1], dtype=np.int64), np.empty(indptr[-1])
    for_each_chunk(lambda rows: rows_of(rows, False), n, _ASSEMBLY_CHUNK)
    index_type = np.int32 if max(n, indptr[-1]) < np.iinfo(np.int32).max else np.int64
    return sp.csr_matrix((data, indices.astype(index_type), indptr.astype(index_type)), shape=(n, n))


def _row_weights(ball_indices: np.ndarray, t: np.ndarray, mask: np.ndarray, on_boundary: np.ndarray,
                 interior: str, boundary: str, tangent_w: sp.spmatrix | None, width: float,
                 boundary_width: float) -> np.ndarray:
    """(N, B) weights of :func:`neumann_laplacian`: interior rows by ``interior``, boundary rows by ``boundary``."""
    n = ball_indices.shape[0]
    inner = ~on_boundary
    if "tangent" in (interior, boundary):
        rows = np.broadcast_to(np.arange(n)[:, None], ball_indices.shape)
        w_tan = np.zeros(ball_indices.shape)
        w_tan[mask] = np.asarray(sp.csr_matrix(tangent_w)[rows[mask], ball_indices[mask]]).ravel()
    if interior == "tangent":
        w = w_tan.copy()
    else:
        n_con = _MOMENTS["quadratic"]
        if np.any(mask[inner].sum(axis=1) < n_con):
            raise InvalidInputError(f"quadratic moment weights need balls of at least {n_con} members; "
                                    "increase ball_k.")
        if mask.sum(axis=1).min() >= n_con:
            # Every row at once (boundary rows are overwritten below): no gathered copy
            # of the interior rows' coordinates.
            w = _moment_rows(t, mask, n_con, width, 1e-10)
        else:
            w = np.zeros(ball_indices.shape)
            w[inner] = _moment_rows(t[inner], mask[inner], n_con, width, 1e-10)
    if boundary == "tangent":
        w[on_boundary] = w_tan[on_boundary]
    elif on_boundary.any():
        if np.any(mask[on_boundary].sum(axis=1) < _MOMENTS["linear"]):
            raise InvalidInputError("linear moment weights need balls of at least 3 members; increase ball_k.")
        w[on_boundary] = _moment_rows(t[on_boundary], mask[on_boundary], _MOMENTS["linear"], boundary_width, 1e-10)
    return w


def neumann_laplacian(ball_indices: np.ndarray, coords: np.ndarray, loops: Sequence[np.ndarray],
                      mean_spacing: float, *, interior: str = "quadratic", boundary: str = "linear",
                      tangent_w: sp.spmatrix | None = None, area_factor: float = DEFAULT_AREA_FACTOR,
                      width: float = DEFAULT_GAUSS_WIDTH, boundary_width: float = DEFAULT_BOUNDARY_WIDTH,
                      boundary_area: str = "fan") -> sp.csr_matrix:
    """The Laplacian ``s_i (I - W)_i + b_i . G_i`` described in the module docstring.

    Parameters
    ----------
    ball_indices : (N, B) numpy.ndarray of int64
        DEM ball members (-1 padding), e.g. ``FrontEnd.ball_indices``.
    coords : (N, B, 2) numpy.ndarray of float64
        Their tangent coordinates (``FrontEnd.tangent_coords``).
    loops : sequence of (L_i,) numpy.ndarray of int64
        Oriented boundary loops (``FrontEnd.boundary_loops``).
    mean_spacing : float or (N,) numpy.ndarray of float64
        l, or the spacing around each point; the area per point is
        ``area_factor * l^2`` (halved at boundary points, where ``boundary_area="fan"``
        measures it instead).
    interior : {"quadratic", "tangent"}
        Weights of the interior rows: :func:`moment_weights` of order 2, or the given
        ``tangent_w`` (W^tan).
    boundary : {"linear", "tangent"}
        Weights of the boundary rows: :func:`moment_weights` of order 1, or ``tangent_w``.
    tangent_w : (N, N) scipy.sparse matrix, optional
        W^tan, required when either option is "tangent".
    area_factor : float
    width : float
        Gaussian width of the interior rows' moment weights (the gradient uses equal weights).
    boundary_width : float
        Gaussian width of the boundary rows' linear moment weights (see the module docstring).
    boundary_area : {"fan", "spacing"}
        Boundary rows' area: measured (:func:`boundary_cell_areas`; the model where it is
        undefined) or the model ``area_factor * l^2 / 2`` (before this option existed).

    Returns
    -------
    (N, N) scipy.sparse.csr_matrix of float64
        Rows sum to zero; scaled so that ``1/2 u^T L u`` approximates the Dirichlet
        energy (k_opt ~ 1 in :class:`~parambench.methods.spectral.ConformalProblem`).

    Raises
    ------
    InvalidInputError
        Unknown options, missing ``tangent_w``, non-positive spacing or area factor, bad
        shapes.
    """
    if interior not in ("quadratic", "tangent") or boundary not in ("linear", "tangent"):
        raise InvalidInputError(f"interior must be 'quadratic' or 'tangent' and boundary 'linear' or 'tangent'; "
                                f"got {interior!r}, {boundary!r}.")
    if (interior == "tangent" or boundary == "tangent") and tangent_w is None:
        raise InvalidInputError("tangent_w (W^tan) is needed for 'tangent' rows.")
    if not (np.all(np.asarray(mean_spacing) > 0) and area_factor > 0 and width > 0 and boundary_width > 0):
        raise InvalidInputError("mean_spacing, area_factor and the Gaussian widths must be positive.")
    if boundary_area not in BOUNDARY_AREAS:
        raise InvalidInputError(f"boundary_area must be one of {', '.join(BOUNDARY_AREAS)}, got {boundary_area!r}.")
    ball_indices = np.asarray(ball_indices, dtype=np.int64)
    mask = ball_indices >= 0
    t, mask = _check_balls(coords, mask)
    n = ball_indices.shape[0]
    bpts, bvec = boundary_edge_normals(ball_indices, t, loops)
    on_boundary = np.zeros(n, dtype=bool)
    on_boundary[bpts] = True

    w = _row_weights(ball_indices, t, mask, on_boundary, interior, boundary, tangent_w, width, boundary_width)
    inner = ~on_boundary
    boundary_rows = np.flatnonzero(on_boundary)
    grad = _gradient_rows(t[boundary_rows], mask[boundary_rows], None, 1e-10)  # (n_b, 2, B)
    fan = boundary_area == "fan" and bpts.size > 0
    if fan:
        cell_pts, cells = boundary_cell_areas(ball_indices, t, loops)

    # Eq. 14 with a known k_i: [(I - W) f]_i = -(q_i / 4) Lap f for quadratic f.
    q = np.einsum("nbk,nbk,nb->n", t, t, w)
    del t  # the largest array here (N x B x 2): gone before the stencils are assembled
    q_ref = np.median(q[inner]) if inner.any() else np.median(q)
    q = np.maximum(q, 0.25 * q_ref)  # half balls with negative weights: keep the scale sane
    area = area_factor * np.broadcast_to(np.asarray(mean_spacing, dtype=np.float64), (n,))**2
    area[on_boundary] *= 0.5
    if fan:
        measured = np.isfinite(cells)
        area[cell_pts[measured]] = cells[measured]
    w *= (4.0 * area / q)[:, None]
    pos = np.full(n, -1, dtype=np.int64)
    pos[bpts] = np.arange(bpts.size)
    flux = np.einsum("nc,ncb->nb", bvec[pos[boundary_rows]], grad)
    if (ball_indices == np.arange(n)[:, None]).any():  # a point in its own ball: not a DEM ball
        lap = -stencil_matrix(ball_indices, w, n)
        return (lap + stencil_matrix(ball_indices[boundary_rows], flux, n, rows=boundary_rows)).tocsr()
    return assembled_laplacian(ball_indices, w, boundary_rows, flux)
