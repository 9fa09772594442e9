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

The rows are shared out among the workers in ROW_BLOCKS contiguous blocks, each sweeping
all columns of its rows and reading the other blocks' rows as they stood before the
sweep (a hybrid Gauss-Seidel, the same iterates whatever the number of cores); each
worker restricts its rows' residual and adds the coarse correction to its rows, and
the coarse solves (SuperLU releases the GIL) run side by side on column blocks. Every
block of right-hand sides costs a full set of cycles, so the solver asks for large
blocks (:attr:`TwoGridSolver.max_block_bytes`). Measured at 1M points (bump, 21
right-hand sides, 2 cores, the fine level of :mod:`.multilevel`): three blocks of at
most 8 columns in one shared array, 27 cycles, 49 s; one block with the columns
shared out among the workers, 9 cycles, 14-15 s; with the rows shared out instead
(each worker then reads half the matrix per sweep), see :data:`ROW_BLOCKS`.
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
from .leading_block import LeadingBlock, as_leading_block
from .ordering import symmetric_permutation
from .sparse_eigen import SparseFactor

__all__ = ["TwoGridSolver"]

_CACHE, _ = configure_numba_cache(Path(__file__).resolve().parent)


@numba.njit(cache=_CACHE, nogil=True, fastmath=True)
def _gauss_seidel_rows(starts, stops, indices, data, diag, b, x, r0, r1, halo_slot, halo, backward):  # pragma: no cover
    """One in-place Gauss-Seidel sweep over rows r0:r1 of the column block x (in order or reversed).

    Row i's entries are ``indices[starts[i]:stops[i]]`` (a CSR matrix's ``indptr[:-1]``
    and ``indptr[1:]``, or a :class:`~.leading_block.LeadingBlock`'s rows).

    Entries in columns outside r0:r1 read ``halo[halo_slot[j]]`` (the other blocks' rows
    as they stood before the sweep). The rows' indices are sorted, so such entries sit
    at either end of a row, and the many rows without any take the plain loop. The
    diagonal term is summed with the others and added back, so the inner loop over the
    columns has no branch and vectorises (2.3x faster at 11 columns).
    """
    width = x.shape[1]
    acc = np.empty(width)
    for step in range(r1 - r0):
        i = r1 - 1 - step if backward else r0 + step
        for c in range(width):
            acc[c] = b[i, c]
        lo, hi = starts[i], stops[i]
        if hi > lo and (indices[lo] < r0 or indices[hi - 1] >= r1):
            for p in range(lo, hi):
                a = data[p]
                j = indices[p]
                xj = x[j] if r0 <= j < r1 else halo[halo_slot[j]]
                for c in range(width):
                    acc[c] -= a * xj[c]
        else:
            for p in range(lo, hi):
                a = data[p]
                xj = x[indices[p]]
                for c in range(width):
                    acc[c] -= a * xj[c]
        di = diag[i]
        xi = x[i]
        for c in range(width):
            xi[c] = (acc[c] + di * xi[c]) / di


#: Contiguous row blocks the sweeps are shared out in, from ROW_SPLIT_MIN_ROWS rows (fixed,
#: so that the iterates do not depend on the machine's number of cores). Measured at 1M
#: points (bump, 21 columns, 2 cores): one sweep 0.15-0.20 s against 0.21-0.29 s with the
#: columns shared out instead (each worker then reads the whole matrix); the fine solve
#: 21.4-21.9 s against 23.3-27.5 s, the same 9 cycles, the map the same to 4.8e-9 of the
#: diameter.
ROW_BLOCKS = 2

#: Below this many rows the sweeps run on one block. Smaller problems gain little from the
#: split, and the iterates change: ``real/meg-helmet`` with two levels forced (2k points)
#: ended 4.6e-3 of the diameter from the direct map with two blocks, 8.6e-7 with one (its
#: Davidson refinement on inexact products is sensitive to them, see
#: :data:`~parambench.methods.spectral.multilevel.TWO_LEVEL_REFINE`).
ROW_SPLIT_MIN_ROWS = 200_000


