"""Sparse factorisation and the shift-invert eigen-solve of ``K z = lambda B z``.

Translations (the constant vector, ``K 1 = 0``) are removed explicitly: the iteration
runs on ``P (K - sigma B)^{-1} B P`` with ``P`` the projection that subtracts the mean.
Because the constant vector is an exact eigenvector of the shift-inverted operator, this
Schur-style deflation leaves every other eigenvalue in place, for Hermitian and
non-Hermitian K alike, and the eigenvectors it returns are the true ones up to a
translation. No fixed number of eigenvectors is skipped, so exactly developable surfaces
(a second zero eigenvalue, the conformal map itself) are handled.

One factorisation of ``K - sigma B`` serves every iteration. For Hermitian K the LDL-like
pivots of that factorisation also give the inertia (Sylvester), i.e. the number of
eigenvalues below sigma, which detects an indefinite energy without searching for it.
"""

from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as sla

from parambench.datasets_gen.errors import ConvergenceError, SolverError, UnknownNameError

from ..hints import Hint, hinted
from .leading_block import LeadingBlock
from .threads import single_threaded_blas, solver_threads

__all__ = ["SparseFactor", "EigenResult", "smallest_eigenpair", "MIXED_PRECISION_FROM"]

#: Fewest right-hand sides per chunk when a block's triangular solves are shared out by
#: columns (SuperLU releases the GIL); smaller blocks are solved on one thread.
SPLIT_MIN_COLUMNS = 8

#: Real systems at least this large are factorised in single precision by default
#: (``precision="auto"``): the factor, which dominates the memory of a million-point
#: solve, halves; a few steps of iterative refinement in double precision restore the
#: accuracy (measured relative residuals: ocp's interior block at 100k, 5e-7 -> 2e-12
#: -> 4e-16; the SDP matrix of 100k holes, 1e-5 -> 4e-9 -> 3e-12 -> 1e-14).
MIXED_PRECISION_FROM = 250_000


