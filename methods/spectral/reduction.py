"""Exact reduction of the conformal problems to the boundary (plus any pinned vertices).

The area matrix M and Mullen's B live on the boundary only, so every interior row of
``(k L / 2 - M) z = lambda B z`` reads ``L_II z_I + L_IK z_K = 0``: the interior is the
discrete harmonic extension of the kept values, *whatever k and lambda*. Eliminating it
leaves the dense Schur complement ``S = L_KK - L_KI L_II^{-1} L_IK`` and

* SCP:  ``(k S / 2 - M_KK) z_K = lambda z_K``,
* DNCP: the same operator with two entries of z_K pinned,
* k_opt directly: ``M_KK z = mu (S / 2) z``, the largest real mu.

S costs one real factorisation of L_II and one solve per kept vertex; after that each k
costs one dense eigen-solve of the size of the boundary, and the turning numbers need
only z_K. This is the back end of the k searches with B = boundary indicator.

Up to :data:`TRAILING_SCHUR_MAX` kept vertices, S comes from one factorisation of the
whole matrix with the kept vertices ordered last instead (:class:`_TrailingSchur`):
without pivoting across the two blocks, the trailing block of that LU is S's own LU, so
the K solves (each a pass through every factor) are replaced by one K x K product. The
subspace search's Schur products use that S too while the kept set is short against V
(:data:`TRAILING_PRODUCTS_PER_SEPARATOR`): one matmul each instead of one interior solve per column.
"""

from __future__ import annotations

import warnings

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp
import scipy.sparse.linalg as sla

from parambench.datasets_gen.errors import SolverError

from ..hints import Hint, hinted
from .leading_block import LeadingBlock
from .ordering import submatrix
from .sparse_eigen import SparseFactor
from .threads import single_threaded_blas

__all__ = ["BoundaryReduction", "deflation_basis", "dense_smallest", "dense_real_pencil", "TRAILING_SCHUR_MAX",
           "TRAILING_PRODUCTS_MAX", "TRAILING_PRODUCTS_PER_SEPARATOR"]

#: Kept sets up to this size get S from the trailing block of one LU of the whole matrix.
#: Measured on pymeshlab's bunny cut open (15,448 points, 262 kept): S in 0.16 s after a
#: factorisation of 0.54 s, against 1.66 s of interior solves after one of 0.57 s; S
#: agreed to 7e-16 of its largest entry. SuperLU factors the trailing block as a dense
#: one (K^3 / 3 flops without vendor BLAS), hence the bound.
TRAILING_SCHUR_MAX = 1000

#: Schur *products* (the subspace search's, S never formed otherwise) come from that LU too
#: up to this many kept vertices, and only while K is at most TRAILING_PRODUCTS_PER_SEPARATOR
#: times the size s of the interior ordering's root separator. The factorisation's densest
#: front is s x s; kept last, the boundary makes it (s + K) x (s + K), so K / s is what the
#: extra cost grows with; it buys the subspace path's 70-110 products at one matmul each.
#: Measured, ocp end to end, min of 2-5 runs against interior solves (K / s in brackets):
#: jittered bump / cap / saddle 10k (1.25 / - / -) 1.12 / 1.20 / 1.30 -> 1.03 / 1.02 / 1.24 s,
#: cap 20k (1.08) 3.47 -> 2.44 s, bump / cap 50k 7.95 / 9.49 -> 6.47 / 6.85 s, bump 100k
#: (1.29, K 1176) 13.0 -> 9.9 s, graded bump 20k (1.40) 6.00 -> 4.67 s; jittered holes
#: (four loops) 20k (2.85) 1.63 -> 1.91 s, 50k (2.89, K 1350) 5.1 -> 6.7 s, graded holes 20k
#: (2.47) even. K / sqrt(V) does not separate them (graded bump 4.77 wins, holes 6.0 loses).
#: Between: jittered cylinder 20k (two loops, 1.84) 3.13 -> 2.47 s, random plane 20k (1.63)
#: 2.32 -> 2.13 s; forced past the bound, slit 20k (2.01) 2.05 -> 1.91 s and holes-bumped
#: 20k (2.63) 4.17 -> 4.00 s: about even from 2 on, so the bound stays there.
TRAILING_PRODUCTS_MAX = 1200
TRAILING_PRODUCTS_PER_SEPARATOR = 2.0


