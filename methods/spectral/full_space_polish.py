"""Polish a two-level SCP map in the full space, where its residual costs a product and no solve.

The fine level of :mod:`.multilevel` refines its map on the boundary Schur complement,
whose products come from two-grid interior solves; the map's accuracy floors at theirs,
and at a million points the smallest eigenvalue is so close to the next (relative gap
~2.5e-6) that this floor leaves the map 2.5e-3 of the diameter off the exact eigenvector
on ``protrusions`` (the direct path: 5.5e-4). In the full space the residual
``r = (k L / 2 - M) z - lambda B z`` is one sparse product, exact to rounding. Each step
here adds a two-grid correction of r to a small basis (weighted Jacobi sweeps on the fine
operator, a solve on the two-level path's coarse points through its interpolation P, more
sweeps) and takes the Ritz pair of the pencil (k L / 2 - M, B) on it again, the constant
vector included so translations cost nothing (Davidson's method with a two-grid
preconditioner).

Measured at 1M points, ``protrusions`` jittered, against the exact eigenvector of the same
problem (one complex sparse factorisation of ``k L / 2 - M``): 2.5e-3 of the diameter ->
2.4e-5 in 20 steps (the direct path's map: 5.5e-4); at 100k 4.7e-4 -> 4.4e-6 in 14
steps. It costs one complex factorisation on the coarse points (~1 GB at 1M; the fine
refinement's coarse preconditioner releases its own first) and about a second a step at
1M, so ``ocp`` runs it only where it is needed. The full-space residuals of the default
maps at 1M (bump 1.0e-8, holes 1.3e-9, cap 2.3e-8, protrusions 3.8e-8) do not single
that map out; the spread of its local scale does (:func:`map_scale_spread`: 361
against 1.33-1.71). The operator is applied as real Laplacian products and a boundary
part (:class:`~.operators.SplitConformalOperator`), with no shifted or transposed copy:
the polish's peak went from 3 GB to 0.3 GB above the solve's. ``ocp`` on protrusions at
1M: 108-110 s and 3.8-3.9 GiB peak polished, 72 s and 3.4 GiB without (2 cores).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp
from scipy.spatial import cKDTree

from parambench.datasets_gen.errors import SolverError

from .operators import SplitConformalOperator
from .ordering import nested_dissection
from .sparse_eigen import SparseFactor
from .turning import loop_turning_numbers

__all__ = ["full_space_residual", "full_space_polish", "PolishRule", "map_scale_spread"]


@dataclass(frozen=True)
class PolishRule:
    """When the polish stops.

    Attributes
    ----------
    rtol : float
        Relative full-space residual to reach (protrusions at 1M: 2.3e-10 went with a map
        4.1e-4 of the diameter from the exact one).
    max_steps : int
    window : int
        Also stop when this many steps did not lower the best residual.
    sweeps : int
        Weighted Jacobi sweeps before and after the coarse correction.
    omega : float
        Their damping.
    """

    rtol: float = 2e-10
    max_steps: int = 30
    window: int = 6
    sweeps: int = 2
    omega: float = 0.6


def _scale(operator: sp.csr_matrix) -> float:
    return max(float(np.abs(operator.diagonal()).max()), np.finfo(float).tiny)


def _residual(operator: sp.csr_matrix, boundary: np.ndarray, lam: complex, y: np.ndarray) -> tuple[np.ndarray, float]:
    """``r = A y - lambda B y`` and ``|r|`` over ``max|diag A|`` and y's norm without its mean (a translation is not the map)."""
    r = operator @ y - lam * np.where(boundary, y, 0.0)
    return r, float(np.linalg.norm(r) / (_scale(operator) * np.linalg.norm(y - y.mean())))


def _ritz(basis: np.ndarray, a_small: np.ndarray, b_small: np.ndarray, previous: np.ndarray):
    """The Ritz pair of the small pencil whose vector overlaps ``previous`` most (translations aside)."""
    values, vectors = la.eig(a_small, b_small)
    best, best_overlap = None, -1.0
    ref = previous - previous.mean()
    if not np.linalg.norm(ref) > 0:  # a constant map follows no eigenvector
        return None
    ref /= np.linalg.norm(ref)
    for i in np.flatnonzero(np.isfinite(values)):
        y = basis @ vectors[:, i]
        yc = y - y.mean()
        norm = np.linalg.norm(yc)
        if norm <= 1e-8 * np.linalg.norm(y):  # the translation itself
            continue
        overlap = abs(np.vdot(ref, yc)) / norm
        if overlap > best_overlap:
            best, best_overlap = (values[i], y), overlap
    return best


