"""SDP on two levels: the boundary eigenproblem of ``L f = lambda B f`` in a subspace (``sdp``'s ``solver="multilevel"``).

With B the indicator of the boundary points, the interior rows of ``L f = lambda B f``
say that f is the harmonic extension of its boundary values, so the problem is the
eigenproblem of the Schur complement ``S = L_BB - L_BI L_II^{-1} L_IB`` on the
boundary, exactly. Its two smallest non-trivial eigenvectors are smooth along the
loops, so they are sought in a subspace of the boundary: Fourier modes of each loop,
the boundary points' coordinates and, on the fine level, the coarse level's pair; a
block Davidson refinement adds the Ritz pair's residuals until they stop falling. Every
product with S costs one interior solve per column, and the harmonic extension reuses
those solutions (no further solve).

The levels are those of :mod:`.multilevel`: a Poisson-disk subsample keeping every
boundary point, the linear-exact prolongation P, the Galerkin operator ``P^T L P``. The
coarse pair comes from the direct path's shift-invert on ``P^T L P``; the fine level
solves its interior block by two-grid cycles on the coarse interior factorisation
(:mod:`.twogrid`), so no fine matrix is ever factorised, and the coarse Schur
complement (one more coarse factorisation) preconditions its refinement.

Constants are an eigenvector of S with eigenvalue 0 (rows of L sum to zero). The
subspace is kept orthogonal to them and S's products are projected likewise: for an
eigenvector f of S, its mean-free part is an eigenvector of the projected operator with
the same eigenvalue, which is what the direct path's mean-deflated shift-invert
(:func:`~parambench.methods.spectral.dirichlet.smallest_nontrivial_pair`) returns too.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from contextlib import AbstractContextManager, nullcontext

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp
import scipy.sparse.linalg as sla

from parambench.datasets_gen.errors import ConvergenceError, InvalidInputError

from .dirichlet import real_pair, smallest_nontrivial_pair
from .multilevel import (FINE_SOLVERS, MultilevelSettings, galerkin_operator, interpolation_matrix,
                         leaf_ordered, two_grid_factory)
from .problem import ConformalProblem
from .ordering import nested_dissection
from .reduction import BoundaryReduction
from .sparse_eigen import SparseFactor
from .subspace import BoundarySubspace, _stalled, boundary_basis
from .threads import single_threaded_blas

__all__ = ["multilevel_sdp", "boundary_dirichlet_pair", "SDP_RTOL"]

#: Relative residual ``||P S X - X H|| / (max |diag L_KK| ||X||)`` of the boundary pair at which the
#: refinement stops (it stops earlier when the residual stalls, as on the SCP path).
SDP_RTOL = 1e-9

#: A pair whose residual stays above this is not returned.
TRUSTED_RESIDUAL = 1e-4

#: Stop rule of the refinement on both levels (see :func:`~parambench.methods.spectral.subspace._stalled`).
SDP_REFINE = {"max_steps": 30, "stall": 0.7, "window": 4}


def _mean_free(x: np.ndarray) -> np.ndarray:
    return x - x.mean(axis=0)


def boundary_dirichlet_pair(reduction: BoundaryReduction, loops: Sequence[np.ndarray], points: np.ndarray | None,
                            *, n_modes: int = 8, extra: np.ndarray | None = None, rtol: float = SDP_RTOL,
                            refine_rule: dict | None = None,
                            preconditioner: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None
                            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict]:
    """The two smallest non-trivial eigenpairs of the boundary Schur complement, and their extension.

    Parameters
    ----------
    reduction : BoundaryReduction
        Onto the concatenated loops (in that order).
    loops : sequence of (L_i,) numpy.ndarray of int64
        Boundary loops, indices into the full point set.
    points : (N, 3) numpy.ndarray of float64, optional
        Positions (arc length and coordinate functions of the subspace).
    n_modes : int
        Fourier frequencies of the starting subspace (:func:`boundary_basis`).
    extra : (K, e) numpy.ndarray of float64, optional
        Further starting directions on the boundary (a coarse level's pair).
    rtol : float
        Residual at which the refinement stops.
    refine_rule : dict, optional
        ``max_steps``, ``stall``, ``window`` of the stop rule (default
        :data:`SDP_REFINE`).
    preconditioner : callable, optional
        ``preconditioner(residual, x)`` maps the (K, 2) residual of the plane x (K, 2) to
        further directions, added at each step to Davidson's (the residual solved with
        the boundary block shifted by the mean Ritz value). Measured on a 20k bump with
        the coarse Schur complement (:func:`multilevel_sdp`): Davidson's alone took 11
        steps to 2.6e-7, the coarse one alone stalled at 1.2e-5 (its inverse is close to
        that of S - theta I, so it mostly returns the plane itself), both 5 steps to 1.5e-7.

    Returns
    -------
    values : (2,) numpy.ndarray of float64
        The eigenvalues (equal for a complex-conjugate pair, whose real and imaginary
        parts are returned as the two vectors).
    pair : (N, 2) numpy.ndarray of float64
        The eigenvectors extended harmonically to every point.
    boundary_pair : (K, 2) numpy.ndarray of float64
        Their boundary values, mean-free.
    info : dict
        ``boundary_residual``, ``subspace_size``, ``refine_steps``.

    Raises
    ------
    ConvergenceError
        The residual stayed above :data:`TRUSTED_RESIDUAL`.
    """
    rule = dict(SDP_REFINE if refine_rule is None else refine_rule)
    rtol = max(float(rtol), BoundarySubspace.SOLVE_FLOOR * reduction.solve_rtol)
    with single_threaded_blas():
        basis = boundary_basis(loops, points, n_modes, extra)
    sv, interior = reduction.apply_schur_extended(basis)
    # Interior values grow by blocks, combined once at the end: concatenating them at each
    # step would copy the whole (V, m) array (hundreds of MB at a million points).
    interior = [interior]
    l_kk = sp.csc_matrix(reduction.boundary_block)
    # Residuals are measured against L_KK's scale, not the (small) eigenvalues'.
    scale = float(np.abs(l_kk.diagonal()).max())
    rels: list[float] = []
    bests: list[float] = []
    best = None
    for step in range(int(rule["max_steps"]) + 1):
        coef, block = _ritz_plane(basis, sv)
        x, sx = basis @ coef, _mean_free(sv @ coef)
        residual = sx - x @ block  # the plane's residual: zero exactly when it is invariant
        rel = float(np.linalg.norm(residual) / (scale * np.linalg.norm(x)))
        rels.append(rel)
        if best is None or rel < best[0]:
            best = (rel, np.sort(np.linalg.eigvals(block).real), coef, basis.shape[1])
        bests.append(best[0])
        if rel <= rtol or step == int(rule["max_steps"]) or _stalled(rels, bests, rule["stall"], rule["window"]):
            break
        # Davidson's preconditioner: the boundary block shifted by the plane's mean Ritz value.
        shift = float(np.trace(block)) / 2.0
        try:
            directions = sla.splu(l_kk - shift * sp.identity(l_kk.shape[0], format="csc")).solve(residual)
        except RuntimeError:
            directions = residual  # a singular shift: the plain residual still enlarges the basis
        if preconditioner is not None:
            directions = np.hstack([directions, preconditioner(residual, x)])
        new = _orthogonal_complement(basis, directions)
        if new.shape[1] == 0:
            break
        s_new, i_new = reduction.apply_schur_extended(new)
        basis, sv = np.hstack([basis, new]), np.hstack([sv, s_new])
        interior.append(i_new)
    rel, values, coef, used = best
    if rel > TRUSTED_RESIDUAL:
        raise ConvergenceError(f"the boundary eigenproblem's refinement did not converge (relative residual "
                               f"{rel:.2g} after {len(rels) - 1} steps)")
    b_pair = basis[:, :used] @ coef
    inner = np.zeros((reduction.interior.size, 2))
    start = 0
    for block in interior:
        stop = min(start + block.shape[1], used)
        if stop > start:
            inner += block[:, :stop - start] @ coef[start:stop]
        start += block.shape[1]
    n = reduction.keep.size + reduction.interior.size
    pair = np.empty((n, 2))
    pair[reduction.keep] = b_pair
    pair[reduction.interior] = inner
    return values, pair, b_pair, {"boundary_residual": rel, "subspace_size": int(used), "refine_steps": len(rels) - 1,
                                  "residuals": [float(f"{r:.3g}") for r in rels]}


def _ritz_plane(basis: np.ndarray, sv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The plane of the two smallest Ritz values of the mean-free S on ``basis`` (orthonormal, mean-free).

    Returns its orthonormal coefficients C (m, 2) and the 2 x 2 block ``C^T H C`` of the
    projected operator H on it (a complex-conjugate pair of Ritz values gives the plane of
    its real and imaginary parts).
    """
    h = basis.T @ _mean_free(sv)
    vals, vecs = la.eig(h)
    _, coef = real_pair(vals, vecs)
    coef, _ = np.linalg.qr(coef)
    return coef, coef.T @ h @ coef