class SparseFactor:
    """LU factorisation of a sparse square matrix, optionally in a given elimination order.

    Parameters
    ----------
    matrix : (V, V) scipy.sparse matrix (real or complex), or a LeadingBlock (copied out)
        In mixed precision a CSR or CSC matrix is kept by reference for the
        refinement residuals: do not modify it while the factor is in use.
    perm : (V,) numpy.ndarray of int64, optional
        Symmetric elimination order (e.g. :func:`~parambench.methods.spectral.ordering.nested_dissection`);
        SuperLU's minimum degree on ``A^T + A`` otherwise.
    hermitian : bool
        Factor without row pivoting, so that :meth:`negative_pivots` gives the inertia.
    precision : {"auto", "double", "mixed"}
        "mixed": factor a real matrix in single precision and refine every solve in
        double precision (residual below ``refine_rtol``, at most ``max_refine`` steps).
        "auto": "mixed" for real matrices of at least :data:`MIXED_PRECISION_FROM` rows.
    refine_rtol, max_refine : float, int
        Mixed precision only.

    Raises
    ------
    SolverError
        The matrix is (numerically) singular.
    """

    def __init__(self, matrix: sp.spmatrix, perm: np.ndarray | None = None, hermitian: bool = False,
                 precision: str = "auto", refine_rtol: float = 1e-12, max_refine: int = 4) -> None:
        if precision not in ("auto", "double", "mixed"):
            raise UnknownNameError(f"precision must be 'auto', 'double' or 'mixed', got {precision!r}.")
        if isinstance(matrix, LeadingBlock):  # a factorisation needs the block's own arrays
            matrix = matrix.tocsr()
        real = not np.issubdtype(matrix.dtype, np.complexfloating)
        self.perm = perm
        self.n_solves = 0
        # Solves may come from several threads (the two-grid workers' coarse corrections):
        # the counter and the switch to double precision are guarded.
        self._lock = threading.Lock()
        self.mixed = real and (precision == "mixed" or (precision == "auto" and matrix.shape[0] >= MIXED_PRECISION_FROM))
        # Refinement computes residuals with the caller's matrix in its own order: a
        # reference, not a permuted double-precision copy (340 MB at 1M points).
        self._matrix = (matrix if matrix.format in ("csr", "csc") else matrix.tocsr()) if self.mixed else None
        self._refine_rtol, self._max_refine = float(refine_rtol), int(max_refine)
        # Diagonal pivots only for Hermitian matrices: then the factorisation is an
        # LDL^H in disguise and its pivots give the inertia. Otherwise a small threshold
        # lets SuperLU pivot away from a tiny diagonal.
        self._opts = dict(permc_spec="MMD_AT_PLUS_A" if perm is None else "NATURAL",
                          diag_pivot_thresh=0.0 if hermitian else 0.01, options=dict(SymmetricMode=True))
        if self.mixed:
            try:
                self._lu = sla.splu(self._permuted(matrix, np.float32), **self._opts)
                self._factor_dtype = np.dtype(np.float32)
                return
            except RuntimeError:  # singular in single precision: too ill-conditioned for it
                self.mixed, self._matrix = False, None
        self._lu = self._factor_double(self._permuted(matrix, None))

    def _permuted(self, matrix: sp.spmatrix, dtype) -> sp.csc_matrix:
        """The matrix in elimination order, as CSC (optionally cast)."""
        a = sp.csr_matrix(matrix)
        if self.perm is not None:
            a = a[self.perm][:, self.perm]
        a = sp.csc_matrix(a)
        return a if dtype is None else a.astype(dtype)

    def _factor_double(self, a: sp.csc_matrix):
        self._factor_dtype = np.result_type(a.dtype, np.float32)  # as splu casts
        try:
            return sla.splu(a, **self._opts)
        except RuntimeError as exc:  # SuperLU: "Factor is exactly singular"
            raise hinted(SolverError, f"sparse factorisation failed ({exc}); the system is singular",
                         Hint("check that the mesh is connected and the weights are not degenerate"),
                         Hint("try other weights", "weights")) from None

    def _fall_back_to_double(self) -> None:
        self.mixed = False
        self._lu = None
        self._lu = self._factor_double(self._permuted(self._matrix, None))
        self._matrix = None

    @property
    def arrays_per_column(self) -> int:
        """Work arrays of the matrix's size per right-hand side of a solve (4 in mixed precision)."""
        return 4 if self.mixed else 1

    @property
    def fill(self) -> int:
        """Nonzeros in the L and U factors."""
        return int(self._lu.L.nnz + self._lu.U.nnz)

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """Solve ``A x = rhs`` for a vector or an (V, m) block of right-hand sides."""
        with self._lock:
            self.n_solves += 1 if rhs.ndim == 1 else rhs.shape[1]
        return self._solve_mixed(rhs) if self.mixed else self._lu_solve(rhs)

    def _solve_mixed(self, rhs: np.ndarray) -> np.ndarray:
        if np.iscomplexobj(rhs):
            return self._solve_mixed(rhs.real) + 1j * self._solve_mixed(rhs.imag)
        rhs = np.asarray(rhs, dtype=np.float64)
        x = self._lu_solve(rhs.astype(np.float32)).astype(np.float64)
        norm_b = np.linalg.norm(rhs, axis=0)
        for _ in range(self._max_refine):
            r = rhs - self._matrix @ x
            if np.all(np.linalg.norm(r, axis=0) <= self._refine_rtol * norm_b):
                return x
            x += self._lu_solve(r.astype(np.float32))
        if np.all(np.linalg.norm(rhs - self._matrix @ x, axis=0) <= 1e-8 * norm_b):
            return x
        # Refinement stalls when the matrix is too ill-conditioned for single precision.
        with self._lock:
            if self.mixed:  # another thread may have switched already
                self._fall_back_to_double()
        return self._lu_solve(rhs)

    def _lu_solve(self, rhs: np.ndarray) -> np.ndarray:
        """One solve with the factors (whatever their precision), in the caller's order."""
        if self.perm is None:
            return self._solve_columns(rhs)
        x = self._solve_columns(np.ascontiguousarray(rhs[self.perm]))
        out = np.empty_like(x)
        out[self.perm] = x
        return out

    def _solve_columns(self, rhs: np.ndarray) -> np.ndarray:
        """SuperLU's solve, its columns shared out among threads when there are many.

        SuperLU releases the GIL, and its solves with one BLAS thread each run side by
        side (80 right-hand sides of a 90k-row Laplacian, 2 cores: 0.66-0.91 s on one
        thread, 0.42-0.51 s on two). The block is cut into two chunks per thread, of at
        least ``SPLIT_MIN_COLUMNS`` columns each, so the copies SuperLU makes of the
        chunks being solved are at most half the block at any time (the memory budget
        of :attr:`arrays_per_column` counts the block itself). Only the main thread
        shares out: a solve called from workers that already share the cores (the
        two-grid cycles' coarse corrections) stays on its thread.
        """
        workers = solver_threads()
        nested = threading.current_thread() is not threading.main_thread()
        n_chunks = 2 * workers
        if rhs.ndim == 1 or workers < 2 or nested or rhs.shape[1] < n_chunks * SPLIT_MIN_COLUMNS:
            return self._lu.solve(rhs)
        cols = rhs.shape[1]
        bounds = [(c * cols // n_chunks, (c + 1) * cols // n_chunks) for c in range(n_chunks)]
        out = np.empty((rhs.shape[0], cols), dtype=self._factor_dtype)  # SuperLU solves in its factors' type

        def run(bound: tuple[int, int]) -> None:
            lo, hi = bound
            out[:, lo:hi] = self._lu.solve(rhs[:, lo:hi])

        with single_threaded_blas(), ThreadPoolExecutor(max_workers=workers) as pool:
            list(pool.map(run, bounds))
        return out

    def negative_pivots(self) -> int | None:
        """Number of negative pivots, the inertia of a Hermitian matrix; None if rows were pivoted."""
        if not np.array_equal(self._lu.perm_r, self._lu.perm_c):
            return None
        return int(np.sum(self._lu.U.diagonal().real < 0))


@dataclass
class EigenResult:
    """An eigenpair of ``K z = lambda B z``.

    Attributes
    ----------
    vector : (V,) numpy.ndarray of complex128
        Mean-free (translation removed), unit 2-norm.
    value : complex
        Its eigenvalue (real up to rounding for Hermitian K).
    values : (m,) numpy.ndarray of complex128
        All eigenvalues found, by increasing real part.
    residual : float
        Normwise backward error ``|K z - lambda B z| / ((|K|_1 + |lambda| |B|_1) |z|)``,
        the translation component of the residual removed.
    n_solves : int
        Triangular solves with the factorisation.
    n_factorizations : int
    vectors : (V, m) numpy.ndarray of complex128
        The eigenvectors of ``values``, as the solver returned them.
    """

    vector: np.ndarray
    value: complex
    values: np.ndarray
    residual: float
    n_solves: int
    n_factorizations: int
    vectors: np.ndarray | None = None


def _spectral_scale(k_mat: sp.spmatrix, b_mat: sp.spmatrix) -> float:
    bd = np.abs(b_mat.diagonal())
    kd = np.abs(k_mat.diagonal())
    return float(kd.mean() / bd[bd > 0].mean())


def _nearest(k_mat, b_mat, factor: SparseFactor, sigma: float, nev: int, tol: float, seed: int):
    n = k_mat.shape[0]

    def apply(x: np.ndarray) -> np.ndarray:
        x = np.asarray(x).ravel()
        y = factor.solve(b_mat @ (x - x.mean()))
        return y - y.mean()

    op = sla.LinearOperator((n, n), matvec=apply, dtype=np.complex128)
    rng = np.random.default_rng(seed)
    v0 = rng.standard_normal(n) + 1j * rng.standard_normal(n)
    v0 -= v0.mean()
    # A short Krylov space suffices: the wanted eigenvalue is well separated after the
    # shift-inversion (measured: 7-11 solves to a backward error of 1e-16 at 100k vertices).
    ncv = min(n - 1, 2 * nev + 6)
    try:
        theta, vecs = sla.eigs(op, k=nev, which="LM", v0=v0, ncv=ncv, tol=tol, maxiter=max(1000, 20 * ncv))
    except sla.ArpackNoConvergence as exc:
        raise hinted(ConvergenceError, f"shift-invert eigen-solve did not converge ({exc})",
                     Hint("try b_matrix='mass'", "b_matrix", "mass"), Hint("try other weights", "weights"),
                     Hint("check the mesh for near-degenerate triangles")) from None
    keep = np.abs(theta) > 0
    lam = sigma + 1.0 / theta[keep]
    order = np.argsort(lam.real)
    return lam[order], vecs[:, keep][:, order]


def _residual(k_mat, b_mat, z: np.ndarray, lam: complex) -> float:
    kz, bz = k_mat @ z, b_mat @ z
    r = kz - lam * bz
    # The eigenvector is only known up to a translation c 1, and K(z + c1) = Kz while
    # B(z + c1) = Bz + c B1: drop the residual's component along B1.
    b1 = np.asarray(b_mat.sum(axis=1)).ravel()
    r = r - b1 * (np.vdot(b1, r) / np.vdot(b1, b1))
    # Normwise backward error: relative to |K| |z|, not |K z|, which vanishes for the
    # exactly conformal map of a developable surface (eigenvalue 0).
    k_norm = sp.linalg.norm(k_mat, 1)
    b_norm = sp.linalg.norm(b_mat, 1)
    scale = (k_norm + abs(lam) * b_norm) * np.linalg.norm(z)
    return float(np.linalg.norm(r) / max(scale, np.finfo(float).tiny))


def _isolate_smallest(factor_at, sigma: float, below: int, scale: float, max_steps: int):
    """Shift just below the smallest eigenvalue of a Hermitian pencil, by inertia counts.

    ``below`` eigenvalues lie under ``sigma``. Step down until none does, then bisect
    until exactly one eigenvalue lies between the two shifts; shift-inverting at the
    lower one then converges to the smallest eigenvalue whatever the spinning modes
    between it and zero (computing all of them instead took 4000 ARPACK steps).
    """
    hi, n_hi = sigma, below
    step = max(abs(sigma), 1e-3 * scale)
    for _ in range(8 * max_steps):
        lo = sigma - step
        f_lo = factor_at(lo)
        n_lo = f_lo.negative_pivots()
        if n_lo is None:
            break
        if n_lo == 0:
            for _ in range(8 * max_steps):
                if n_hi <= 1:
                    return lo, f_lo
                mid = 0.5 * (lo + hi)
                f_mid = factor_at(mid)
                n_mid = f_mid.negative_pivots()
                if n_mid is None:
                    break
                if n_mid == 0:
                    lo, f_lo = mid, f_mid
                else:
                    hi, n_hi = mid, n_mid
            return lo, f_lo
        hi, n_hi = lo, n_lo
        step *= 4.0
    raise ConvergenceError("could not bracket the smallest eigenvalue by inertia (pivoting or a very indefinite "
                           "energy); start the k search closer to k_opt.")


def smallest_eigenpair(k_mat: sp.spmatrix, b_mat: sp.spmatrix, *, hermitian: bool, perm: np.ndarray | None = None,
                       allow_negative: bool = False, check_inertia: bool = True, nev: int = 2, tol: float = 1e-12,
                       seed: int = 0, max_shifts: int = 8) -> EigenResult:
    """Eigenpair of ``K z = lambda B z`` with the smallest real part, translations excluded.

    Parameters
    ----------
    k_mat : (V, V) scipy.sparse matrix of complex128
        The conformal operator ``k L / 2 - M``; its rows must sum to zero.
    b_mat : (V, V) scipy.sparse matrix of float64
        B: positive semi-definite diagonal or mass matrix, positive on the boundary.
    hermitian : bool
        K is Hermitian (symmetric L). Enables the inertia check.
    perm : (V,) numpy.ndarray of int64, optional
        Elimination order for the factorisation.
    allow_negative : bool
        Return a negative smallest eigenvalue (needed inside the k search, below
        k_opt) instead of raising.
    check_inertia : bool
        Count the eigenvalues below the shift from the factorisation's pivots (Hermitian
        K only). Extracting the pivots costs about 15 % of the solve at 100k vertices;
        callers that know K is positive semi-definite (cotangent weights, k >= 1) skip it.
    nev : int
        Eigenvalues computed near each shift.
    tol : float
        ARPACK relative tolerance.
    seed : int
        Seed of the ARPACK start vector.
    max_shifts : int
        Scale of the number of inertia counts allowed while isolating the smallest of
        several negative eigenvalues (Hermitian case).

    Returns
    -------
    EigenResult

    Raises
    ------
    SolverError
        Negative eigenvalues (the energy is unbounded below at this k) and
        ``allow_negative`` is False; a singular factorisation; a backward error above 1e-8.
    ConvergenceError
        ARPACK did not converge, or the smallest eigenvalue could not be isolated.
    """
    with single_threaded_blas():  # see parambench.methods.spectral.threads
        return _smallest_eigenpair(k_mat, b_mat, hermitian=hermitian, perm=perm, allow_negative=allow_negative,
                                   check_inertia=check_inertia, nev=nev, tol=tol, seed=seed, max_shifts=max_shifts)


def _smallest_eigenpair(k_mat: sp.spmatrix, b_mat: sp.spmatrix, *, hermitian: bool, perm: np.ndarray | None = None,
                       allow_negative: bool = False, check_inertia: bool = True, nev: int = 2, tol: float = 1e-12,
                       seed: int = 0, max_shifts: int = 8) -> EigenResult:
    k_mat = sp.csr_matrix(k_mat, dtype=np.complex128)
    b_mat = sp.csr_matrix(b_mat, dtype=np.float64)
    n = k_mat.shape[0]
    nev = max(1, min(nev, n - 3))
    scale = _spectral_scale(k_mat, b_mat)
    # Just below zero: K is singular (translations) and, on developable surfaces, has a
    # second zero eigenvalue; a tiny negative shift makes K - sigma B definite there.
    sigma = -1e-8 * scale
    counter = {"factorizations": 0}

    def factor_at(shift: float) -> SparseFactor:
        counter["factorizations"] += 1
        return SparseFactor(k_mat - shift * b_mat, perm, hermitian=hermitian)

    factor = factor_at(sigma)
    below = factor.negative_pivots() if hermitian and check_inertia else None
    if below and not allow_negative:
        raise hinted(
            SolverError,
            f"the conformal energy is indefinite: {below} eigenvalue(s) below zero at this k, so the map "
            "would spin (turning number > 1)",
            Hint("use k_search='line'", "k_search", "line"), Hint("use k_search='direct'", "k_search", "direct"), Hint("use normalized=False", "normalized", False),
        )
    if below:
        sigma, factor = _isolate_smallest(factor_at, sigma, below, scale, max_shifts)
    lam, vecs = _nearest(k_mat, b_mat, factor, sigma, nev, tol, seed)
    if hermitian:
        lam = lam.real.astype(np.complex128)
    n_solves, n_fact = factor.n_solves, counter["factorizations"]
    z = vecs[:, 0]
    value = complex(lam[0])
    if not allow_negative and value.real < -1e-8 * scale:
        raise hinted(SolverError, f"smallest eigenvalue {value.real:.3e} is negative: the conformal energy is "
                     "indefinite at this k (non-symmetric weights)", Hint("use k_search='line'", "k_search", "line"), Hint("use k_search='direct'", "k_search", "direct"))
    res = _residual(k_mat, b_mat, z, value)
    if not res <= 1e-8:
        raise hinted(SolverError, f"eigenvector residual {res:.2e} is too large; the shift-invert solve is "
                     "unreliable (near-singular system)", Hint("check for degenerate triangles"),
                     Hint("try b_matrix='mass'", "b_matrix", "mass"))
    z = z - z.mean()
    return EigenResult(vector=z / np.linalg.norm(z), value=value, values=lam, residual=res,
                       n_solves=n_solves, n_factorizations=n_fact, vectors=vecs)
