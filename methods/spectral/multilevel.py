"""Two-level SCP k search: a Poisson-disk subsample chooses the subspace, every point decides.

The conformal problem's area matrix M and B live on the boundary loops only, so a coarse
level that keeps every loop point (:func:`parambench.methods.pointset.subsample.poisson_disk_subsample`)
has the fine problem's loops exactly, and its map gives values on the fine boundary
without interpolation. The coarse Laplacian is the Galerkin product ``L_c = P^T L P``;
P interpolates each fine point from its six nearest coarse points with weights that sum
to one and reproduce linear functions in the point's tangent plane
(:func:`interpolation_matrix`), so ``L_c`` keeps zero row sums and the energy of smooth
maps. On the coarse level (about one point in nine) the subspace k search of
:mod:`.subspace` gives a map; its boundary values, real and imaginary parts, join a
small Fourier basis (8 frequencies instead of 32), and the fine k search runs on that
subspace (about 20 interior solves instead of about 70). The fine Ritz vector at k_opt
is then refined to the fine eigenvector by Davidson steps and extended harmonically,
exactly as on the direct path, so the coarse map chooses the subspace, never the answer.

Measured against the direct path (both with the repeated subspace search of
:mod:`.subspace`): at 20k points on saddle, holes-bumped, protrusions, gnome-strip,
cylinder, slit, plane (jittered), bump (random, grid), cap (graded) and holes
(blue-noise), k_opt equal to 3e-5 or better, QC mean to 2e-5 relative, uv after
similarity alignment to 8.3e-4 of the diameter (random bump; 1e-4 or better elsewhere),
0 foldovers, the same self-check verdict; at 100k (bump, holes, cap, jittered) and 300k
(bump) k_opt to 4e-6 or better, uv to 2e-5 of the diameter. Time (2 shared cores, load
3-4): at 100k the two paths are within noise end to end (bump 8.3 s against 8.5 s,
holes 9.3 against 7.4, cap 14.6 against 13.7) at the same peak memory (1.0 GB); at 300k
(bump) 46.7 s against 55.6 s end to end, the solve side 32.0 s (subsample 1.4, coarse
4.0, fine 26.7) against 34.7 s, peak 1.93 GB against 1.75 GB. The fine interior block
was factorised once (sparse direct, O(n^1.5)) and the front end is unchanged: at
1M points (bump, one run, before the repeated search) ``ocp`` took 167 s (front end
43 s, Laplacian 12 s, subsample 5.5 s, coarse 13.7 s, fine 88.6 s) and 5.4 GB peak.

The fine level now factorises nothing by default (``fine_solver="twogrid"``): its
interior solves are two-grid cycles (:mod:`.twogrid`) whose coarse correction is the
coarse level's own interior factorisation, kept alive for that. The fine subspace keeps
the interior values its Schur products solved for, so the final map's extension costs no
solve, and its Davidson refinement stops at the accuracy the cycles allow
(:attr:`~parambench.methods.spectral.subspace.BoundarySubspace.SOLVE_FLOOR`): at 1M points
the fine level then solves its 21 basis columns and nothing else (27 cycles; before, 7
more sequential 2-column solves that moved k_opt by 4.5e-6). Measured on the final code
(jittered, quiet 2-core machine, one run each, ocp end to end): 300k points bump / holes
/ cap 20.5 / 27.3 / 26.0 s against 39.6 / 35.1 / 43.1 s for ``solver="direct"`` (k_opt
to 6.8e-5, uv to 2.4e-4 of the diameter); 1M bump 110 s and 3.45 GB peak (fine level
38.8 s) against 237 s and 5.86 GB for the direct path. Where the cycles stall (the
slit, whose coarse interpolation bridges the gap; random sampling, with 65 % of the rows
not diagonally dominant) the solver factorises instead.

Both levels work in the points' kd-tree leaf order (:func:`multilevel_scp` reorders the
problem and maps the result back): in a point cloud's own order every sparse product
and sweep misses the cache (the Galerkin product at 1M points 7.7 s, 1.0 s in leaf
order). The caller may hand the Laplacian over in a list, and the input-order copy is
then freed for the rest of the solve. With the two-grid workers of :mod:`.twogrid`
(one block of right-hand sides, 9 cycles instead of 27), compiled prolongation weights
and subsample, the multilevel solve at 1M points (bump, saved inputs, quiet machine)
went from 71.6 s to 31.9 s. ``ocp`` end to end through ``parambench flatten`` at 1M
(quiet 2-core machine, one run each): bump / holes / cap 51.1 / 52.1 / 48.1 s of method
time, peak RSS 2.80 / 2.84 / 2.80 GiB.

The two-level map's accuracy is bounded by the two-grid solves: the refinement stops at
a boundary residual of :attr:`~parambench.methods.spectral.subspace.BoundarySubspace.SOLVE_FLOOR`
times ``fine_rtol``, and the map's error is about that residual over the spectral gap,
which shrinks with the point count (relative gap ~2.5e-6 at a million points on bump
and protrusions, ~6e-5 on a 20k cylinder). The refinement reports the ratio
(``map_error_estimate``; a bound, 60-130x the map's measured distance from the exact
one at 1M). ``MultilevelSettings.map_error`` (ocp's ``map_error``) asks for a smaller
one: the solves are tightened, the subspace's products solved again from their kept
interior values (:meth:`~parambench.methods.spectral.subspace.BoundarySubspace.resolve`)
and the k search settled again. Measured on saved protrusions 1M inputs (raw pose,
quiet 2 cores), against the exact map: 1.37e-3 of the diameter in 153 s without,
2.7e-4 in 335 s with ``map_error=0.02`` (each Davidson step on the fine level is a
block of two-grid cycles, ~20 s at that size), about what a uniform ``fine_rtol`` of
1e-9 gives (2.4e-4, 304 s); so it is not the default. On bump at 1M the default map is
6.3e-4 of the diameter from the direct path's.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from contextlib import AbstractContextManager, nullcontext
from dataclasses import dataclass, replace
from pathlib import Path

import numba
import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from parambench.datasets_gen.errors import ConvergenceError, InvalidInputError, SolverError

from ..hints import error_note
from ..numba_cache import configure_numba_cache
from ..pointset.reorder import spatial_order
from .ordering import submatrix, symmetric_permutation
from .full_space_polish import full_space_polish, map_scale_spread
from .operators import SplitConformalOperator, rayleigh_energy
from .problem import ConformalProblem, ConformalSolution
from .sparse_eigen import SparseFactor
from .threads import single_threaded_blas
from .twogrid import TwoGridSolver

__all__ = ["interpolation_matrix", "MultilevelSettings", "multilevel_scp", "leaf_ordered", "galerkin_operator",
           "two_grid_factory", "coarse_scp_preconditioner", "FINE_SOLVERS", "TWO_LEVEL_REFINE"]

_CACHE, _ = configure_numba_cache(Path(__file__).resolve().parent)

#: ``MultilevelSettings.fine_solver`` values.
FINE_SOLVERS = ("twogrid", "direct")

#: Coarse points each fine point is interpolated from.
_INTERP_K = 6

#: Both levels' Davidson refinements stop at the first step that gains less than 0.8x,
#: not after 4 such steps as on the direct path. The coarse map only gives the fine
#: subspace a direction (with the 4-step rule the coarse level took 2.4-3.3 s more at
#: 300k points, bump and holes, for the same fine map); the fine level's products come
#: from two-grid solves, and steps past the first stall chase their error: on
#: real/meg-helmet (two levels forced) the 4-step rule reached a residual of 7.8e-9 on
#: those products with a map 1.1e-3 of the diameter off the exact one (1.3e-5 with
#: this rule). On a jittered cylinder at 300k it did better (1.06e-3 from the exact map
#: against 1.64e-3, but 255 two-grid cycles instead of 143), within issue 14's 1e-3 neither;
#: the fine level's coarse preconditioner (:func:`coarse_scp_preconditioner`) since gets
#: 9.8e-4 in 74 cycles with this rule.
TWO_LEVEL_REFINE = {"max_steps": 12, "stall": 0.8, "window": 1}


@dataclass(frozen=True)
class MultilevelSettings:
    """Choices of the two-level solve.

    Attributes
    ----------
    radius_factor : float
        Poisson-disk radius of the coarse sample in units of the mean spacing l (2.0
        keeps about one point in nine, boundary loops included, at 20k-100k points; 1.6
        about one in 6.7). With two-grid fine solves a denser coarse level would pay (1.6
        at 300k points, bump: 28 cycles instead of 45, the multilevel solve 13 s instead
        of 19 s), but it moves the fine k search's subspace: on a 20k jittered cylinder
        the map then differs from the direct one by 1.2e-3 of the diameter (k_opt by
        1.8e-5) against 1.6e-6 at 2.0, above the 1e-3 this path promises; 2.0 stays.
    fine_modes : int
        Fourier frequencies of the fine subspace besides the coarse map (each loop gets
        at least 4). Fewer per loop where the coarse map joins was tried and not kept:
        holes at 300k needs 23 columns with at least 1 per loop instead of 41 (one block
        of two-grid cycles at a million points instead of two) with the same map, but
        at 20k points holes graded then took 22-24 cycles instead of 8 and
        holes-bumped needed the enlarged search (74 columns).
    seed : int
        Seed of the subsample's priorities.
    fine_solver : {"twogrid", "direct"}
        How the fine level solves with its interior block: two-grid cycles on the coarse
        level's factorisation (:mod:`.twogrid`, no fine factorisation) or one sparse
        factorisation.
    fine_rtol : float
        Relative residual of the two-grid solves.
    fine_ktol : float
        The fine subspace k search is repeated on the refined subspace until k_opt moves
        by less than this, relative (``ConformalProblem``'s ``subspace_ktol``).
    enlarge_residual : float
        A fine search that did not settle is made again on a larger subspace when its
        map's relative boundary residual is above this (measured: 1.9e-5 on the cylinder
        above; bump at 20k, unsettled by 1.2e-5 in k after 4 rounds with a map 1.8e-7
        from converged, is left alone).
    map_error : float or None
        The fine map's error estimate (boundary residual over the Ritz gap, see
        :class:`~parambench.methods.spectral.problem.ConformalProblem`) below which the
        two-grid solves are not tightened; None: never tightened.
    polish_from : float or None
        Full-space relative residual of the fine map above which it is polished in the
        full space (:mod:`.full_space_polish`); None (default): not by its residual. At
        1M points the residual of protrusions' map (3.8e-8, 2.5e-3 of the diameter off
        the exact one) is not far above cap's (2.3e-8, a map that needs no polish, which
        would take 30 s more).
    polish_spread : float or None
        The fine map is polished whatever its residual when its local scale varies more
        than this many times (:func:`~.full_space_polish.map_scale_spread`, at the coarse
        points against their neighbours in the fine Laplacian); None: never. At 100k
        points protrusions' spread is 329 and every other generated surface's 1.0-1.7.
    unsettled_map_error : float or None
        The same for a fine k search that did not settle although its refinement
        reached the two-grid solves' floor (their error moves k_opt from round to round);
        None: never. Measured on saved cylinder 1M inputs (jittered): 4 unsettled rounds,
        k_opt 1.000158, then tightened to 2.5e-10 and settled at 0.9999519 in 85 s more.
    polish_unsettled : bool
        Polish the fine map in the full space when its k search still did not settle
        (after ``unsettled_map_error``'s tightened solves): the k_opt then moves from round
        to round by more than ``fine_ktol`` and the map with it. Measured at 1M points
        (jittered): holes-bumped, unsettled after 7 rounds with the solves tightened to
        8.4e-10, was 7.0e-4 of its uv extent from the direct path's map (1.01e-3 of the
        diameter, issue #14's tolerance 1e-3), polished 3.2e-4; bump, holes and cap
        settle in 2 rounds and are not polished.
    enlarged_modes : int
        Fourier frequencies of that second fine search (``fine_enlarged`` in the
        diagnostics). Measured at 300k points (bump): 32 frequencies from the start
        would cost 69 instead of 21 interior solves (fine level 32 s instead of 12.5 s),
        so they are used only where the small subspace fails.
    """

    radius_factor: float = 2.0
    fine_modes: int = 8
    seed: int = 0
    fine_solver: str = "twogrid"
    fine_rtol: float = 1e-8
    fine_ktol: float = 1e-6
    enlarge_residual: float = 1e-6
    enlarged_modes: int = 32
    map_error: float | None = None
    unsettled_map_error: float | None = 0.02
    polish_from: float | None = None
    polish_spread: float | None = 20.0
    polish_unsettled: bool = True


def interpolation_matrix(points: np.ndarray, coarse: np.ndarray, normals: np.ndarray | None = None,
                         k: int = _INTERP_K) -> sp.csr_matrix:
    """Prolongation P from coarse to fine values: identity on coarse points, local weights elsewhere.

    With ``normals`` each fine point's weights on its ``k`` nearest coarse points are the
    smallest in the distance-weighted norm ``sum_j w_j^2 d_j^2`` that sum to one and
    reproduce the point's position in its tangent plane (linear functions are
    interpolated exactly, so the Galerkin Laplacian keeps the energy of smooth maps);
    without them, or where that local system is singular, inverse squared distance
    weights.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    coarse : (M,) numpy.ndarray of int64
        Sorted, distinct indices of the coarse points.
    normals : (N, 3) numpy.ndarray of float64, optional
        Unit normals of the fine points.
    k : int
        Coarse points per fine point.

    Returns
    -------
    (N, M) scipy.sparse.csr_matrix of float64
        Rows sum to one.

    Raises
    ------
    InvalidInputError
        Fewer coarse points than ``k``.
    """
    n, m = points.shape[0], coarse.size
    if m < k:
        raise InvalidInputError(f"the coarse level needs at least {k} points, got {m}.")
    tree = cKDTree(points[coarse])
    dist, near = tree.query(points, k=k, workers=-1)
    if normals is not None and m > k:
        _keep_to_own_sheet(tree, points, normals, coarse, dist, near)
    d2 = np.maximum(dist, 1e-12 * max(float(dist.max()), 1e-300)) ** 2
    w = 1.0 / d2
    w /= w.sum(axis=1, keepdims=True)
    if normals is not None:
        w = _linear_exact_weights(points, normals, coarse, near, d2, fallback=w)
    p = sp.csr_matrix((w.ravel(), near.ravel(), np.arange(0, n * k + 1, k)), shape=(n, m))
    # Coarse points are their own values exactly.
    on = sp.csr_matrix((np.ones(m), (coarse, np.arange(m))), shape=(n, m))
    is_coarse = np.zeros(n, dtype=bool)
    is_coarse[coarse] = True
    return (sp.diags((~is_coarse).astype(np.float64)) @ p + on).tocsr()


def _keep_to_own_sheet(tree: cKDTree, points: np.ndarray, normals: np.ndarray, coarse: np.ndarray,
                       dist: np.ndarray, near: np.ndarray) -> None:
    """Replace, in place, coarse neighbours whose normal opposes the fine point's.

    Where two sheets of the surface come within the coarse spacing (a fold), the nearest
    coarse points include the facing sheet's, whose normals point the other way;
    interpolating from them couples the sheets in the Galerkin Laplacian. Rows with such
    a neighbour (none on a surface without close sheets, so the common case costs one
    dot product per neighbour) take the ``k`` nearest of ``2 k`` candidates, agreeing
    ones first (an opposed one is kept only when fewer than ``k`` agree).
    """
    k = near.shape[1]
    agree = np.einsum("nd,nkd->nk", normals, normals[coarse][near]) > 0.0
    rows = np.flatnonzero(~agree.all(axis=1))
    if rows.size == 0:
        return
    d_more, n_more = tree.query(points[rows], k=min(coarse.size, 2 * k), workers=-1)
    agree_more = np.einsum("nd,nkd->nk", normals[rows], normals[coarse][n_more]) > 0.0
    order = np.argsort(~agree_more, axis=1, kind="stable")[:, :k]
    dist[rows] = np.take_along_axis(d_more, order, axis=1)
    near[rows] = np.take_along_axis(n_more, order, axis=1)


def _linear_exact_weights(points: np.ndarray, normals: np.ndarray, coarse: np.ndarray, near: np.ndarray,
                          d2: np.ndarray, fallback: np.ndarray) -> np.ndarray:
    """Weights ``w = D^-1 A^T (A D^-1 A^T)^-1 e_1`` with A = [1; tangent offsets] (see interpolation_matrix).

    Rows whose 3 x 3 system is singular keep ``fallback``'s weights. Compiled, rows on
    all cores: the whole-array form (einsum, batched solves) took 2.6 s at a million points.
    """
    out = np.array(fallback, dtype=np.float64, order="C")
    _linear_exact_rows(np.ascontiguousarray(points, dtype=np.float64), np.ascontiguousarray(normals, dtype=np.float64),
                       np.ascontiguousarray(coarse, dtype=np.int64), np.ascontiguousarray(near, dtype=np.int64),
                       np.ascontiguousarray(d2, dtype=np.float64), out)
    return out


@numba.njit(cache=_CACHE, nogil=True, parallel=True)
def _linear_exact_rows(points, normals, coarse, near, d2, out):  # pragma: no cover - compiled
    """Each row of ``out``: the weights of :func:`_linear_exact_weights`, where its system is regular."""
    n, k = near.shape
    for i in numba.prange(n):
        nx, ny, nz = normals[i, 0], normals[i, 1], normals[i, 2]
        length = np.sqrt(nx * nx + ny * ny + nz * nz)
        nx, ny, nz = nx / length, ny / length, nz / length
        # Any orthonormal frame of the tangent plane will do: the weights do not depend on it.
        hx, hy, hz = (1.0, 0.0, 0.0) if abs(nx) < 0.9 else (0.0, 1.0, 0.0)
        ax, ay, az = ny * hz - nz * hy, nz * hx - nx * hz, nx * hy - ny * hx
        length = np.sqrt(ax * ax + ay * ay + az * az)
        ax, ay, az = ax / length, ay / length, az / length
        bx, by, bz = ny * az - nz * ay, nz * ax - nx * az, nx * ay - ny * ax
        mean_d2 = 0.0
        for j in range(k):
            mean_d2 += d2[i, j]
        scale = np.sqrt(mean_d2 / k)  # unit-free rows: a well-conditioned 3 x 3 system
        u = np.empty(k)
        v = np.empty(k)
        dinv = np.empty(k)
        g00 = g01 = g02 = g11 = g12 = g22 = 0.0
        for j in range(k):
            q = coarse[near[i, j]]
            ox, oy, oz = points[q, 0] - points[i, 0], points[q, 1] - points[i, 1], points[q, 2] - points[i, 2]
            h = ox * nx + oy * ny + oz * nz  # into the tangent plane
            ox, oy, oz = ox - h * nx, oy - h * ny, oz - h * nz
            u[j] = (ox * ax + oy * ay + oz * az) / scale
            v[j] = (ox * bx + oy * by + oz * bz) / scale
            dinv[j] = scale * scale / d2[i, j]
            g00 += dinv[j]
            g01 += dinv[j] * u[j]
            g02 += dinv[j] * v[j]
            g11 += dinv[j] * u[j] * u[j]
            g12 += dinv[j] * u[j] * v[j]
            g22 += dinv[j] * v[j] * v[j]
        # (G^-1 e_1) by cofactors of the symmetric G.
        c00 = g11 * g22 - g12 * g12
        c01 = g02 * g12 - g01 * g22
        c02 = g01 * g12 - g02 * g11
        det = g00 * c00 + g01 * c01 + g02 * c02
        if not abs(det) > 1e-8:
            continue
        l0, l1, l2 = c00 / det, c01 / det, c02 / det
        for j in range(k):
            out[i, j] = dinv[j] * (l0 + l1 * u[j] + l2 * v[j])


def multilevel_scp(laplacian: sp.spmatrix | list, loops: Sequence[np.ndarray], points: np.ndarray, coarse: np.ndarray,
                   *, normals: np.ndarray | None = None, settings: MultilevelSettings = MultilevelSettings(),
                   stage: Callable[[str], AbstractContextManager] | None = None
                   ) -> tuple[ConformalSolution, dict]:
    """SCP with the k line search of Eq. 16 on two levels (see the module docstring).

    Parameters
    ----------
    laplacian : (N, N) scipy.sparse matrix of float64, or a list holding one
        Rows sum to zero. Both levels work on a copy in the points' kd-tree order; a
        one-element list is emptied once that copy is made, so a caller that keeps no
        other reference frees the matrix for the rest of the solve (at a million points
        ~320 MB of the peak). If the solve raises, the matrix is put back in the list.
    loops : sequence of (L_i,) numpy.ndarray of int64
        Oriented boundary loops of the fine problem.
    points : (N, 3) numpy.ndarray of float64
    coarse : (M,) numpy.ndarray of int64
        Coarse point indices; must contain every loop point.
    normals : (N, 3) numpy.ndarray of float64, optional
        Fine normals, for linear-exact prolongation weights (:func:`interpolation_matrix`).
    settings : MultilevelSettings
    stage : callable, optional
        ``stage(name)`` gives a context manager around each level (``"coarse"``: the
        prolongation, the Galerkin product and the coarse search; ``"fine"``: the fine
        search, refinement and extension), e.g. a :class:`parambench.methods.base.StageTimer`.

    Returns
    -------
    solution : ConformalSolution
        The fine map at the fine k_opt (its ``diagnostics`` as from
        :meth:`ConformalProblem.solve`).
    info : dict
        ``coarse_points``, ``coarse_k_opt``, ``coarse_regular`` (whether the coarse map was
        a regular flattening; it need not be), ``coarse_triangular_solves``,
        ``coarse_error`` (None, or why the coarse search failed: ``coarse_k_opt`` is then
        None and the fine search runs on ``enlarged_modes`` frequencies),
        ``fine_enlarged`` and
        ``fine_counts`` (the fine problem's :attr:`ConformalProblem.counts`).

    Raises
    ------
    InvalidInputError
        A loop point is missing from ``coarse``.
    SolverError, ConvergenceError
        As :meth:`ConformalProblem.solve` (the fine level) and
        :meth:`ConformalProblem.scp_subspace_estimate` (the coarse level).
    """
    if settings.fine_solver not in FINE_SOLVERS:
        raise InvalidInputError(f"fine_solver must be one of {', '.join(FINE_SOLVERS)}, got {settings.fine_solver!r}.")
    handed_over = isinstance(laplacian, list)
    matrix = laplacian[0] if handed_over else laplacian
    coarse = np.unique(np.asarray(coarse, dtype=np.int64))
    n = matrix.shape[0]
    pos = np.full(n, -1, dtype=np.int64)
    pos[coarse] = np.arange(coarse.size)
    boundary = np.concatenate([np.asarray(lp, dtype=np.int64) for lp in loops])
    if np.any(pos[boundary] < 0):
        raise InvalidInputError("the coarse level must keep every boundary-loop point.")
    stage = stage or (lambda name: nullcontext())
    with stage("coarse"):
        lap, order, inverse = leaf_ordered(matrix, points, last=boundary)
        del matrix
        if handed_over:
            laplacian.clear()
    try:
        sol, info = _two_levels(lap, [inverse[np.asarray(lp, dtype=np.int64)] for lp in loops], points[order],
                                np.sort(inverse[coarse]), None if normals is None else normals[order], settings, stage)
    except Exception:
        if handed_over:  # the caller may fall back to another solver on the same matrix
            laplacian.append(symmetric_permutation(lap, inverse))
        raise
    z = np.empty_like(sol.z)
    z[order] = sol.z
    return replace(sol, z=z), info


def leaf_ordered(matrix: sp.spmatrix, points: np.ndarray, last: np.ndarray | None = None
                 ) -> tuple[sp.csr_matrix, np.ndarray, np.ndarray]:
    """The matrix in the points' kd-tree leaf order (``last`` rows at the end), that order and its inverse.

    Both levels work in this order: the input order of a point cloud is arbitrary, and
    every sparse product, extraction and sweep then misses the cache (at a million
    points the Galerkin product took 7.7 s in input order, 1.0 s in this one). The
    boundary rows go last, so that the interior block is the matrix's leading block and
    the fine solves read it in place
    (:class:`~parambench.methods.spectral.leading_block.LeadingBlock`).

    Parameters
    ----------
    matrix : (N, N) scipy.sparse matrix
    points : (N, 3) numpy.ndarray of float64
    last : (B,) numpy.ndarray of int, optional
        Rows placed after all others, in leaf order among themselves.

    Returns
    -------
    lap : (N, N) scipy.sparse.csr_matrix of float64
        ``matrix[order][:, order]``.
    order, inverse : (N,) numpy.ndarray of int64
        Leaf position -> input row, and input row -> leaf position.
    """
    order = spatial_order(points)
    if last is not None and len(last):
        at_end = np.zeros(order.size, dtype=bool)
        at_end[np.asarray(last, dtype=np.int64)] = True
        order = np.concatenate([order[~at_end[order]], order[at_end[order]]])
    inverse = np.empty_like(order)
    inverse[order] = np.arange(order.size)
    return symmetric_permutation(sp.csr_matrix(matrix, dtype=np.float64), order), order, inverse


def galerkin_operator(lap: sp.csr_matrix, prolong: sp.csr_matrix) -> sp.csr_matrix:
    """``P^T L P`` with its rows' sums set to zero exactly (the products keep them only to rounding)."""
    lap_c = (prolong.T @ lap @ prolong).tocsr()
    return (lap_c - sp.diags(np.asarray(lap_c.sum(axis=1)).ravel())).tocsr()


def _two_levels(lap: sp.csr_matrix, loops: list[np.ndarray], points: np.ndarray, coarse: np.ndarray,
                normals: np.ndarray | None, settings: MultilevelSettings,
                stage: Callable[[str], AbstractContextManager]) -> tuple[ConformalSolution, dict]:
    """:func:`multilevel_scp` on points in a cache-friendly order (its arguments, checked)."""
    n = lap.shape[0]
    pos = np.full(n, -1, dtype=np.int64)
    pos[coarse] = np.arange(coarse.size)
    with single_threaded_blas(), stage("coarse"):
        prolong = interpolation_matrix(points, coarse, normals)
        lap_c = galerkin_operator(lap, prolong)
        coarse_problem = ConformalProblem(lap_c, [pos[lp] for lp in loops], b_matrix="boundary",
                                          points=points[coarse], refine_rule=TWO_LEVEL_REFINE)
        # Held here, the coarse interior factorisation outlives the coarse search: the
        # fine level's two-grid cycles correct on it.
        coarse_reduction = coarse_problem.reduction() if settings.fine_solver == "twogrid" else None
        # The coarse map only gives the fine subspace a direction: it need not be regular
        # (at 100k points the exact coarse map near the coarse k_opt still spun).
        try:
            point, coarse_info = coarse_problem.scp_subspace_estimate()
            z_b, coarse_k, coarse_error = point.state[0], point.k, None
        except (ConvergenceError, SolverError) as exc:
            # A coarse level too sparse for the geometry (the fold's bend, radius about one
            # fine spacing, under a coarse spacing of two) finds no regular map at any k:
            # the fine search then runs on the larger Fourier subspace alone.
            z_b, coarse_k, coarse_info, coarse_error = None, None, {"regular": False}, exc
        precondition = coarse_scp_preconditioner(lap_c, [pos[lp] for lp in loops], points[coarse])
        del lap_c
    solvers: list = []
    interior_solver = None
    if coarse_reduction is not None:
        interior_solver = two_grid_factory(prolong, coarse_reduction, settings, solvers)
    extra = None if z_b is None else np.column_stack([z_b.real, z_b.imag])
    with single_threaded_blas(), stage("fine"):
        fine = ConformalProblem(lap, loops, b_matrix="boundary", points=points,
                                subspace_modes=settings.fine_modes if z_b is not None else settings.enlarged_modes,
                                subspace_extra=extra, interior_solver=interior_solver, subspace_ktol=settings.fine_ktol,
                                refine_rule=dict(TWO_LEVEL_REFINE, precondition=precondition),
                                map_error=settings.map_error,
                                unsettled_map_error=settings.unsettled_map_error)
        sol = fine.solve("scp", "line")
        counts = dict(fine.counts)
        enlarged = (not sol.diagnostics.get("subspace_settled", True)
                    and sol.diagnostics.get("boundary_residual", 0.0) > settings.enlarge_residual
                    and z_b is not None and settings.enlarged_modes > settings.fine_modes)
        if enlarged:
            # The fine k search neither settled nor refined its map (a jittered cylinder
            # at 100k points: residual 1.9e-5, k_opt 5e-4 and the map 6e-3 of the
            # diameter off the direct solve): search again on the direct path's Fourier
            # basis, the coarse and the first fine map.
            z_f = sol.z[np.concatenate([np.asarray(lp, dtype=np.int64) for lp in loops])]
            fine = ConformalProblem(lap, loops, b_matrix="boundary", points=points,
                                    subspace_modes=settings.enlarged_modes,
                                    subspace_extra=np.column_stack([extra, z_f.real, z_f.imag]),
                                    interior_solver=interior_solver, subspace_ktol=settings.fine_ktol,
                                    refine_rule=dict(TWO_LEVEL_REFINE, precondition=precondition),
                                    map_error=settings.map_error,
                                    unsettled_map_error=settings.unsettled_map_error)
            sol = fine.solve("scp", "line")
            counts = {key: counts.get(key, 0) + value for key, value in fine.counts.items()}
        polish = {}
        above = settings.polish_from
        if settings.polish_spread is not None:
            spread = map_scale_spread(points, sol.z, lap, at=coarse)
            polish["map_scale_spread"] = spread if np.isfinite(spread) else None  # None: part of the map collapsed
            if spread > settings.polish_spread:
                above = 0.0
        if settings.polish_unsettled and not sol.diagnostics.get("subspace_settled", True):
            polish["polish_unsettled"] = True
            above = 0.0
        if above is not None:
            precondition.release()  # the polish factorises its own coarse operator: one alive at a time
            sol, found = _polished(fine, sol, prolong, coarse_problem, above)
            polish.update(found)
    info = {**polish, "coarse_points": int(coarse.size), "coarse_k_opt": None if coarse_k is None else float(coarse_k),
            "coarse_regular": bool(coarse_info["regular"]),
            "coarse_triangular_solves": int(coarse_problem.counts["triangular_solves"]),
            "fine_solver": settings.fine_solver, "fine_enlarged": bool(enlarged),
            "coarse_error": None if coarse_error is None else error_note(coarse_error),
            "fine_counts": counts}
    if solvers:
        info.update(twogrid_cycles=int(sum(s.n_cycles for s in solvers)),
                    twogrid_fell_back=bool(any(s.fell_back for s in solvers)))
    return sol, info


#: Shift of the coarse preconditioner, relative to ``k/2 max|diag L_c|``: it keeps
#: ``k/2 L_c - M_c`` regular at the coarse k_opt (where its smallest eigenvalue is ~0).
COARSE_SHIFT = 1e-4


def _polished(fine: ConformalProblem, sol: ConformalSolution, prolong: sp.csr_matrix, coarse: ConformalProblem,
              above: float) -> tuple[ConformalSolution, dict]:
    """``sol`` polished in the full space where its residual is above ``above`` (:mod:`.full_space_polish`)."""
    operator = SplitConformalOperator(fine.laplacian, fine.area, sol.k)
    boundary = np.asarray(fine.b.diagonal()) > 0
    z, info = full_space_polish(operator, boundary, prolong, sol.z, fine.loops, coarse.points, above=above,
                                coarse_operator=coarse.operator(sol.k))
    if z is sol.z:
        return sol, info
    # The polish keeps only steps whose loops turn as the map's did: sol.turning stands.
    return replace(sol, z=z, energy=rayleigh_energy(z, operator, boundary.astype(np.float64)),
                   diagnostics={**sol.diagnostics, **info}), info


def coarse_scp_preconditioner(lap_c: sp.csr_matrix, coarse_loops: Sequence[np.ndarray],
                              points: np.ndarray | None = None):
    """``precondition(k, lam, r, z)`` of the fine Davidson refinement: the coarse boundary operator's inverse.

    The fine boundary points are the coarse ones, so a fine boundary residual r is one of
    the coarse problem: solving ``(k/2 L_c - M_c + s B_c) y = [r; 0]`` gives on the
    boundary ``(k/2 S_c - M_KK + s I)^{-1} r``, the inverse of the coarse Schur
    complement, which carries the smooth part of the fine one that the refinement's
    own preconditioner (the boundary block alone) misses. An inverse this close to the
    fine operator maps r mostly back onto z, so Olsen's correction removes the part
    along ``C^{-1} z``. One complex factorisation per k.

    Measured on saved 300k-point inputs (jittered, two-grid fine solves), against the
    exact map (sparse eigen-solves at the root of q(k)): cylinder 1.64e-3 -> 9.8e-4 of
    the diameter (143 -> 74 cycles, 46 -> 39 s), protrusions 4.8e-4 -> 1.9e-4 (45 -> 16
    cycles, 16.3 -> 13.0 s); fold at 100k (its two-grid solves fall back to a
    factorisation) 6.7e-4 -> 3.3e-7, k_opt to 9e-7 of the direct path's; bump and holes
    unchanged (no refinement step).

    With the coarse ``points`` (M, 3) the factorisations follow their nested dissection,
    computed once: at 1M points (bump, coarse level 100k) a factorisation took 39 s in
    that order against 74 s in SuperLU's minimum degree (both with another job on the
    cores; 27 s for the latter alone), the solves 0.57 s against 0.75 s.
    """
    return CoarseBoundaryPreconditioner(lap_c, coarse_loops, points)


class CoarseBoundaryPreconditioner:
    """The callable :func:`coarse_scp_preconditioner` returns; :meth:`release` frees its factorisation."""

    def __init__(self, lap_c: sp.csr_matrix, coarse_loops: Sequence[np.ndarray], points: np.ndarray | None = None):
        from .operators import area_matrix

        self._lap_c = lap_c
        self._points = points
        n_c = lap_c.shape[0]
        self._rows = np.concatenate([np.asarray(lp, dtype=np.int64) for lp in coarse_loops])
        self._indicator = np.zeros(n_c)
        self._indicator[self._rows] = 1.0
        self._area_c = area_matrix(coarse_loops, n_c)
        self._diag_max = float(np.abs(lap_c.diagonal()).max())
        self._perm = None
        self._cache: dict = {}

    def __call__(self, k: float, lam: complex, r: np.ndarray, z: np.ndarray) -> np.ndarray:
        from .ordering import nested_dissection

        if self._cache.get("k") != k:
            shift = COARSE_SHIFT * 0.5 * abs(k) * self._diag_max
            op = ((0.5 * k) * self._lap_c - self._area_c + shift * sp.diags(self._indicator)).tocsc().astype(np.complex128)
            if self._perm is None and self._points is not None:
                self._perm = nested_dissection(self._points, self._lap_c)
            self._cache.clear()  # one factorisation alive at a time
            self._cache.update(k=k, factor=SparseFactor(op, perm=self._perm))
        rhs = np.zeros((self._lap_c.shape[0], 2), dtype=np.complex128)
        rhs[self._rows, 0] = r
        rhs[self._rows, 1] = z
        with single_threaded_blas():
            sol = self._cache["factor"].solve(rhs)[self._rows]
        t_r, t_z = sol[:, 0], sol[:, 1]
        return t_r - t_z * (np.vdot(z, t_r) / np.vdot(z, t_z))

    def release(self) -> None:
        """Drop the factorisation (at 1M points about 1 GB; the next call factorises again)."""
        self._cache.clear()


def two_grid_factory(prolong: sp.csr_matrix, coarse_reduction, settings: MultilevelSettings, made: list):
    """``interior_solver`` for the fine problem: two-grid cycles on the coarse interior factorisation.

    The fine interior rows of P restricted to the coarse interior columns interpolate
    interior values (coarse boundary columns only feed boundary rows' Dirichlet values,
    zero in a correction); ``P_II^T L_II P_II`` is then the coarse problem's interior
    block up to the rounding residue removed from its row sums. Each solver made is
    appended to ``made`` (its cycle counts go to the diagnostics). The sweeps keep the
    rows' order (the points are in kd-tree leaf order already, see :func:`multilevel_scp`).
    """
    coarse_factor = coarse_reduction.interior_factor
    coarse_interior = coarse_reduction.interior

    def factory(l_ii: sp.csr_matrix, interior: np.ndarray):
        if coarse_factor is None:  # no coarse interior: nothing to correct on
            solver = SparseFactor(l_ii)
        else:
            p_ii = submatrix(prolong, interior, coarse_interior)
            solver = TwoGridSolver(l_ii, p_ii, coarse_factor.solve, rtol=settings.fine_rtol,
                                   order=np.arange(interior.size))
            made.append(solver)
        return solver

    return factory