def _orthogonal_complement(basis: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """``directions`` made mean-free and orthonormal to ``basis`` (two Gram-Schmidt passes), dependent ones dropped."""
    d = _mean_free(directions)
    scale = np.linalg.norm(d, axis=0)
    for _ in range(2):
        d = d - basis @ (basis.T @ d)
    q, r = np.linalg.qr(d)
    keep = np.abs(np.diag(r)) > 1e-8 * max(float(scale.max()), 1e-300)
    return q[:, keep]


def multilevel_sdp(laplacian: sp.spmatrix, loops: Sequence[np.ndarray], points: np.ndarray, coarse: np.ndarray, *,
                   normals: np.ndarray | None = None, settings: MultilevelSettings = MultilevelSettings(),
                   stage: Callable[[str], AbstractContextManager] | None = None) -> tuple[np.ndarray, dict]:
    """The SDP pair (``L f = lambda B f``, B the boundary indicator) on two levels.

    Parameters
    ----------
    laplacian : (N, N) scipy.sparse matrix of float64
        Rows sum to zero; may be non-symmetric (W^tan).
    loops : sequence of (L_i,) numpy.ndarray of int64
        Boundary loops; B is the indicator of their points.
    points : (N, 3) numpy.ndarray of float64
    coarse : (M,) numpy.ndarray of int64
        Coarse point indices; must contain every loop point.
    normals : (N, 3) numpy.ndarray of float64, optional
        For linear-exact prolongation weights.
    settings : MultilevelSettings
        ``fine_modes``, ``fine_solver``, ``fine_rtol`` are used.
    stage : callable, optional
        ``stage("coarse")`` and ``stage("fine")`` context managers (timings).

    Returns
    -------
    pair : (N, 2) numpy.ndarray of float64
        The two eigenvectors, in the input order.
    info : dict
        ``eigenvalues``, ``coarse_points``, ``coarse_eigenvalues``, the fine level's
        ``boundary_residual``, ``residuals`` (per step), ``subspace_size`` and
        ``refine_steps``, ``fine_solver`` and, with two-grid solves, ``twogrid_cycles``.

    Raises
    ------
    InvalidInputError
        A loop point is missing from ``coarse``, or ``fine_solver`` is unknown.
    ConvergenceError
        A level's refinement did not converge.
    """
    if settings.fine_solver not in FINE_SOLVERS:
        raise InvalidInputError(f"fine_solver must be one of {', '.join(FINE_SOLVERS)}, got {settings.fine_solver!r}.")
    stage = stage or (lambda name: nullcontext())
    coarse = np.unique(np.asarray(coarse, dtype=np.int64))
    boundary = np.concatenate([np.asarray(lp, dtype=np.int64) for lp in loops])
    if not np.isin(boundary, coarse).all():
        raise InvalidInputError("the coarse level must keep every boundary-loop point.")
    with stage("coarse"):
        lap, order, inverse = leaf_ordered(laplacian, points, last=boundary)
        loops = [inverse[np.asarray(lp, dtype=np.int64)] for lp in loops]
        points, coarse = points[order], np.sort(inverse[coarse])
        normals = None if normals is None else normals[order]
        with single_threaded_blas():
            prolong = interpolation_matrix(points, coarse, normals)
        pos = np.full(lap.shape[0], -1, dtype=np.int64)
        pos[coarse] = np.arange(coarse.size)
        coarse_loops = [pos[lp] for lp in loops]
        lap_c = galerkin_operator(lap, prolong)
        # The coarse pair by the direct path's shift-invert (the subspace refinement with
        # Davidson's preconditioner alone stalled at 1.2e-4 on the coarse level of a 300k bump).
        coarse_rows = boundary_order(coarse_loops)
        indicator = np.zeros(coarse.size)
        indicator[coarse_rows] = 1.0
        coarse_values, coarse_pair = smallest_nontrivial_pair(
            lap_c.tocsc(), sp.diags(indicator).tocsc(), perm=nested_dissection(points[coarse], lap_c))
        coarse_b = coarse_pair[coarse_rows] - coarse_pair[coarse_rows].mean(axis=0)
        precondition = _coarse_schur_inverse(lap_c, coarse_loops, points[coarse], coarse_values)
        # The coarse interior factorisation (nested dissection) is the two-grid cycles' coarse solve.
        coarse_red = (ConformalProblem(lap_c, coarse_loops, points=points[coarse]).reduction()
                      if settings.fine_solver == "twogrid" else None)
        del lap_c
    solvers: list = []
    with stage("fine"):
        if settings.fine_solver == "twogrid":
            red = BoundaryReduction(lap, boundary_order(loops),
                                    interior_solver=two_grid_factory(prolong, coarse_red, settings, solvers))
        else:
            red = ConformalProblem(lap, loops, points=points).reduction()
        values, pair, _, info = boundary_dirichlet_pair(red, loops, points, n_modes=settings.fine_modes,
                                                        extra=coarse_b, preconditioner=precondition)
    out = np.empty_like(pair)
    out[order] = pair
    info = dict(info, eigenvalues=values.tolist(), coarse_points=int(coarse.size), fine_solver=settings.fine_solver,
                coarse_eigenvalues=np.asarray(coarse_values).tolist())
    if solvers:
        info.update(twogrid_cycles=int(sum(s.n_cycles for s in solvers)),
                    twogrid_fell_back=bool(any(s.fell_back for s in solvers)))
    return out, info


def _coarse_schur_inverse(lap_c: sp.csr_matrix, coarse_loops: Sequence[np.ndarray], points: np.ndarray,
                          values: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
    """``r -> (S_c - sigma I)^{-1} r``: the coarse Schur complement, the fine one's smooth part, as the fine preconditioner.

    The fine boundary points are the coarse ones (in the same loop order), so a residual
    on the fine boundary is one on the coarse boundary. ``sigma = -lambda_1`` of the
    coarse pair keeps the shifted operator regular (S_c has the constants as its null
    space) while it still inverts S_c's smooth part, which the boundary block alone
    misses. Its own factorisation: reusing the coarse shift-invert's (sigma = -1e-6 of
    the scale) took the 20k bump's refinement 8 steps and 64 two-grid cycles instead of 5 and 43. One factorisation of the coarse ``L_c - sigma B_c``: the residual's rows on the
    boundary, zero interior rows, and the solution's boundary rows are ``(S_c - sigma I)^{-1} r``.
    """
    n_c = lap_c.shape[0]
    rows = boundary_order(coarse_loops)
    indicator = np.zeros(n_c)
    indicator[rows] = 1.0
    shifted = (lap_c + abs(float(values[0])) * sp.diags(indicator)).tocsc()
    factor = SparseFactor(shifted, nested_dissection(points, shifted))

    def apply(residual: np.ndarray, x: np.ndarray) -> np.ndarray:
        rhs = np.zeros((n_c, 4))
        rhs[rows, :2] = residual
        rhs[rows, 2:] = x
        with single_threaded_blas():
            sol = factor.solve(rhs)[rows]
        t_r, t_x = sol[:, :2], sol[:, 2:]
        # Olsen's correction: an inverse this close to S - theta I maps the residual back
        # onto x itself; subtracting the part along M^{-1} x keeps the directions X-orthogonal.
        return t_r - t_x @ np.linalg.solve(x.T @ t_x, x.T @ t_r)

    return apply


def boundary_order(loops: Sequence[np.ndarray]) -> np.ndarray:
    """The loops' points concatenated (the row order of the boundary subspace)."""
    return np.concatenate([np.asarray(lp, dtype=np.int64) for lp in loops])