class _TrailingSchur:
    """S, and harmonic extensions, from one LU of the whole matrix with the kept vertices last.

    The matrix is singular (zero row sums), so one diagonal entry of the kept block is
    raised by ``shift``: that changes only S (by ``shift`` at that entry, taken off
    again), not the interior rows, and makes the whole matrix solvable. The extension of
    kept values x is then the interior part of the solution of ``A' [u; x] = [0; S' x]``.
    ``None`` from :meth:`build` when SuperLU pivoted a row or column across the blocks.
    """

    def __init__(self, lu, n_interior: int, perm_interior: np.ndarray, s_shifted: np.ndarray, shift: float):
        self._lu = lu
        self._n_interior = n_interior
        self._perm = perm_interior
        self._s_shifted = s_shifted
        self.schur = s_shifted.copy()
        self.schur[-1, -1] -= shift
        self.n_solves = 0

    @classmethod
    def build(cls, lap: sp.csr_matrix, interior: np.ndarray, keep: np.ndarray,
              perm_interior: np.ndarray) -> "_TrailingSchur | None":
        order = np.concatenate([interior[perm_interior], keep])
        a = sp.csc_matrix(submatrix(lap, order, order))
        kept_diagonal = np.abs(a.diagonal()[interior.size:])
        shift = float(kept_diagonal.mean()) if kept_diagonal.size and kept_diagonal.mean() > 0 else 1.0
        a = a + sp.csc_matrix(([shift], ([a.shape[0] - 1], [a.shape[0] - 1])), shape=a.shape)
        try:
            with single_threaded_blas():  # as for SparseFactor: see parambench.methods.spectral.threads
                lu = sla.splu(a, permc_spec="NATURAL", diag_pivot_thresh=0.01,
                              options=dict(SymmetricMode=True, Equil=False))
        except RuntimeError:  # singular: the interior path raises the user-facing SolverError
            return None
        n_i = interior.size
        rows, cols = lu.perm_r[n_i:] - n_i, lu.perm_c[n_i:] - n_i
        if (rows < 0).any() or (cols < 0).any():
            return None
        with single_threaded_blas():
            # dense: the trailing factors are full triangles, and BLAS multiplies them
            # ~10x faster than a sparse product (368 kept: 3 ms against 30 ms)
            product = lu.L[n_i:, n_i:].toarray() @ lu.U[n_i:, n_i:].toarray()
        return cls(lu, n_i, perm_interior, product[np.ix_(rows, cols)], shift)

    def extension(self, x: np.ndarray) -> np.ndarray:
        """``-L_II^{-1} L_IK x`` for kept values ``x`` (K, m), in the interior list's order."""
        rhs = np.zeros((self._n_interior + x.shape[0], x.shape[1]))
        rhs[self._n_interior:] = self._s_shifted @ x
        self.n_solves += x.shape[1]
        with single_threaded_blas():
            sol = self._lu.solve(rhs)
        out = np.empty((self._n_interior, x.shape[1]))
        out[self._perm] = sol[:self._n_interior]
        return out