def map_scale_spread(points: np.ndarray, uv: np.ndarray, graph: sp.spmatrix | None = None,
                     at: np.ndarray | None = None, neighbours: int = 8, tail: float = 0.01) -> float:
    """How many times the map's local scale varies over the points, tails cut: q(1 - tail) / q(tail).

    A point's scale is its mean uv distance to its neighbours over their mean 3D
    distance. A conformal map shrinks a protrusion exponentially along it, and the
    eigenvector is then ill-conditioned (the fine level's accuracy floor leaves it far
    from the exact one: ``protrusions`` at 1M points, 2.5e-3 of the diameter). Measured
    at 100k points (jittered, two levels, the Laplacian's neighbours): protrusions 329, every
    other generated surface 1.0-1.7. Euclidean neighbours of a sparse subset bridge
    narrow gaps (the fold's coarse points at 100k: 109), so the two-level path measures
    its coarse points against their neighbours in the fine Laplacian, which keep to the
    surface.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    uv : (N,) numpy.ndarray of complex128, or (N, 2) of float64
    graph : (N, N) scipy.sparse matrix, optional
        Its off-diagonal entries are the neighbours (a Laplacian). None: the
        ``neighbours`` nearest points in 3D.
    at : (M,) numpy.ndarray of int64, optional
        The points measured (default: all).
    neighbours : int
    tail : float
        Fraction of points cut at each end.

    Returns
    -------
    float
        >= 1; inf where some point's scale is 0 (a collapsed part).
    """
    uv = np.asarray(uv)
    flat = np.column_stack([uv.real, uv.imag]) if np.iscomplexobj(uv) else np.asarray(uv, dtype=np.float64)
    at = np.arange(points.shape[0]) if at is None else np.asarray(at, dtype=np.int64)
    if graph is None:
        k = min(neighbours + 1, points.shape[0])
        d3, near = cKDTree(points).query(points[at], k)
        d3, near = d3[:, 1:], near[:, 1:]
        scale = (np.linalg.norm(flat[near] - flat[at, None, :], axis=2).mean(axis=1)
                 / np.maximum(d3.mean(axis=1), np.finfo(float).tiny))
    else:
        rows = sp.csr_matrix(graph)[at]
        owner = np.repeat(np.arange(at.size), np.diff(rows.indptr))
        source, target = at[owner], rows.indices
        off = source != target
        d3 = np.linalg.norm(points[source[off]] - points[target[off]], axis=1)
        d2 = np.linalg.norm(flat[source[off]] - flat[target[off]], axis=1)
        sum3 = np.bincount(owner[off], weights=d3, minlength=at.size)
        sum2 = np.bincount(owner[off], weights=d2, minlength=at.size)
        has = sum3 > 0
        scale = sum2[has] / sum3[has]
    low, high = np.quantile(scale, [tail, 1.0 - tail])
    return float(high / low) if low > 0 else float("inf")


def full_space_residual(operator: sp.csr_matrix, boundary: np.ndarray, z: np.ndarray) -> tuple[float, complex, np.ndarray]:
    """The Ritz pair of ``(k L / 2 - M, B)`` on span{z, 1} and its relative residual.

    Parameters
    ----------
    operator : (N, N) scipy.sparse.csr_matrix of complex128
        ``k L / 2 - M``.
    boundary : (N,) numpy.ndarray of bool
        B's diagonal (the boundary indicator).
    z : (N,) numpy.ndarray of complex128
        A map.

    Returns
    -------
    residual : float
        ``|A y - lambda B y| / (max|diag A| |y - mean(y)|)``.
    lam : complex
    y : (N,) numpy.ndarray of complex128
        z with the translation that fits the pencil best.

    Raises
    ------
    SolverError
        z is constant (no map to measure).
    """
    basis, _ = np.linalg.qr(np.column_stack([z, np.ones_like(z)]))
    a_small = basis.conj().T @ (operator @ basis)
    b_small = basis[boundary].conj().T @ basis[boundary]
    pair = _ritz(basis, a_small, b_small, z)
    if pair is None:  # z is a translation: nothing to measure
        raise SolverError("the map is constant (a collapsed map): there is no residual to measure.")
    lam, y = pair
    return _residual(operator, boundary, lam, y)[1], lam, y