def _row_blocks(a: LeadingBlock, count: int) -> tuple[list[tuple[int, int]], np.ndarray, np.ndarray]:
    """Row ranges of about equal nonzeros, the rows other blocks read, and each one's slot.

    Parameters
    ----------
    a : LeadingBlock
        The matrix's rows (indices sorted).
    count : int
        Blocks wanted.

    Returns
    -------
    blocks : list of (int, int)
        ``count`` (or fewer, for tiny matrices) half-open row ranges covering the rows.
    halo_rows : (H,) numpy.ndarray of int64
        Rows read by a row of another block (sorted).
    halo_slot : (n,) numpy.ndarray of int64
        ``halo_slot[halo_rows[h]] == h``; 0 elsewhere.
    """
    n = a.shape[0]
    start, stop = a.starts, a.stops
    lengths_all = stop - start
    cuts = np.searchsorted(np.concatenate([[0], np.cumsum(lengths_all)]), np.arange(1, count) * a.nnz / count)
    edges = np.unique(np.concatenate([[0], np.clip(cuts, 0, n), [n]]))
    blocks = [(int(lo), int(hi)) for lo, hi in zip(edges[:-1], edges[1:])]
    # A row's indices are sorted, so its first and last say whether it reads another
    # block: per-row arrays only, no nonzero-sized temporaries (at 1M points those were
    # 0.5 GB).
    sizes = np.diff(edges)
    lo = np.repeat(edges[:-1], sizes)
    hi = np.repeat(edges[1:], sizes)
    filled = lengths_all > 0
    size = a.indices.size
    first = np.where(filled, a.indices[np.minimum(start, max(size - 1, 0))], lo) if size else lo
    last = np.where(filled, a.indices[np.clip(stop - 1, 0, max(size - 1, 0))], lo) if size else lo
    crossing = np.flatnonzero(filled & ((first < lo) | (last >= hi)))
    lengths = lengths_all[crossing]
    entries = np.repeat(start[crossing] - np.cumsum(lengths) + lengths, lengths) + np.arange(lengths.sum())
    cols = a.indices[entries]
    row_lo, row_hi = np.repeat(lo[crossing], lengths), np.repeat(hi[crossing], lengths)
    halo_rows = np.unique(cols[(cols < row_lo) | (cols >= row_hi)]).astype(np.int64)
    halo_slot = np.zeros(n, dtype=np.int64)
    halo_slot[halo_rows] = np.arange(halo_rows.size)
    return blocks, halo_rows, halo_slot


