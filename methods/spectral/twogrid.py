"""Two-grid iterative solves of the interior block L_II, the fine level of :mod:`.multilevel`.

The k search and the map of the fine level need ``L_II^{-1}`` applied to a few dozen
right-hand sides (the Schur products of the boundary subspace, the Davidson steps and the
harmonic extension, :mod:`.reduction`). A sparse factorisation of L_II costs O(n^1.5)
time and its fill dominates the memory at a million points. The coarse level already
holds what a multigrid cycle needs: the prolongation P from the Poisson-disk subsample
(linear-exact, :func:`~parambench.methods.spectral.multilevel.interpolation_matrix`) and a
factorisation of the Galerkin block ``P_II^T L_II P_II``, which is exactly the coarse
problem's interior block (coarse interior columns of P vanish on the boundary, whose
points are coarse points). One cycle is ``sweeps`` forward Gauss-Seidel sweeps, the
coarse correction, and ``sweeps`` backward sweeps; it is iterated as a stationary method
until every column's residual (read after a forward smoothing) is below ``rtol`` of its
right-hand side.

Measured on ocp's Neumann Laplacian (29 nonzeros per row, non-symmetric) at 100k points
(bump, jittered; coarse block 9.5k rows): the residual falls by a factor 7-8 per cycle,
1e-10 after 10 cycles. Where a cycle stops reducing the residual (a Laplacian with
weights the smoother does not suit), the solver factorises L_II once and solves directly
from then on (``fell_back``), so a bad case is slow, never wrong.
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numba
import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import reverse_cuthill_mckee

from ..numba_cache import configure_numba_cache
from .sparse_eigen import SparseFactor

__all__ = ["TwoGridSolver"]

_CACHE, _ = configure_numba_cache(Path(__file__).resolve().parent)


@numba.njit(cache=_CACHE, nogil=True, fastmath=True)
def _gauss_seidel(indptr, indices, data, diag, b, x, c0, c1, sweeps, backward):  # pragma: no cover - compiled
    """In-place Gauss-Seidel sweeps on columns c0:c1 of the block x (rows in order or reversed).

    The diagonal term is summed with the others and added back, so the inner loop over
    the columns has no branch and vectorises (2.3x faster at 11 columns).
    """
    n = x.shape[0]
    width = c1 - c0
    acc = np.empty(width)
    for _ in range(sweeps):
        for step in range(n):
            i = n - 1 - step if backward else step
            for c in range(width):
                acc[c] = b[i, c0 + c]
            for p in range(indptr[i], indptr[i + 1]):
                a = data[p]
                xj = x[indices[p], c0:c1]
                for c in range(width):
                    acc[c] -= a * xj[c]
            di = diag[i]
            xi = x[i, c0:c1]
            for c in range(width):
                xi[c] = (acc[c] + di * xi[c]) / di


class TwoGridSolver:
    """Solve ``A x = b`` for the interior block A of a Laplacian by two-grid cycles.

    Parameters
    ----------
    matrix : (n, n) scipy.sparse matrix of float64
        The interior block L_II; its diagonal must be positive.
    prolong : (n, m) scipy.sparse matrix of float64
        Coarse-to-fine interpolation of interior values.
    coarse_solve : callable
        ``coarse_solve(r)`` for an (m, c) float64 block returns ``(P^T A P)^{-1} r``
        (a :class:`~parambench.methods.spectral.sparse_eigen.SparseFactor`'s ``solve``).
    rtol : float
        Stop when every column's residual 2-norm is at most ``rtol`` times its right-hand side's.
    max_cycles : int
        Most cycles before the direct fallback.
    sweeps : int
        Gauss-Seidel sweeps before and after the coarse correction.
    stall : float
        Fall back to the direct solve when a cycle reduces the largest relative residual
        by less than this factor (after the first three cycles).
    workers : int
        Threads; the columns of a block are shared among them (the kernel releases the GIL).

    Attributes
    ----------
    n_solves : int
        Right-hand sides solved so far.
    n_cycles : int
        Cycles run so far (each on a whole block).
    fell_back : bool
        True once the solver has switched to a sparse factorisation of ``matrix``.
    mixed : bool
        Always False (the attribute :class:`~parambench.methods.spectral.reduction.BoundaryReduction` reads).
    arrays_per_column : int
        Work arrays of the matrix's size per right-hand side (block-size budget).
    iterative : bool
        Always True: every solve costs cycles, so callers keep solutions they may reuse
        (:meth:`~parambench.methods.spectral.reduction.BoundaryReduction.apply_schur_extended`).
    """

    mixed = False
    arrays_per_column = 4
    iterative = True

    def __init__(self, matrix: sp.spmatrix, prolong: sp.spmatrix, coarse_solve: Callable[[np.ndarray], np.ndarray],
                 *, rtol: float = 1e-10, max_cycles: int = 40, sweeps: int = 2, stall: float = 0.7,
                 workers: int | None = None) -> None:
        a = sp.csr_matrix(matrix, dtype=np.float64)
        # The sweeps gather neighbours' rows of the block: in the caller's order (any
        # order the points came in) they miss the cache; reverse Cuthill-McKee keeps
        # neighbours close in memory (measured at 100k points, 21 columns: 2 sweeps
        # 0.46 s -> 0.08 s).
        self._order = reverse_cuthill_mckee(a, symmetric_mode=False).astype(np.int64)
        self._a = sp.csr_matrix(a[self._order][:, self._order])
        self._a.sort_indices()
        self._p = sp.csr_matrix(sp.csr_matrix(prolong, dtype=np.float64)[self._order])
        self._pt = sp.csr_matrix(self._p.T)
        self._coarse_solve = coarse_solve
        self._diag = self._a.diagonal()
        self.rtol, self.max_cycles, self.sweeps, self.stall = float(rtol), int(max_cycles), int(sweeps), float(stall)
        self.workers = max(1, int(numba.config.NUMBA_NUM_THREADS if workers is None else workers))
        self.n_solves = 0
        self.n_cycles = 0
        self._direct: SparseFactor | None = None
        if not np.all(self._diag > 0):  # Gauss-Seidel needs a positive diagonal
            self._fall_back()

    @property
    def fell_back(self) -> bool:
        return self._direct is not None

    def _fall_back(self) -> None:
        self._direct = SparseFactor(self._a)

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """Solve for a vector or an (n, c) block of right-hand sides (real or complex).

        Returns
        -------
        numpy.ndarray
            Same shape and kind (real/complex) as ``rhs``.
        """
        rhs = np.asarray(rhs)
        self.n_solves += 1 if rhs.ndim == 1 else rhs.shape[1]
        if np.iscomplexobj(rhs):
            block = rhs.reshape(rhs.shape[0], -1)
            x = self._solve_real(np.hstack([block.real, block.imag]))
            half = block.shape[1]
            return (x[:, :half] + 1j * x[:, half:]).reshape(rhs.shape)
        return self._solve_real(rhs.reshape(rhs.shape[0], -1)).reshape(rhs.shape)

    def _solve_real(self, b: np.ndarray) -> np.ndarray:
        """Solve for an (n, c) real block in the caller's order."""
        x = np.empty((b.shape[0], b.shape[1]), dtype=np.float64)
        x[self._order] = self._solve_ordered(np.ascontiguousarray(b[self._order], dtype=np.float64))
        return x

    def _solve_ordered(self, b: np.ndarray) -> np.ndarray:
        if self._direct is not None:
            return self._direct.solve(b)
        norm_b = np.linalg.norm(b, axis=0)
        norm_b[norm_b == 0] = 1.0
        x = np.zeros_like(b)
        previous = np.inf
        for cycle in range(self.max_cycles):
            # The residual after the pre-smoothing both feeds the coarse correction and
            # decides convergence: one product with A per cycle instead of two.
            self._smooth(b, x, backward=False)
            r = b - self._a @ x
            rel = float((np.linalg.norm(r, axis=0) / norm_b).max())
            if rel <= self.rtol:
                return x
            if cycle >= 3 and rel > self.stall * previous:
                break
            previous = rel
            x += self._p @ self._coarse_solve(np.ascontiguousarray(self._pt @ r))
            self._smooth(b, x, backward=True)
            self.n_cycles += 1
        self._fall_back()
        return self._direct.solve(b)

    def _smooth(self, b: np.ndarray, x: np.ndarray, backward: bool) -> None:
        a, cols = self._a, x.shape[1]
        chunks = min(self.workers, cols)
        bounds = [(c * cols // chunks, (c + 1) * cols // chunks) for c in range(chunks)]

        def run(bound):
            _gauss_seidel(a.indptr, a.indices, a.data, self._diag, b, x, bound[0], bound[1], self.sweeps, backward)

        if chunks == 1:
            run(bounds[0])
            return
        with ThreadPoolExecutor(max_workers=chunks) as pool:
            list(pool.map(run, bounds))