def full_space_polish(operator, boundary: np.ndarray, prolong: sp.csr_matrix, z: np.ndarray,
                      loops, coarse_points: np.ndarray | None = None, rule: PolishRule = PolishRule(),
                      above: float = 0.0, coarse_operator: sp.spmatrix | None = None) -> tuple[np.ndarray, dict]:
    """Davidson steps in the full space with a two-grid preconditioner, from the map z.

    Parameters
    ----------
    operator : (N, N) scipy.sparse.csr_matrix of complex128, or SplitConformalOperator
        ``k L / 2 - M`` at the map's k.
    boundary : (N,) numpy.ndarray of bool
        B's diagonal.
    prolong : (N, M) scipy.sparse.csr_matrix of float64
        Interpolation from the M coarse points.
    z : (N,) numpy.ndarray of complex128
        The map to polish.
    loops : sequence of (L_i,) numpy.ndarray of int64
        Boundary loops, for the turning numbers of the result.
    coarse_points : (M, 3) numpy.ndarray of float64, optional
        For the coarse factorisation's nested-dissection order.
    rule : PolishRule
    above : float
        Polish only a map whose full-space residual is above this (and above
        ``rule.rtol``); otherwise z itself is returned, untouched.
    coarse_operator : (M, M) scipy.sparse matrix of complex128, optional
        ``P^T (k L / 2 - M) P`` where the caller has it (the two-level path's coarse
        problem: its Galerkin Laplacian, and the fine loops' area matrix, which P carries
        over unchanged); computed otherwise.

    Returns
    -------
    z : (N,) numpy.ndarray of complex128
        The step's map with the smallest residual whose loops turn as z's do (z with
        the translation fitted when no step did better).
    info : dict
        ``full_space_residual_before``, ``full_space_residual``, ``full_space_steps``.

    Raises
    ------
    SolverError
        The coarse operator is singular, or z is constant.
    """
    res0, lam, y = full_space_residual(operator, boundary, z)
    if not res0 > max(above, rule.rtol):  # nothing to do: no factorisation either
        return z, {"full_space_residual_before": res0, "full_space_residual": res0, "full_space_steps": 0}
    turning = loop_turning_numbers(y, loops)
    best = (res0, y)
    # No shifted or conjugate-transposed copy of the operator: at 1M points each is
    # ~0.5 GB of complex entries (the polish's peak was 3 GB above the solve's).
    on_boundary = boundary.astype(np.float64)
    lam0 = lam  # the shift stays at the first Ritz value: the coarse factorisation is made once

    def shifted(x: np.ndarray) -> np.ndarray:
        return operator @ x - lam0 * (on_boundary * x)

    b_coarse = prolong[boundary].T @ prolong[boundary]
    if coarse_operator is None:
        coarse_operator = _galerkin(operator, prolong)
    coarse_op = (coarse_operator - lam0 * b_coarse).tocsc()
    perm = None if coarse_points is None else nested_dissection(coarse_points, abs(coarse_op))
    factor = SparseFactor(coarse_op, perm=perm)
    diag = operator.diagonal() - lam0 * on_boundary
    # Columns in one Fortran-ordered block: adding one copies nothing.
    store = np.empty((y.shape[0], rule.max_steps + 2), dtype=np.complex128, order="F")
    store[:, :2] = np.linalg.qr(np.column_stack([y, np.ones_like(y)]))[0]
    width = 2
    basis = store[:, :width]
    a_small = basis.conj().T @ (operator @ basis)
    steps, since_best = 0, 0
    r = _residual(operator, boundary, lam, y)[0]
    while steps < rule.max_steps and best[0] > rule.rtol and since_best < rule.window:
        e = _jacobi(shifted, diag, -r, np.zeros_like(y), rule)
        e += prolong @ factor.solve(prolong.T @ (-r - shifted(e)))
        e = _jacobi(shifted, diag, -r, e, rule)
        for _ in range(2):  # classical Gram-Schmidt, twice
            e -= basis @ (basis.conj().T @ e)
        norm = np.linalg.norm(e)
        if not norm > 0:
            break
        e /= norm
        op_e = operator @ e
        column = basis.conj().T @ op_e
        row = (operator.T @ e.conj()) @ basis  # e^H A V without a copy of A^H (.T of CSR is a view)
        corner = np.vdot(e, op_e)
        a_small = np.block([[a_small, column[:, None]], [row[None, :], np.array([[corner]])]])
        store[:, width] = e
        width += 1
        basis = store[:, :width]
        b_small = basis[boundary].conj().T @ basis[boundary]
        pair = _ritz(basis, a_small, b_small, y)
        if pair is None:
            break
        lam, y = pair
        steps += 1
        r, res = _residual(operator, boundary, lam, y)
        if res < best[0] and np.array_equal(loop_turning_numbers(y, loops), turning):
            best, since_best = (res, y), 0
        else:
            since_best += 1
    return best[1], {"full_space_residual_before": res0, "full_space_residual": best[0], "full_space_steps": steps}


def _galerkin(operator, prolong: sp.csr_matrix) -> sp.csr_matrix:
    """``P^T A P``."""
    if isinstance(operator, SplitConformalOperator):
        lap_c = prolong.T @ (operator.laplacian @ prolong)
        return ((0.5 * operator.k) * lap_c - prolong.T @ (operator.area @ prolong)).tocsr()
    return (prolong.T @ (operator @ prolong)).tocsr()


def _jacobi(matvec, diag: np.ndarray, rhs: np.ndarray, x: np.ndarray, rule: PolishRule) -> np.ndarray:
    for _ in range(rule.sweeps):
        x = x + rule.omega * (rhs - matvec(x)) / diag
    return x