class TwoGridSolver:
    """Solve ``A x = b`` for the interior block A of a Laplacian by two-grid cycles.

    Parameters
    ----------
    matrix : (n, n) scipy.sparse matrix of float64, or a LeadingBlock
        The interior block L_II; its diagonal must be positive. A
        :class:`~parambench.methods.spectral.leading_block.LeadingBlock` (L_II as the
        leading rows of L, the kept rows numbered last) is read in place in the caller's
        order; anything else is held as a CSR matrix (the caller's own arrays, its indices
        sorted in place, when it is CSR of float64 already).
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

    def __init__(self, matrix: sp.spmatrix | LeadingBlock, prolong: sp.spmatrix,
                 coarse_solve: Callable[[np.ndarray], np.ndarray], *, rtol: float = 1e-10, max_cycles: int = 40,
                 sweeps: int = 2, stall: float = 0.7, workers: int | None = None,
                 order: np.ndarray | None = None) -> None:
        n = matrix.shape[0]
        own = None if isinstance(matrix, LeadingBlock) and order is not None else _own_csr(matrix)
        # The sweeps gather neighbours' rows of the block: in the caller's order (any
        # order the points came in) they miss the cache; reverse Cuthill-McKee keeps
        # neighbours close in memory (measured at 100k points, 21 columns: 2 sweeps
        # 0.46 s -> 0.08 s). A spatial order does as well for a tenth of the cost (1M
        # points: kd-tree order 0.42 s, RCM 2.7 s; one sweep 0.12-0.14 s either way).
        if order is None:
            order = reverse_cuthill_mckee(own, symmetric_mode=False)
        self._order = np.asarray(order, dtype=np.int64)
        if not np.array_equal(np.sort(self._order), np.arange(n)):
            raise ValueError("order must be a permutation of the matrix's rows.")
        self._identity = bool(np.array_equal(self._order, np.arange(n)))
        # In the caller's order a LeadingBlock is read in place: no copy of the block.
        if self._identity:
            self._a = as_leading_block(matrix if own is None else own)
        else:
            self._a = as_leading_block(symmetric_permutation(_own_csr(matrix) if own is None else own, self._order))
        prolong = sp.csr_matrix(prolong, dtype=np.float64)
        self._p = prolong if self._identity else sp.csr_matrix(prolong[self._order])
        self._coarse_solve = coarse_solve
        self._diag = self._a.diagonal()
        self._blocks, self._halo_rows, self._halo_slot = _row_blocks(
            self._a, ROW_BLOCKS if n >= ROW_SPLIT_MIN_ROWS else 1)
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
        self._direct = SparseFactor(self._a.tocsr())

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
        # From ROW_SPLIT_MIN_ROWS rows on, the rows are shared out in ROW_BLOCKS contiguous
        # blocks, every block sweeping all columns: each worker then reads only its part
        # of the matrix, which bounds the sweeps (measured at 1M points, 21 columns, one sweep on 2 cores: 0.15-0.20 s
        # against 0.21-0.29 s with the columns shared out and the whole matrix read by
        # each worker). A block reads the rows of the others as they stood at the start
        # of the sweep (a snapshot of those few rows), so the iterates depend on the
        # fixed block count only, not on the number of workers or their timing.
        x = np.zeros(b.shape) if guess is None else np.array(guess, dtype=np.float64, order="C")
        blocks = self._blocks
        m, cols = self._p.shape[1], b.shape[1]
        halo = np.empty((self._halo_rows.size, cols))
        restricted = [np.empty((m, cols)) for _ in blocks]
        squares = [np.empty(cols) for _ in blocks]
        col_bounds = [(c * cols // ROW_BLOCKS, (c + 1) * cols // ROW_BLOCKS) for c in range(min(ROW_BLOCKS, cols))]
        a, p = self._a, self._p
        previous = np.inf
        with ThreadPoolExecutor(max_workers=min(self.workers, max(len(blocks), len(col_bounds)))) as pool:
            def each(task, items=range(len(blocks))):
                return list(pool.map(task, items))

            def sweeps(backward: bool) -> None:
                for _ in range(self.sweeps):
                    np.take(x, self._halo_rows, axis=0, out=halo)
                    each(lambda k: _gauss_seidel_rows(a.starts, a.stops, a.indices, a.data, self._diag, b, x, blocks[k][0],
                                                      blocks[k][1], self._halo_slot, halo, backward))

            def residual(k: int) -> None:
                # The residual after the pre-smoothing both feeds the coarse correction
                # and decides convergence: one product with A per cycle instead of two.
                _restricted_residual(a.starts, a.stops, a.indices, a.data, b, x, blocks[k][0], blocks[k][1], p.indptr,
                                     p.indices, p.data, restricted[k], squares[k])

            for cycle in range(self.max_cycles):
                sweeps(backward=False)
                each(residual)
                rel = float((np.sqrt(sum(squares[1:], squares[0])) / norm_b).max())
                if rel <= self.rtol:
                    if not overwrite:
                        return x
                    b[...] = x
                    return b
                if cycle >= 3 and rel > self.stall * previous:
                    break
                previous = rel
                total = sum(restricted[1:], restricted[0])
                # Coarse solves on column blocks, side by side (SuperLU releases the GIL).
                coarse = np.hstack(each(lambda c: self._coarse_solve(np.ascontiguousarray(total[:, c[0]:c[1]])),
                                        col_bounds))
                each(lambda k: _add_csr_product(p.indptr, p.indices, p.data, coarse, x, blocks[k][0], blocks[k][1]))
                sweeps(backward=True)
                self.n_cycles += 1
        self._fall_back()
        return self._direct.solve(b)


def _own_csr(matrix: sp.spmatrix | LeadingBlock) -> sp.csr_matrix:
    """The matrix as CSR of float64 (a LeadingBlock's rows copied out)."""
    return matrix.tocsr() if isinstance(matrix, LeadingBlock) else sp.csr_matrix(matrix, dtype=np.float64)


@numba.njit(cache=_CACHE, nogil=True)
def _restricted_residual(starts, stops, indices, data, b, x, r0, r1, p_ptr, p_idx, p_val, out,
                         squares):  # pragma: no cover
    """``out = P[r0:r1]^T (b - A x)[r0:r1]`` for a column block x, and each column's squared residual on those rows.

    A's rows are read as in :func:`_gauss_seidel_rows`; P is CSR.

    Each row's residual (summed in CSR order, as scipy's product) is scattered through
    its row of P and never stored: no (n, c) residual array.
    """
    width = x.shape[1]
    ri = np.empty(width)
    out[:] = 0.0
    squares[:] = 0.0
    for i in range(r0, r1):
        for c in range(width):
            ri[c] = 0.0
        for p in range(starts[i], stops[i]):
            a = data[p]
            xj = x[indices[p]]
            for c in range(width):
                ri[c] += a * xj[c]
        for c in range(width):
            ri[c] = b[i, c] - ri[c]
            squares[c] += ri[c] * ri[c]
        for q in range(p_ptr[i], p_ptr[i + 1]):
            w = p_val[q]
            oq = out[p_idx[q]]
            for c in range(width):
                oq[c] += w * ri[c]


@numba.njit(cache=_CACHE, nogil=True)
def _add_csr_product(indptr, indices, data, x, out, r0, r1):  # pragma: no cover - compiled
    """``out[r0:r1] += M[r0:r1] x`` for a CSR matrix M and a column block x."""
    width = x.shape[1]
    for i in range(r0, r1):
        oi = out[i]
        for p in range(indptr[i], indptr[i + 1]):
            a = data[p]
            xj = x[indices[p]]
            for c in range(width):
                oi[c] += a * xj[c]