class BoundaryReduction:
    """Schur complement of a Laplacian onto a kept vertex set.

    Parameters
    ----------
    laplacian : (V, V) scipy.sparse matrix of float64
        L = D - W, possibly non-symmetric.
    keep : (K,) numpy.ndarray of int64
        Kept vertices (boundary loops concatenated, then pins), distinct.
    perm_interior : (V - K,) numpy.ndarray of int64, optional
        Elimination order for L_II (indices into the interior list).
    interior_solver : callable, optional
        ``interior_solver(l_ii, interior)`` returns the object that solves with L_II
        (``solve(rhs)``, ``n_solves``, ``mixed``, ``arrays_per_column``, optionally
        ``iterative``), e.g. a
        :class:`~parambench.methods.spectral.twogrid.TwoGridSolver`; a
        :class:`~parambench.methods.spectral.sparse_eigen.SparseFactor` in ``perm_interior``'s
        order when omitted. Where the kept vertices are the last ones (the interior is
        ``0 .. V-K-1``), ``l_ii`` is a
        :class:`~parambench.methods.spectral.leading_block.LeadingBlock` reading L's own
        rows (both take it; its ``tocsr()`` copies it out), else a CSR copy of the block.
    root_separator : int, optional
        Size of the root separator of ``perm_interior``'s nested dissection
        (:func:`~parambench.methods.spectral.ordering.nested_dissection_with_root`): Schur
        products come from the whole matrix's LU only when it is given and the kept set is
        short against it (:data:`TRAILING_PRODUCTS_PER_SEPARATOR`).
    max_block_bytes : int
        Memory bound for the work arrays of one block of right-hand sides. Wider blocks
        solve faster per right-hand side (measured with a single-precision factor at
        300k rows: 0.22 s for one, 0.09 s each in a block of 32), but a mixed-precision solve holds about four double-size
        arrays per column (right-hand side, solution, residual, single-precision
        copies), so its blocks are a quarter as wide (8 columns at 1M points).

    Attributes
    ----------
    keep, interior : numpy.ndarray of int64
    schur : (K, K) numpy.ndarray of float64
        Computed on first access.
    n_solves : int
        Right-hand sides solved so far.
    """

    def __init__(self, laplacian: sp.spmatrix, keep: np.ndarray, perm_interior: np.ndarray | None = None,
                 max_block_bytes: int = 128 * 2**20, interior_solver=None, root_separator: int | None = None) -> None:
        lap = sp.csr_matrix(laplacian)
        n = lap.shape[0]
        self.keep = np.asarray(keep, dtype=np.int64)
        mask = np.ones(n, dtype=bool)
        mask[self.keep] = False
        self.interior = np.flatnonzero(mask)
        self._l_ik = sp.csc_matrix(submatrix(lap, self.interior, self.keep))
        self._l_ki = submatrix(lap, self.keep, self.interior)
        self._l_kk = submatrix(lap, self.keep, self.keep)
        self._max_block_bytes = int(max_block_bytes)
        self._schur: np.ndarray | None = None
        self._trailing: _TrailingSchur | None = None
        self._lap, self._perm_interior = lap, perm_interior
        # S from the whole matrix's LU is tried when S, or (for a small enough kept set
        # against V) a first Schur product, is asked for; otherwise the interior
        # factorisation is made when a solve with L_II is first needed, so the dense
        # path (S, then one extension) never makes it and a subspace path with a long
        # boundary never pays for the dense trailing block.
        viable = bool(self.interior.size and interior_solver is None and perm_interior is not None)
        self._try_trailing = viable and self.keep.size <= TRAILING_SCHUR_MAX
        self._trailing_products = viable and root_separator is not None and self.keep.size <= min(
            TRAILING_PRODUCTS_MAX, TRAILING_PRODUCTS_PER_SEPARATOR * root_separator)
        self._factor = None
        if self.interior.size and interior_solver is not None:
            self._factor = interior_solver(self._interior_block(), self.interior)

    def _interior_block(self) -> sp.csr_matrix | LeadingBlock:
        """L_II: L's own leading rows where the interior comes first (no copy: 315 MiB at 1M points), else a copy."""
        n_i = self.interior.size
        if self.interior[-1] == n_i - 1:  # sorted and distinct, so exactly 0 .. n_i - 1
            return LeadingBlock(self._lap, n_i)
        return submatrix(self._lap, self.interior, self.interior)

    @property
    def boundary_block(self) -> sp.csr_matrix:
        """(K, K) scipy.sparse.csr_matrix of float64: L_KK."""
        return self._l_kk

    @property
    def interior_factor(self):
        """What solves with L_II (a SparseFactor unless ``interior_solver`` was given), or None without interior.

        A SparseFactor is made on first access.
        """
        if self._factor is None and self.interior.size:
            with single_threaded_blas():
                self._factor = SparseFactor(submatrix(self._lap, self.interior, self.interior), self._perm_interior)
        return self._factor

    @property
    def n_solves(self) -> int:
        """Right-hand sides solved with the interior factorisation (or the whole matrix's) so far."""
        own = 0 if self._factor is None else self._factor.n_solves
        return own + (0 if self._trailing is None else self._trailing.n_solves)

    @property
    def schur(self) -> np.ndarray:
        """(K, K) numpy.ndarray of float64: the dense S (from the whole matrix's LU, or on first use by one solve per kept vertex)."""
        self._ensure_trailing()
        if self._schur is None:
            self._schur = self.apply_schur(np.eye(self.keep.size))
        return self._schur

    def _ensure_trailing(self, for_products: bool = False) -> None:
        """Try S from the whole matrix's LU once, for S itself or for Schur products.

        See :data:`TRAILING_SCHUR_MAX` and :data:`TRAILING_PRODUCTS_MAX` for when.
        """
        if self._trailing_products if for_products else self._try_trailing:
            self._try_trailing = self._trailing_products = False
            self._trailing = _TrailingSchur.build(self._lap, self.interior, self.keep, np.asarray(self._perm_interior))
            if self._trailing is not None:
                self._schur = self._trailing.schur

    @property
    def solves_are_iterative(self) -> bool:
        """Whether each interior solve costs cycles of an iterative solver (then callers keep solutions)."""
        return bool(getattr(self._factor, "iterative", False))

    @property
    def solve_rtol(self) -> float:
        """Relative residual the interior solves stop at (0.0 for a factorisation, exact to rounding).

        Also 0.0 once an iterative solver has fallen back to a factorisation
        (``fell_back``): its solves are exact from then on.
        """
        if not self.solves_are_iterative or getattr(self._factor, "fell_back", False):
            return 0.0
        return float(getattr(self._factor, "rtol", 0.0))

    def apply_schur(self, x: np.ndarray) -> np.ndarray:
        """``S x = L_KK x - L_KI L_II^{-1} L_IK x`` without forming S.

        Parameters
        ----------
        x : (K, m) numpy.ndarray of float64

        Returns
        -------
        (K, m) numpy.ndarray of float64
            A matmul with S where S comes from the whole matrix's LU (see
            :data:`TRAILING_PRODUCTS_MAX`); otherwise m solves with the interior
            factorisation, in blocks bounded by ``max_block_bytes``.
        """
        return self._schur_product(x, None)

    def apply_schur_extended(self, x: np.ndarray, guess: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """``S x`` and the interior values of the harmonic extensions of x's columns.

        Parameters
        ----------
        x : (K, m) numpy.ndarray of float64
        guess : (V - K, m) numpy.ndarray of float64, optional
            Interior values from an earlier, looser solve for the same x: an iterative
            interior solver starts from them (a factorisation ignores them). Overwritten
            with the new interior values, which are also returned.

        Returns
        -------
        sx : (K, m) numpy.ndarray of float64
        interior : (V - K, m) numpy.ndarray of float64
            ``-L_II^{-1} L_IK x``: with them, :meth:`extend` of any combination of x's
            columns costs no further solve.
        """
        x = np.asarray(x, dtype=np.float64)
        if guess is None:
            interior = np.zeros((self.interior.size, x.shape[1]))
        else:
            interior = guess
            if interior.shape != (self.interior.size, x.shape[1]):
                raise ValueError(f"guess must have shape {(self.interior.size, x.shape[1])}, got {interior.shape}.")
        return self._schur_product(x, interior, warm=guess is not None), interior

    def tighten(self, rtol: float) -> bool:
        """Make later iterative interior solves stop at the smaller relative residual ``rtol``.

        Returns
        -------
        bool
            Whether anything changed (False for a factorisation, exact to rounding, and
            when the solver's tolerance is already at most ``rtol``).
        """
        if self.solve_rtol == 0.0 or self.solve_rtol <= rtol:
            return False
        self._factor.rtol = float(rtol)
        return True

    def _schur_product(self, x: np.ndarray, interior: np.ndarray | None, warm: bool = False) -> np.ndarray:
        x = np.asarray(x, dtype=np.float64)
        if self._factor is None:  # before the first solve: S from one LU may be cheaper
            self._ensure_trailing(for_products=True)
        if self._trailing is not None:
            if interior is not None:
                interior[:] = self._trailing.extension(x)
            return self._schur @ x
        out = np.asarray(self._l_kk @ x, dtype=np.float64)
        if self.interior_factor is None:
            return out
        arrays_per_column = self._factor.arrays_per_column
        # An iterative solver may ask for larger blocks (each block costs it a full solve).
        budget = max(self._max_block_bytes, int(getattr(self._factor, "max_block_bytes", 0)))
        block = max(8, int(budget // (8 * arrays_per_column * self.interior.size)))
        # Blocks of equal width: the widest sets the memory (at 1M points, 41 columns in
        # blocks of 26 and 15 took 120 MB more than in 21 and 20, for the same cycles).
        n_blocks = -(-x.shape[1] // block)
        block = max(1, -(-x.shape[1] // max(n_blocks, 1)))
        with single_threaded_blas():  # see parambench.methods.spectral.threads
            for start in range(0, x.shape[1], block):
                cols = slice(start, min(start + block, x.shape[1]))
                rhs = np.ascontiguousarray(self._l_ik @ x[:, cols])
                # No block-sized temporary beyond the solver's own arrays
                # (``arrays_per_column``): an iterative solve returns its solution in
                # rhs, the warm start is the kept values negated in place (they are
                # overwritten below, and a start only changes the cycles' count).
                if self.solves_are_iterative:
                    guess = None
                    if warm and interior is not None:
                        guess = interior[:, cols]
                        np.negative(guess, out=guess)
                    sol = self._factor.solve(rhs, guess=guess, overwrite_rhs=True)
                else:
                    sol = self._factor.solve(rhs)
                del rhs
                out[:, cols] -= self._l_ki @ sol
                if interior is not None:
                    np.negative(sol, out=interior[:, cols])
        return out

    def extend(self, z_keep: np.ndarray, interior: np.ndarray | None = None) -> np.ndarray:
        """Harmonic extension of kept values to all vertices.

        Parameters
        ----------
        z_keep : (K,) numpy.ndarray of complex128
        interior : (V - K,) numpy.ndarray of complex128, optional
            The extension's interior values when the caller already has them (a
            combination of :meth:`apply_schur_extended`'s); no solve then.

        Returns
        -------
        (V,) numpy.ndarray of complex128
        """
        n = self.keep.size + self.interior.size
        z = np.empty(n, dtype=np.complex128)
        z[self.keep] = z_keep
        if interior is not None:
            z[self.interior] = interior
        elif self._trailing is not None:
            x = self._trailing.extension(np.column_stack([z_keep.real, z_keep.imag]))
            z[self.interior] = x[:, 0] + 1j * x[:, 1]
        elif self.interior_factor is not None:
            rhs = -(self._l_ik @ np.column_stack([z_keep.real, z_keep.imag]))
            with single_threaded_blas():
                x = self._factor.solve(rhs)
            z[self.interior] = x[:, 0] + 1j * x[:, 1]
        return z


def deflation_basis(n: int) -> np.ndarray:
    """Orthonormal basis of the vectors with zero sum (the complement of translations).

    Returns
    -------
    (n, n - 1) numpy.ndarray of float64
        Columns 2..n of the Householder reflector that maps ``1 / sqrt(n)`` to e_1.
    """
    u0 = np.full(n, 1.0 / np.sqrt(n))
    v = u0.copy()
    v[0] -= 1.0
    v /= np.linalg.norm(v)
    h = np.eye(n) - 2.0 * np.outer(v, v)
    return h[:, 1:]


def dense_smallest(operator: np.ndarray, *, hermitian: bool, count: int = 3,
                   vectors: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Eigenpairs of a dense operator with zero row sums, translations deflated.

    Parameters
    ----------
    operator : (K, K) numpy.ndarray of complex128
        ``k S / 2 - M_KK`` (B = identity on the kept, all-boundary, set).
    hermitian : bool
    count : int
        How many of the smallest (by real part) to return.
    vectors : int, optional
        How many of their eigenvectors (the first ones; default all ``count``): each
        costs a dense LU where ``operator`` is not Hermitian.

    Returns
    -------
    values : (count,) numpy.ndarray of complex128, increasing real part
    vectors : (K, vectors) numpy.ndarray of complex128, zero-mean unit columns
    """
    with single_threaded_blas():
        return _dense_smallest(operator, hermitian, count, count if vectors is None else vectors)


def _dense_smallest(operator: np.ndarray, hermitian: bool, count: int,
                    n_vectors: int) -> tuple[np.ndarray, np.ndarray]:
    q = deflation_basis(operator.shape[0])
    reduced = q.T @ operator @ q
    count = min(count, reduced.shape[0])
    n_vectors = min(n_vectors, count)
    if hermitian:
        reduced = 0.5 * (reduced + reduced.conj().T)
        vals, vecs = la.eigh(reduced, subset_by_index=[0, count - 1])
        vals, vecs = vals.astype(np.complex128), vecs[:, :n_vectors]
    else:
        # Eigenvalues only (about 3x cheaper than with vectors), then each wanted vector by
        # inverse iteration with one LU at a shift just off the eigenvalue.
        vals = la.eigvals(reduced)
        vals = vals[np.argsort(vals.real)[:count]]
        eye = np.eye(reduced.shape[0])
        vecs = np.empty((reduced.shape[0], n_vectors), dtype=np.complex128)
        for c, lam in enumerate(vals[:n_vectors]):
            shift = lam + 1e-10 * max(abs(lam), np.abs(reduced).max())
            lu = la.lu_factor(reduced - shift * eye, check_finite=False)
            v = np.ones(reduced.shape[0], dtype=np.complex128)
            for _ in range(3):
                v = la.lu_solve(lu, v, check_finite=False)
                v /= np.linalg.norm(v)
            vecs[:, c] = v
    vectors = q @ vecs
    return vals, vectors / np.linalg.norm(vectors, axis=0)


def pencil_k_estimates(s_half: np.ndarray, m: np.ndarray, imag_tol: float = 1e-2) -> np.ndarray:
    """The k at which ``k S / 2 - M`` has a zero eigenvalue, largest first: start points of a k search.

    ``(k S / 2 - M) y = 0`` is the pencil ``M y = mu (S / 2) y``; the smallest eigenvalue's
    real part crosses zero at its largest (near-)real positive mu, exactly for symmetric L
    and to about 6 digits otherwise (as for ``k_search="direct"``). Eigenvalues only, of
    one standard m x m problem: about the cost of one evaluation of the search.

    Parameters
    ----------
    s_half : (m, m) numpy.ndarray of float64
        ``S / 2`` on a basis without translations (zero-sum columns), where it is
        definite for the Laplacians here.
    m : (m, m) numpy.ndarray of complex128
        The area matrix on the same basis.
    imag_tol : float
        Largest ``|Im mu| / |mu|`` of a candidate.

    Returns
    -------
    (c,) numpy.ndarray of float64
        Real parts of the candidates, decreasing, all > 0; empty when ``s_half`` is singular.
    """
    with single_threaded_blas(), warnings.catch_warnings():
        warnings.simplefilter("error", la.LinAlgWarning)
        try:
            vals = la.eigvals(la.solve(s_half, m, check_finite=False), check_finite=False)
        except la.LinAlgWarning:
            # S/2 numerically singular (rcond ~1e-18 on a range scan's kNN graph, where a
            # part hangs on by a few weak weights): the QZ form needs no inverse, and its
            # infinite eigenvalues are dropped below instead of polluting the finite ones.
            try:
                vals = la.eigvals(m, s_half, check_finite=False)
            except (la.LinAlgError, ValueError):
                return np.empty(0)
        except (la.LinAlgError, ValueError):
            return np.empty(0)
    ok = np.isfinite(vals) & (vals.real > 0) & (np.abs(vals.imag) <= imag_tol * np.abs(vals))
    return np.sort(vals.real[ok])[::-1]


def dense_real_pencil(a: np.ndarray, b: np.ndarray, *, hermitian: bool, imag_tol: float = 1e-8
                      ) -> tuple[np.ndarray, np.ndarray]:
    """Real positive eigenvalues mu of ``a z = mu b z`` on zero-sum vectors, largest first.

    Parameters
    ----------
    a : (K, K) numpy.ndarray of complex128
        The area matrix M_KK.
    b : (K, K) numpy.ndarray of float64
        ``S / 2``, positive definite on zero-sum vectors when L is symmetric.
    hermitian : bool
    imag_tol : float
        Eigenvalues with ``|Im mu| > imag_tol * |mu|`` do not count as real.

    Returns
    -------
    mus : (m,) numpy.ndarray of float64, decreasing, all > 0
        Real parts of the (near-)real eigenvalues.
    vectors : (K, m) numpy.ndarray of complex128, zero-mean unit columns

    Raises
    ------
    SolverError
        No finite real positive eigenvalue, or b is not definite (Hermitian case).
    """
    with single_threaded_blas():
        return _dense_real_pencil(a, b, hermitian, imag_tol)


def _dense_real_pencil(a: np.ndarray, b: np.ndarray, hermitian: bool, imag_tol: float
                       ) -> tuple[np.ndarray, np.ndarray]:
    q = deflation_basis(a.shape[0])
    ar, br = q.T @ a @ q, q.T @ b @ q
    if hermitian:
        try:
            vals, vecs = la.eigh(0.5 * (ar + ar.conj().T), 0.5 * (br + br.T))
        except la.LinAlgError:
            raise hinted(SolverError, "the reduced Dirichlet matrix is not positive definite (negative total "
                         "weights?); k_opt cannot be computed directly", Hint("use k_search='line'", "k_search", "line")) from None
        vals = vals.astype(np.complex128)
    else:
        vals, vecs = la.eig(ar, br)
    finite = np.isfinite(vals)
    real = finite & (np.abs(vals.imag) <= imag_tol * np.maximum(np.abs(vals), np.finfo(float).tiny))
    cand = np.flatnonzero(real & (vals.real > 0))
    if cand.size == 0:
        raise hinted(SolverError, "no real k > 0 makes the conformal energy vanish (the area/Dirichlet pencil has "
                     "no real positive eigenvalue)", Hint("use k_search='line'", "k_search", "line"),
                     Hint("check that the outer loop runs counter-clockwise as seen from the normals"))
    cand = cand[np.argsort(-vals.real[cand])]
    z = q @ vecs[:, cand]
    return vals.real[cand], z / np.linalg.norm(z, axis=0)
