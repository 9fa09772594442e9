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

The columns of a block are shared out among the workers, each owning a contiguous
block of them for the whole solve: its sweeps, its residual (restricted through P as
it is formed, never stored), its coarse solves (SuperLU releases the GIL) and its
share of the correction. Every block of right-hand sides costs a full set of cycles,
so the solver asks for large blocks (:attr:`TwoGridSolver.max_block_bytes`). Measured
at 1M points (bump, 21 right-hand sides, 2 cores, the fine level of :mod:`.multilevel`):
three blocks of at most 8 columns in one shared array, 27 cycles, 49 s; one block
with the work split as above, 9 cycles, 14-15 s.
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
from .ordering import symmetric_permutation
from .sparse_eigen import SparseFactor

__all__ = ["TwoGridSolver"]

_CACHE, _ = configure_numba_cache(Path(__file__).resolve().parent)


@numba.njit(cache=_CACHE, nogil=True, fastmath=True)
def _gauss_seidel(indptr, indices, data, diag, b, b0, x, sweeps, backward):  # pragma: no cover - compiled
    """In-place Gauss-Seidel sweeps on the block x, right-hand sides columns b0: of b (rows in order or reversed).

    The diagonal term is summed with the others and added back, so the inner loop over
    the columns has no branch and vectorises (2.3x faster at 11 columns).
    """
    n, width = x.shape
    acc = np.empty(width)
    for _ in range(sweeps):
        for step in range(n):
            i = n - 1 - step if backward else step
            for c in range(width):
                acc[c] = b[i, b0 + c]
            for p in range(indptr[i], indptr[i + 1]):
                a = data[p]
                xj = x[indices[p]]
                for c in range(width):
                    acc[c] -= a * xj[c]
            di = diag[i]
            xi = x[i]
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
        (a :class:`~parambench.methods.spectral.sparse_eigen.SparseFactor`'s ``solve``);
        called from several threads at once, on different blocks.
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
    order : (n,) numpy.ndarray of int, optional
        The order of the rows in the sweeps, a permutation that keeps neighbours close in
        memory (e.g. :func:`parambench.methods.pointset.reorder.spatial_order` of
        the rows' points); reverse Cuthill-McKee of ``matrix`` by default.

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
        Work arrays of the matrix's size per right-hand side (block-size budget): the
        right-hand side and the workers' solutions, written into it when the caller
        lets the solve overwrite it (``overwrite_rhs``); a permuted copy more when the
        rows are reordered.
    max_block_bytes : int
        The block-size budget this solver asks for (larger than a factorisation's).
    iterative : bool
        Always True: every solve costs cycles, so callers keep solutions they may reuse
        (:meth:`~parambench.methods.spectral.reduction.BoundaryReduction.apply_schur_extended`).
    """

    mixed = False
    #: Column blocks up to this size (:class:`~parambench.methods.spectral.reduction.BoundaryReduction`):
    #: every block costs its own cycles (at 1M points 9 per block: 21 columns in one
    #: block took 21 s, in three blocks of at most 8 columns 44 s).
    max_block_bytes = 640 * 2**20
    iterative = True

    def __init__(self, matrix: sp.spmatrix, prolong: sp.spmatrix, coarse_solve: Callable[[np.ndarray], np.ndarray],
                 *, rtol: float = 1e-10, max_cycles: int = 40, sweeps: int = 2, stall: float = 0.7,
                 workers: int | None = None, order: np.ndarray | None = None) -> None:
        a = sp.csr_matrix(matrix, dtype=np.float64)
        # The sweeps gather neighbours' rows of the block: in the caller's order (any
        # order the points came in) they miss the cache; reverse Cuthill-McKee keeps
        # neighbours close in memory (measured at 100k points, 21 columns: 2 sweeps
        # 0.46 s -> 0.08 s). A spatial order does as well for a tenth of the cost (1M
        # points: kd-tree order 0.42 s, RCM 2.7 s; one sweep 0.12-0.14 s either way).
        if order is None:
            order = reverse_cuthill_mckee(a, symmetric_mode=False)
        self._order = np.asarray(order, dtype=np.int64)
        if not np.array_equal(np.sort(self._order), np.arange(a.shape[0])):
            raise ValueError("order must be a permutation of the matrix's rows.")
        self._identity = bool(np.array_equal(self._order, np.arange(a.shape[0])))
        self._a = a if self._identity else symmetric_permutation(a, self._order)
        self._a.sort_indices()
        prolong = sp.csr_matrix(prolong, dtype=np.float64)
        self._p = prolong if self._identity else sp.csr_matrix(prolong[self._order])
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
    def arrays_per_column(self) -> int:
        """2 in the caller's order, 3 when the rows are permuted (a permuted copy of the block).

        The workers read their columns of the right-hand side in place (read-only, so no
        cache lines are shared for writing) and copy their solutions into it at the end:
        2 arrays per column instead of 3, so at 1M points the 41 right-hand sides of
        "holes" fit one block of cycles instead of two.
        """
        return 2 if self._identity else 3

    @property
    def fell_back(self) -> bool:
        return self._direct is not None

    def _fall_back(self) -> None:
        self._direct = SparseFactor(self._a)

    def solve(self, rhs: np.ndarray, guess: np.ndarray | None = None, *, overwrite_rhs: bool = False) -> np.ndarray:
        """Solve for a vector or an (n, c) block of right-hand sides (real or complex).

        Parameters
        ----------
        rhs : (n,) or (n, c) numpy.ndarray of float64 or complex128
        guess : (n, c) numpy.ndarray of float64, optional
            Starting values of a real block (a solution to a looser tolerance: the
            cycles then only go on from its residual, 2-3 cycles per factor 100).
        overwrite_rhs : bool
            Let the solve return the solution in ``rhs``'s own memory (a C-contiguous
            float64 block; otherwise a copy is made and ``rhs`` left alone): one array of
            the block's size less at the peak.

        Returns
        -------
        numpy.ndarray
            Same shape and kind (real/complex) as ``rhs``.
        """
        rhs = np.asarray(rhs)
        self.n_solves += 1 if rhs.ndim == 1 else rhs.shape[1]
        if np.iscomplexobj(rhs):
            if guess is not None:
                raise ValueError("a starting guess is taken for real right-hand sides only.")
            block = rhs.reshape(rhs.shape[0], -1)
            x = self._solve_real(np.hstack([block.real, block.imag]), overwrite=True)
            half = block.shape[1]
            return (x[:, :half] + 1j * x[:, half:]).reshape(rhs.shape)
        shape = rhs.shape
        if guess is not None and np.shape(guess) != shape:
            raise ValueError(f"guess must have the right-hand side's shape {shape}, got {np.shape(guess)}.")
        g = None if guess is None else np.asarray(guess, dtype=np.float64).reshape(shape[0], -1)
        b = rhs.reshape(shape[0], -1)
        if not (overwrite_rhs and b.dtype == np.float64 and b.flags.c_contiguous and b.flags.writeable):
            b = np.array(b, dtype=np.float64, order="C")  # the solve's own copy, free to overwrite
        return self._solve_real(b, g, overwrite=True).reshape(shape)

    def _solve_real(self, b: np.ndarray, guess: np.ndarray | None = None, overwrite: bool = False) -> np.ndarray:
        """Solve for an (n, c) real block in the caller's order (into ``b`` when ``overwrite``)."""
        if self._identity:
            return self._solve_ordered(np.ascontiguousarray(b, dtype=np.float64), guess, overwrite)
        solution = self._solve_ordered(np.ascontiguousarray(b[self._order], dtype=np.float64),
                                       None if guess is None else guess[self._order], True)
        x = b if overwrite else np.empty((b.shape[0], b.shape[1]), dtype=np.float64)
        x[self._order] = solution
        return x

    def _solve_ordered(self, b: np.ndarray, guess: np.ndarray | None = None, overwrite: bool = False) -> np.ndarray:
        if self._direct is not None:
            return self._direct.solve(b)
        norm_b = np.linalg.norm(b, axis=0)
        norm_b[norm_b == 0] = 1.0
        # Each worker owns a contiguous block of columns for the whole solve: threads
        # writing neighbouring columns of one (n, c) array share its cache lines, which
        # made two threads slower than one (measured at 1M points, 21 columns: one
        # Gauss-Seidel sweep 0.22-0.37 s on two threads sharing the array, 0.16 s on one
        # thread, 0.13 s on two threads with their own arrays); the right-hand side is
        # only read, so the workers share it in place. The workers also restrict
        # their residual and add their share of the coarse correction, so no (n, c)
        # array is gathered or formed per cycle.
        cols = b.shape[1]
        chunks = max(1, min(self.workers, cols))
        bounds = [(c * cols // chunks, (c + 1) * cols // chunks) for c in range(chunks)]
        xs = [np.zeros((b.shape[0], hi - lo)) if guess is None else np.array(guess[:, lo:hi], dtype=np.float64, order="C")
              for lo, hi in bounds]
        m = self._p.shape[1]
        restricted = [np.empty((m, hi - lo)) for lo, hi in bounds]
        squares = [np.empty(hi - lo) for lo, hi in bounds]
        a, p = self._a, self._p
        previous = np.inf
        with ThreadPoolExecutor(max_workers=chunks) as pool:
            def each(task):
                list(pool.map(task, range(chunks)))

            def pre(t):
                # The residual after the pre-smoothing both feeds the coarse correction
                # and decides convergence: one product with A per cycle instead of two.
                self._sweep(b, bounds[t][0], xs[t], backward=False)
                _restricted_residual(a.indptr, a.indices, a.data, b, bounds[t][0], xs[t], p.indptr, p.indices,
                                     p.data, restricted[t], squares[t])

            for cycle in range(self.max_cycles):
                each(pre)
                rel = float((np.sqrt(np.concatenate(squares)) / norm_b).max())
                if rel <= self.rtol:
                    if not overwrite:
                        return np.hstack(xs)
                    for (lo, hi), part in zip(bounds, xs):
                        b[:, lo:hi] = part
                    return b
                if cycle >= 3 and rel > self.stall * previous:
                    break
                previous = rel

                def post(t):
                    # The coarse solves run in the workers too (SuperLU releases the GIL).
                    coarse = np.ascontiguousarray(self._coarse_solve(restricted[t]))
                    _add_csr_product(p.indptr, p.indices, p.data, coarse, xs[t])
                    self._sweep(b, bounds[t][0], xs[t], backward=True)

                each(post)
                self.n_cycles += 1
        self._fall_back()
        return self._direct.solve(b)

    def _sweep(self, b: np.ndarray, b0: int, x: np.ndarray, backward: bool) -> None:
        """Gauss-Seidel sweeps on a worker's block x, whose right-hand sides are columns b0: of b."""
        a = self._a
        _gauss_seidel(a.indptr, a.indices, a.data, self._diag, b, b0, x, self.sweeps, backward)


@numba.njit(cache=_CACHE, nogil=True)
def _restricted_residual(indptr, indices, data, b, b0, x, p_ptr, p_idx, p_val, out, squares):  # pragma: no cover
    """``out = P^T (b - A x)`` for a column block x (right-hand sides: columns b0: of b), and each column's squared residual norm.

    Each row's residual (summed in CSR order, as scipy's product) is scattered through
    its row of P and never stored: no (n, c) residual array.
    """
    width = x.shape[1]
    ri = np.empty(width)
    out[:] = 0.0
    squares[:] = 0.0
    for i in range(x.shape[0]):
        for c in range(width):
            ri[c] = 0.0
        for p in range(indptr[i], indptr[i + 1]):
            a = data[p]
            xj = x[indices[p]]
            for c in range(width):
                ri[c] += a * xj[c]
        for c in range(width):
            ri[c] = b[i, b0 + c] - ri[c]
            squares[c] += ri[c] * ri[c]
        for q in range(p_ptr[i], p_ptr[i + 1]):
            w = p_val[q]
            oq = out[p_idx[q]]
            for c in range(width):
                oq[c] += w * ri[c]


@numba.njit(cache=_CACHE, nogil=True)
def _add_csr_product(indptr, indices, data, x, out):  # pragma: no cover - compiled
    """``out += M x`` for a CSR matrix M and a column block x."""
    width = x.shape[1]
    for i in range(out.shape[0]):
        oi = out[i]
        for p in range(indptr[i], indptr[i + 1]):
            a = data[p]
            xj = x[indices[p]]
            for c in range(width):
                oi[c] += a * xj[c]
