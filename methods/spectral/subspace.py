"""The k search of SCP on a small subspace of boundary functions (Rayleigh-Ritz).

With B supported on the boundary, every eigenvector of ``(k L / 2 - M) z = lambda B z``
is the harmonic extension of its boundary values z_K, which solve the boundary problem
``(k S / 2 - M_KK) z_K = lambda z_K`` (:mod:`.reduction`). Forming S costs one solve per
boundary vertex and each k a dense eigen-solve of the boundary size: at 100k points
(about 1,200 boundary points) that was about 2 minutes for a search. The map at k_opt is smooth
along each loop, so its boundary values are well represented by a few dozen functions:

* per loop, the constant and the Fourier modes ``cos(2 pi j s / l)``, ``sin(...)`` of the
  normalised arc length s, j = 1..J with J proportional to the loop's length;
* the 3D coordinates of the boundary points (they carry the corners of a square, whose
  Fourier series converges slowly).

Projected on this basis Q (orthonormal, zero-sum columns), ``Q^T S Q`` costs one solve
per column and every k of the search an m x m eigen-problem (m ~ 70). The search gives
k_opt. At k_opt the Ritz vector is then refined to the eigenvector of the full boundary
problem by Davidson steps (:meth:`BoundarySubspace.refine`: the subspace grows by the
residual preconditioned with the sparse boundary block ``k L_KK / 2 - M_KK``, two
interior solves per step), so the subspace decides the k but not the map. Measured at
20k points: the boundary values agree with the exact eigenvector to 4e-6 (cap) and
3e-5 (saddle) relative after 6-8 steps, and k_opt with the dense search to 1e-7-9e-5.
A single search can miss by far more where the map near k_opt is not smooth along the
boundary (measured: 1.4e-3 on a jittered cylinder and 5.6e-2 on a random-sampled bump
at 20k points, 0.18 at 5k), so :class:`~parambench.methods.spectral.problem.ConformalProblem`
keeps the refinement's directions (``refine(absorb=True)``) and searches again on the
grown subspace until k_opt settles (to 2e-6 and 2e-5 of the dense search on those two).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp
import scipy.sparse.linalg as sla

from parambench.datasets_gen.errors import SolverError

from ..hints import Hint, hinted
from .ksearch import KPoint
from .reduction import BoundaryReduction, pencil_k_estimates
from .threads import single_threaded_blas
from .turning import loop_turning_numbers

__all__ = ["BoundarySubspace", "boundary_basis", "loop_arc_fraction", "DEFAULT_MODES"]

#: Fourier modes (cos and sin pairs) shared out among the loops by length.
DEFAULT_MODES = 32
#: Fourier modes every loop gets at least; with more than :data:`MANY_LOOPS` loops the
#: holes get at least :data:`MANY_LOOPS_MIN_MODES` instead. The basis grows by 9
#: functions per loop at 4 modes, and each Ritz step is a dense eigen-solve of its
#: size: ``ocp`` on a bump with 36 / 64 small holes (10k points) took 12 / 27 s against
#: 2.3 s with 4 holes. At one mode per hole: 4.2 / 5.1 s, the same refined map; on a
#: plane with 36 and 100 holes 9.5 -> 2.5 s and 97 -> 11 s, uv within 4e-8 of the
#: diameter of the map at 4 modes.
MIN_MODES = 4
MANY_LOOPS = 8
MANY_LOOPS_MIN_MODES = 1


def loop_arc_fraction(points: np.ndarray | None, loop: np.ndarray) -> np.ndarray:
    """Normalised arc length in [0, 1) at each vertex of a closed loop.

    Parameters
    ----------
    points : (V, 3) numpy.ndarray of float64, or None
        None: the vertices are taken as evenly spaced.
    loop : (L,) numpy.ndarray of int64
        Vertex indices in order; the loop closes from the last back to the first.

    Returns
    -------
    (L,) numpy.ndarray of float64
        0 at ``loop[0]``, increasing.
    """
    if points is None:
        return np.arange(loop.size) / loop.size
    seg = np.linalg.norm(points[np.roll(loop, -1)] - points[loop], axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)[:-1]])
    return s / seg.sum()


def boundary_basis(loops: Sequence[np.ndarray], points: np.ndarray | None = None, n_modes: int = DEFAULT_MODES,
                   extra: np.ndarray | None = None) -> np.ndarray:
    """Orthonormal zero-sum basis of smooth functions on the concatenated boundary loops.

    Parameters
    ----------
    loops : sequence of (L_i,) numpy.ndarray of int64
        Boundary loops (vertex indices); the basis rows follow their concatenation.
    points : (V, 3) numpy.ndarray of float64, optional
        Vertex positions: arc length along the loops and the coordinate functions. Without
        them the loops are parameterised by index.
    n_modes : int
        Fourier frequencies in total, shared among the loops in proportion to their
        number of vertices (at least :data:`MIN_MODES` per loop, or
        :data:`MANY_LOOPS_MIN_MODES` per hole beyond :data:`MANY_LOOPS` loops; at most a
        third of its vertices).
    extra : (K, e) numpy.ndarray of float64, optional
        Further functions on the boundary, e.g. the real and imaginary parts of a coarse
        level's map (:mod:`.multilevel`).

    Returns
    -------
    (K, m) numpy.ndarray of float64
        Orthonormal columns, each summing to zero (translations removed), K the number
        of boundary vertices.
    """
    sizes = np.array([loop.size for loop in loops])
    total = int(sizes.sum())
    offsets = np.concatenate([[0], np.cumsum(sizes)])
    cols = []
    hole_min = MANY_LOOPS_MIN_MODES if len(loops) > MANY_LOOPS else MIN_MODES
    for i, loop in enumerate(loops):
        s = loop_arc_fraction(points, loop)
        n_j = int(np.clip(round(n_modes * loop.size / total), hole_min if i else MIN_MODES, max(1, loop.size // 3)))
        block = np.zeros((total, 2 * n_j + 1))
        rows = slice(offsets[i], offsets[i + 1])
        block[rows, 0] = 1.0
        ang = 2.0 * np.pi * np.outer(s, np.arange(1, n_j + 1))
        block[rows, 1::2] = np.cos(ang)
        block[rows, 2::2] = np.sin(ang)
        cols.append(block)
    if points is not None:
        cols.append(points[np.concatenate(loops)])
    if extra is not None:
        cols.append(np.asarray(extra, dtype=np.float64).reshape(total, -1))
    q = np.hstack(cols)
    q -= q.mean(axis=0)
    # Rank-revealing orthonormalisation: drop the columns the others already span
    # (a single loop's constant, a planar boundary's normal coordinate).
    with single_threaded_blas():  # two busy BLAS threads made this 368 x 70 SVD take ~1 s
        u, sv, _ = la.svd(q, full_matrices=False)
    return u[:, sv > 1e-10 * sv[0]]


def _combine(blocks: Sequence[np.ndarray], y: np.ndarray) -> np.ndarray:
    """``np.hstack(blocks) @ y`` without forming the concatenation."""
    out, start = None, 0
    for block in blocks:
        part = block @ y[start:start + block.shape[1]]
        out = part if out is None else out + part
        start += block.shape[1]
    return out


#: A Davidson step whose residual is more than this multiple of the best before it took a
#: swapped Ritz pair (a non-normal operator; the residual falls again after it).
SWAP_FACTOR = 2.0


def _stalled(rels: Sequence[float], bests: Sequence[float], stall: float, window: int) -> bool:
    """Whether the Davidson residuals stopped falling.

    ``rels`` holds each step's residual, ``bests`` the smallest so far after each step.
    With ``window`` > 1: the last ``window`` steps brought the best residual down by less
    than the factor ``stall``. With ``window`` = 1 (the two-level path's rule): the last
    step gained less than ``stall`` over the one before, unless it more than doubled the
    best residual before it (a swapped Ritz pair, after which the residual falls again).
    A window rule judges the steps since the last such swap on their own as well: a swap
    right after a good start left the start the best for the whole window (protrusions at
    1M points, direct path: 2.1e-6, 4.3e-5, 3.7e-6, 3.5e-6, 1.9e-6 stopped there, the map
    2.3e-3 of its diameter off the exact one at that k), so only when both the best so
    far and the newest branch's best stopped falling is it a stall.
    """
    if window > 1:
        if not (len(bests) > window and bests[-1] > stall * bests[-1 - window]):
            return False
        start = _last_swap(rels)
        if start == 0:
            return True
        branch = np.minimum.accumulate(rels[start:])
        return branch.size > window and branch[-1] > stall * branch[-1 - window]
    return len(rels) > 1 and rels[-1] > stall * rels[-2] and not rels[-1] > SWAP_FACTOR * bests[-2]


def _last_swap(rels: Sequence[float]) -> int:
    """Index of the last step whose residual more than doubled the best before it (0 if none)."""
    r = np.asarray(rels, dtype=float)
    if r.size < 2:
        return 0
    jumps = np.flatnonzero(r[1:] > SWAP_FACTOR * np.minimum.accumulate(r)[:-1]) + 1
    return int(jumps[-1]) if jumps.size else 0


def _ritz_gap(op: np.ndarray, lam: complex) -> float:
    """Distance from ``lam`` to the nearest other eigenvalue of the small dense ``op``.

    An eigenvector's error is bounded by its residual over this gap (to first order), so
    the residual a refinement must reach for a given map accuracy scales with it.
    """
    with single_threaded_blas():
        vals = la.eigvals(op, check_finite=False)
    dist = np.sort(np.abs(vals - lam))
    return float(dist[1]) if dist.size > 1 else np.inf


def _inverse_iteration(op: np.ndarray, lam: complex, steps: int = 3, rtol: float = 1e-10) -> np.ndarray | None:
    """Unit eigenvector of the small dense ``op`` for its eigenvalue ``lam``, or None if it does not converge."""
    m = op.shape[0]
    scale = max(float(np.abs(op).max()), np.finfo(float).tiny)
    # A shift just off lam keeps the factorisation regular; the iteration converges at once.
    lu = la.lu_factor(op - (lam + 1e-12 * scale) * np.eye(m), check_finite=False)
    x = np.ones(m, dtype=np.complex128) + 1j * np.linspace(0.0, 1.0, m)
    for _ in range(steps):
        x = la.lu_solve(lu, x, check_finite=False)
        x /= np.linalg.norm(x)
        if np.linalg.norm(op @ x - lam * x) <= rtol * scale:
            return x
    return None


class BoundarySubspace:
    """Rayleigh-Ritz evaluations of SCP's smallest eigenpair on a boundary subspace.

    Parameters
    ----------
    reduction : BoundaryReduction
        Holds the interior factorisation; its kept set must be the boundary loops
        concatenated (no pins).
    area : (V, V) scipy.sparse matrix of complex128
        The area matrix M.
    loops : sequence of (L_i,) numpy.ndarray of int64
    points : (V, 3) numpy.ndarray of float64, optional
    n_modes : int
        See :func:`boundary_basis`.
    extra : (K, e) numpy.ndarray of float64, optional
        Further basis functions, see :func:`boundary_basis`.

    Attributes
    ----------
    basis : (K, m) numpy.ndarray of float64
    n_solves : int
        Interior solves spent on ``S Q``.
    """

    #: Boundary residuals of :meth:`refine` floor at about this multiple of the interior
    #: solves' relative residual (measured with two-grid solves at rtol 1e-8, 1M points:
    #: 1.2e-7 to 2.1e-7; a step from there left it at 2.06e-7 (0.03 % less) or made it
    #: worse, 1.2e-7 -> 5.1e-6); refine stops there instead of paying a solve to find out.
    SOLVE_FLOOR = 50.0

    #: Largest relative distance of boundary values from the basis's span for which
    #: :meth:`extend` combines the kept interior values.
    SPAN_RTOL = 1e-10

    def __init__(self, reduction: BoundaryReduction, area: sp.spmatrix, loops: Sequence[np.ndarray],
                 points: np.ndarray | None = None, n_modes: int = DEFAULT_MODES,
                 extra: np.ndarray | None = None) -> None:
        self.basis = boundary_basis(loops, points, n_modes, extra)
        self._reduction = reduction
        before = reduction.n_solves
        # With an iterative interior solver every solve costs cycles: the interior values
        # the Schur products compute anyway are kept, so the final map's harmonic
        # extension is a combination of them (:meth:`extend`), not two more solves.
        self._interior: list[np.ndarray] | None = None  # column blocks, never concatenated (see refine)
        if reduction.solves_are_iterative:
            self._sq, interior = reduction.apply_schur_extended(self.basis)
            self._interior = [interior]
        else:
            self._sq = reduction.apply_schur(self.basis)
        self.n_solves = reduction.n_solves - before
        keep = reduction.keep
        self._m_kk = sp.csr_matrix(area)[keep][:, keep]
        self._s = self.basis.T @ self._sq
        self._m = self.basis.T @ np.asarray(self._m_kk @ self.basis)
        self.hermitian = bool(np.allclose(self._s, self._s.T, rtol=0, atol=1e-12 * np.abs(self._s).max()))
        pos = np.full(area.shape[0], -1, dtype=np.int64)
        pos[keep] = np.arange(keep.size)
        self._local_loops = [pos[loop] for loop in loops]

    def _ritz(self, k: float, s_proj: np.ndarray, m_proj: np.ndarray) -> tuple[complex, np.ndarray]:
        op = (0.5 * k) * s_proj - m_proj
        with single_threaded_blas():
            if self.hermitian:
                vals, vecs = la.eigh(0.5 * (op + op.conj().T), subset_by_index=[0, 0])
                return complex(vals[0]), vecs[:, 0].astype(np.complex128)
            # Eigenvalues alone cost about half of eig() and the search calls this ~80 times
            # per solve; the one eigenvector wanted then comes from inverse iteration.
            vals = la.eigvals(op, check_finite=False)
            lam = complex(vals[int(np.argmin(vals.real))])
            vec = _inverse_iteration(op, lam)
            if vec is None:  # a (near-)multiple eigenvalue: let LAPACK sort it out
                vals, vecs = la.eig(op, check_finite=False)
                i = int(np.argmin(vals.real))
                return complex(vals[i]), vecs[:, i]
        return lam, vec

    def k_estimates(self, imag_tol: float = 1e-2) -> np.ndarray:
        """The k at which the Ritz problem has a zero eigenvalue, largest first: start points of a k search.

        :func:`~parambench.methods.spectral.reduction.pencil_k_estimates` of
        ``((k / 2) Q^T S Q - Q^T M_KK Q) y = 0``; Q^T S Q is definite on the zero-sum basis
        (no translations) for the Laplacians here.

        Parameters
        ----------
        imag_tol : float
            Largest ``|Im mu| / |mu|`` of a candidate.

        Returns
        -------
        (c,) numpy.ndarray of float64
            Real parts of the candidates, decreasing, all > 0; empty when S's projection
            is singular.
        """
        return pencil_k_estimates(0.5 * self._s, self._m, imag_tol)

    @property
    def size(self) -> int:
        """Dimension m of the subspace."""
        return int(self.basis.shape[1])

    def evaluate(self, k: float) -> KPoint:
        """Ritz approximation of the smallest eigenpair at k.

        Returns
        -------
        KPoint
            ``energy`` the Ritz value's real part, ``turning`` of the boundary values
            ``Q y``, ``state`` = (boundary values, Ritz value).
        """
        lam, y = self._ritz(k, self._s, self._m)
        z_k = self.basis @ y
        turning = loop_turning_numbers(z_k, self._local_loops)
        return KPoint(k=float(k), energy=float(lam.real), turning=turning, state=(z_k, lam))

    def refine(self, k: float, *, max_steps: int = 40, rtol: float = 1e-9, stall: float = 0.7, window: int = 4,
               absorb: bool = False, precondition=None) -> tuple[KPoint, dict]:
        """The smallest eigenpair of the full boundary problem at k, by Davidson steps.

        Each step adds the real and imaginary parts of the residual
        ``r = (k S / 2 - M_KK) z - lambda z``, preconditioned by the sparse
        ``k L_KK / 2 - M_KK - lambda I``, to the basis (two interior solves) and takes
        the new Ritz pair. The basis grows locally; the search basis is not changed.

        Parameters
        ----------
        k : float
        max_steps : int
        rtol : float
            Stop when ``|P r| / (|k L_KK / 2|_max |z|)`` is below this (P removes the
            translation component, which the zero-sum basis cannot represent), or below
            :attr:`SOLVE_FLOOR` times the interior solves' tolerance when they are iterative.
        stall, window : float, int
            Also stop when ``window`` steps bring the smallest residual so far down by less
            than the factor ``stall`` (it floors at the accuracy of the interior solves);
            ``window=1`` is the one-step rule of the two-level path (:func:`_stalled`).
            Progress is judged over several steps, not one: on small spectral gaps the
            residual falls slowly and unevenly (a jittered cylinder at 300k points: 0.6-0.9x
            per step, with rises; the old one-step rule stopped at 4e-7 with k_opt 7e-4 and
            the map 2.4e-3 of its diameter off the exact ones, now 1e-9, 2e-8 and 4e-6).
        absorb : bool
            Keep the grown basis as the subspace of later :meth:`evaluate` calls (a
            second k search then sees the directions the refinement found).
        precondition : callable, optional
            ``precondition(k, lam, r, z)`` gives further complex directions (K,) from the
            residual r of the Ritz vector z, added each step with their real and
            imaginary parts (the two-level path's coarse operator:
            :func:`~parambench.methods.spectral.multilevel.coarse_scp_preconditioner`).

        Returns
        -------
        point : KPoint
            ``state`` = (boundary values (K,) complex128, Ritz value).
        info : dict
            ``refine_steps``, ``boundary_residual`` (the relative residual reached),
            ``ritz_gap`` (distance from the returned Ritz value to the next one on the
            final basis, relative like the residual) and ``map_error_estimate`` (their
            ratio: a first-order bound on the map's error, pessimistic by 60-130x on the
            maps measured at a million points).

        Raises
        ------
        SolverError
            The preconditioner is singular.
        """
        red = self._reduction
        rtol = max(float(rtol), self.SOLVE_FLOOR * red.solve_rtol)
        basis, sq = self.basis, self._sq
        # The interior values grow by blocks: concatenating them at each step copied the
        # whole (V, m) array (at 1M points with 41 columns, 330 MB twice over at the peak).
        interior = None if self._interior is None else list(self._interior)
        l_kk = red.boundary_block
        scale = 0.5 * abs(k) * float(np.abs(l_kk.diagonal()).max())
        steps, rel = 0, np.inf
        best, bests, rels = None, [], []
        while True:
            lam, y = self._ritz(k, basis.T @ sq, basis.T @ np.asarray(self._m_kk @ basis))
            z = basis @ y
            r = (0.5 * k) * (sq @ y) - self._m_kk @ z - lam * z
            rel = float(np.linalg.norm(r - r.mean()) / (scale * np.linalg.norm(z)))
            # A step can multiply the residual when the Ritz pair swaps on a non-normal
            # operator, and it falls again after (protrusions at 300k points: 5.0e-7,
            # 2.0e-6, 4.5e-7, ..., 2.2e-8): only the best residual over a window counts.
            if best is None or rel < best[0]:
                best = (rel, lam, z)
            bests.append(best[0])
            rels.append(rel)
            if rel <= rtol or steps >= max_steps or _stalled(rels, bests, stall, window):
                break
            new = self._corrections(k, lam, r, z, precondition)
            new -= new.mean(axis=0)
            for _ in range(2):  # classical Gram-Schmidt, twice is enough
                new -= basis @ (basis.T @ new)
            q, rr = la.qr(new, mode="economic")
            ok = np.abs(np.diag(rr)) > 1e-12 * max(np.abs(rr).max(), np.finfo(float).tiny)
            if not ok.any():
                break
            q = q[:, ok]
            basis = np.hstack([basis, q])
            if interior is None:
                sq = np.hstack([sq, red.apply_schur(q)])
            else:
                sq_q, interior_q = red.apply_schur_extended(q)
                sq = np.hstack([sq, sq_q])
                interior.append(interior_q)
            steps += 1
        if absorb and basis is not self.basis:
            self.basis, self._sq, self._interior = basis, sq, interior
            self._s = basis.T @ sq
            self._m = basis.T @ np.asarray(self._m_kk @ basis)
        # With a non-normal operator a step can make the Ritz pair worse (protrusions at
        # 300k points, direct path: residual 5.0e-7 -> 2.0e-6, the map 6.7e-4 -> 1.8e-3 of
        # its diameter off the exact one): the pair with the smallest residual is returned.
        rel, lam, z = best
        turning = loop_turning_numbers(z, self._local_loops)
        point = KPoint(k=float(k), energy=float(lam.real), turning=turning, state=(z, lam))
        gap = _ritz_gap((0.5 * k) * (basis.T @ sq) - basis.T @ np.asarray(self._m_kk @ basis), lam) / scale
        return point, {"refine_steps": steps, "boundary_residual": rel, "ritz_gap": gap,
                       "map_error_estimate": rel / max(gap, np.finfo(float).tiny)}

    def resolve(self) -> None:
        """Compute the basis's Schur products again, to the interior solver's present tolerance.

        After :meth:`BoundaryReduction.tighten` the products already made keep the old
        solves' error, and a refinement cannot get below it (:attr:`SOLVE_FLOOR`); each
        block of kept interior values is the starting guess of its new solve, so an
        iterative solver only runs the cycles that close the gap between the tolerances.
        Without kept interior values (a factorisation) there is nothing to gain: no-op.
        """
        if self._interior is None:
            return
        parts, start = [], 0
        for block in self._interior:
            cols = slice(start, start + block.shape[1])
            sq_part, _ = self._reduction.apply_schur_extended(self.basis[:, cols], guess=block)
            parts.append(sq_part)
            start = cols.stop
        self._sq = np.hstack(parts)
        self._s = self.basis.T @ self._sq
        self.n_solves += start

    def _corrections(self, k: float, lam: complex, r: np.ndarray, z: np.ndarray, precondition) -> np.ndarray:
        """Davidson's correction of the Ritz pair (lam, z) with residual r, and the caller's, as real columns."""
        l_kk = self._reduction.boundary_block
        eye = sp.identity(l_kk.shape[0], format="csc")
        precond = sp.csc_matrix((0.5 * k) * l_kk - self._m_kk - lam.real * eye)
        try:
            t = sla.spsolve(precond, r)
        except RuntimeError:
            raise hinted(SolverError, "the boundary preconditioner is singular",
                         Hint("use backend='boundary'", "backend", "boundary")) from None
        new = np.column_stack([t.real, t.imag])
        if precondition is not None:
            extra_t = precondition(k, lam, r, z)
            new = np.column_stack([new, extra_t.real, extra_t.imag])
        return new

    def extend(self, z_keep: np.ndarray) -> np.ndarray:
        """Harmonic extension of boundary values to every vertex.

        For values in the basis's span (every map :meth:`evaluate` and :meth:`refine`
        with ``absorb`` return) and kept interior values, a combination of those; an
        interior solve otherwise (:meth:`BoundaryReduction.extend`).

        Parameters
        ----------
        z_keep : (K,) numpy.ndarray of complex128

        Returns
        -------
        (V,) numpy.ndarray of complex128
        """
        if self._interior is not None:
            y = self.basis.T @ z_keep  # the basis is orthonormal
            off = np.linalg.norm(z_keep - self.basis @ y)
            if off <= self.SPAN_RTOL * max(np.linalg.norm(z_keep), np.finfo(float).tiny):
                return self._reduction.extend(z_keep, interior=_combine(self._interior, y))
        return self._reduction.extend(z_keep)
