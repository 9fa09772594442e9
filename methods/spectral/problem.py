"""SCP and DNCP at a given k, k_opt directly, and the k searches, on any Laplacian.

:class:`ConformalProblem` holds a V x V Laplacian L (symmetric or not), the oriented
boundary loops and B, and picks a back end per call:

* ``"sparse"``: one complex sparse factorisation of the full V x V system per k
  (shift-invert eigen-solve for SCP, a linear solve for DNCP). Used for a single k
  (cotangent SCP, the fast path) and whenever B is not supported on the boundary.
* ``"boundary"``: the exact reduction of :mod:`.reduction` (one real factorisation of
  the interior block, one solve per boundary vertex, then a dense boundary-sized problem
  per k). Used for the k searches on small boundaries and ``k_search="direct"``.
* ``"subspace"``: SCP's k search on a few dozen smooth boundary functions
  (:mod:`.subspace`: one solve per function, then an m x m problem per k); at k_opt
  the boundary eigenvector is refined to full accuracy (Davidson steps) and extended
  harmonically, with the sparse back end as the fallback when that map is not regular.
  Used for the SCP k search when the boundary has more than ``subspace_from`` vertices.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from functools import partial
from types import SimpleNamespace

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp

from parambench.datasets_gen.errors import ConvergenceError, InvalidInputError, SolverError, UnknownNameError

from ..hints import Hint, hinted
from .ksearch import DEFAULT_R, KPoint, line_search, root_search_near
from .operators import area_matrix, boundary_indicator, check_loops, conformal_operator, is_symmetric, rayleigh_energy
from .ordering import nested_dissection, nested_dissection_with_root
from .reduction import BoundaryReduction, deflation_basis, dense_real_pencil, dense_smallest, pencil_k_estimates
from .sparse_eigen import SparseFactor, smallest_eigenpair
from .tied_modes import outer_rim_if_tied, outer_rim_mode, tied_pair
from .subspace import DEFAULT_MODES, BoundarySubspace
from .threads import single_threaded_blas
from .turning import is_regular_turning, loop_turning_numbers

__all__ = ["ConformalProblem", "ConformalSolution", "K_SEARCH_MODES", "solve_line_then_direct"]

K_SEARCH_MODES = ("none", "line", "direct")
BACKENDS = ("auto", "sparse", "boundary", "subspace")

#: Largest boundary on which a failed search falls back by itself to the exact searches
#: on the dense boundary reduction (:meth:`ConformalProblem.exact_fallback_affordable`):
#: ``real/cortex-lh``'s mesh (451 boundary vertices) needs that fallback for SCP with
#: normalized cotangent weights; on its bare points with four detected loops (792 and
#: 874 boundary points after and before hole filling) the fallbacks ran 153 dense
#: eigen-solves of 0.6-1.6 s each, 3.5 minutes before the ConvergenceError.
EXACT_FALLBACK_MAX_BOUNDARY = 500

#: Near-real candidates the direct fallback of :func:`solve_line_then_direct` examines for
#: non-symmetric weights (all of them for symmetric ones, where a candidate is free). Each
#: costs a dense eigen-solve of the boundary reduction: on points scattered over
#: ``real/lilium`` (5k), 87 candidates took 13 s and none gave a regular map. Over the 61
#: cases of ``bench_realdata.py`` and 7 scattered real meshes, the 13 fallbacks with
#: non-symmetric weights found a regular map at no candidate at all.
FALLBACK_NONSYMMETRIC_CANDIDATES = 8


@dataclass
class ConformalSolution:
    """A map z = u + i v at some k.

    Attributes
    ----------
    z : (V,) numpy.ndarray of complex128
    k : float
    energy : float
        Normalised conformal energy ``Re z^H (k L/2 - M) z / z^H B z`` (translation removed).
    turning : (n_loops,) numpy.ndarray of int64
    eigenvalue : complex or None
        SCP only.
    diagnostics : dict
        Solver counts, search landscape, back end (JSON-serialisable).
    """

    z: np.ndarray
    k: float
    energy: float
    turning: np.ndarray
    eigenvalue: complex | None = None
    diagnostics: dict = field(default_factory=dict)

    @property
    def uv(self) -> np.ndarray:
        """(V, 2) numpy.ndarray of float64: columns Re z, Im z."""
        return np.column_stack([self.z.real, self.z.imag])


class ConformalProblem:
    """Conformal energy ``z^H (k L / 2 - M) z`` of a Laplacian with boundary loops.

    Parameters
    ----------
    laplacian : (V, V) scipy.sparse matrix of float64
        L = D - W; rows must sum to zero. Scaled so that k = 1 is conformal for
        cotangent weights (see :mod:`parambench.methods.mesh.weights`).
    loops : sequence of (L_i,) array_like of int
        Oriented boundary loops: the outer one counter-clockwise in the intended image,
        holes clockwise (e.g. :func:`parambench.methods.mesh.topology.boundary_loops`, which follows
        the face orientation).
    b_matrix : "boundary" or (V, V) scipy.sparse matrix
        Mullen et al.'s B (1 at every boundary vertex), or a given positive
        semi-definite matrix such as a mass matrix.
    points : (V, d) numpy.ndarray of float64, optional
        Positions, only used for a fill-reducing nested-dissection order.
    max_boundary_dense : int
        Above this many boundary vertices the searches use the sparse back end.
    psd_from_k : float, optional
        The caller knows ``k L / 2 - M`` is positive semi-definite for k >= this value
        (1 for cotangent weights: per triangle the Dirichlet energy of a linear map is at
        least its image's area). The inertia check of the fixed-k SCP solve is then skipped.
    subspace_from : int
        With more boundary vertices than this, the SCP k search runs on a boundary
        subspace (``backend="subspace"``) under ``backend="auto"``.
    subspace_modes : int
        Fourier modes of that subspace (:func:`parambench.methods.spectral.subspace.boundary_basis`).
    subspace_extra : (K, e) numpy.ndarray of float64, optional
        Further functions on the concatenated boundary loops added to that subspace (a
        coarse level's map, :mod:`.multilevel`); when given, the SCP k search under
        ``backend="auto"`` uses the subspace whatever the boundary's size.
    subspace_rounds : int
        Most k searches on the subspace, each after a refinement grew it (1: search once).
    subspace_ktol : float
        Stop repeating the search once k_opt moves by less than this, relative; whether it
        did within ``subspace_rounds`` is ``subspace_settled`` in the diagnostics.
    refine_rule : dict, optional
        Keyword arguments of the Davidson refinement
        (:meth:`~parambench.methods.spectral.subspace.BoundarySubspace.refine`'s
        ``max_steps``, ``stall``, ``window``); its defaults when None.
    interior_solver : callable, optional
        Solves with the interior block of the boundary reduction instead of a sparse
        factorisation (``interior_solver(l_ii, interior)``, see
        :class:`~parambench.methods.spectral.reduction.BoundaryReduction`; the two-grid
        solver of :mod:`.multilevel`). Used for the reduction onto the boundary loops alone.
    map_error : float, optional
        With iterative interior solves (``interior_solver``), the subspace map's error
        estimate (its boundary residual over the gap to the next Ritz value, both
        relative to ``k/2 max|diag L_KK|``; ``map_error_estimate`` in the diagnostics)
        the search must reach: when the first settled map's is above it, the solves are
        tightened, the subspace's products solved again from their kept interior values
        and the k search settled again (``polish_rtol`` in the diagnostics). None: no
        polish.
    unsettled_map_error : float, optional
        The same, only when the k search did not settle within ``subspace_rounds`` while
        its refinement reached the interior solves' floor (the solves' error moves
        k_opt from round to round: a jittered cylinder at 1M points).
    exact_fallbacks : bool
        May a failed search fall back to the exact searches on the dense boundary
        reduction (:meth:`exact_fallback_affordable`)? False where the caller has a cheaper
        fallback to try first: ``ocp`` on points scattered over a real mesh, whose Neumann
        energy has no regular map there, spent most of its 9-50 s in them before its paper-energy
        fallback found the map (:func:`solve_line_then_direct` then says they were left out).
    k_start : float
        Where the line search starts (its ``k0``) unless :meth:`solve` is given one: 1 for
        weights at the cotangent scale; a caller that knows the weights' scale differs
        (authalic, mean-value) passes an estimate of k_opt (see
        :func:`parambench.methods.mesh.conformal_setup.k_start_estimate`).

    Raises
    ------
    InvalidInputError
        Shapes, loops, row sums or B are invalid.
    UnknownNameError
        ``b_matrix`` is an unknown string.
    """

    #: Largest relative boundary residual of a refined subspace map that is extended and
    #: returned. Converged maps reach 1e-9 to 5e-7 (the two-grid solves' floor); the worst
    #: unsettled one measured that was still close to the exact map, 1.9e-5 (cylinder,
    #: 100k points, two levels). Above this neither the map nor its k_opt is trusted: the
    #: exact search runs instead where the boundary is small enough for it, else the exact
    #: map at k_opt is solved (cortex-lh, normalized cotangent weights: 1.4e-3 with
    #: turning number 1, QC 2.19 and 10 foldovers, before the refinement's window rule).
    TRUSTED_RESIDUAL = 1e-4

    #: The tightest interior-solve tolerance a polish asks for (``map_error``): below it the
    #: two-grid cycles approach double precision's limit on these rows.
    MIN_SOLVE_RTOL = 1e-12

    def __init__(self, laplacian: sp.spmatrix, loops: Sequence[np.ndarray], b_matrix="boundary",
                 points: np.ndarray | None = None, max_boundary_dense: int = 4000,
                 psd_from_k: float | None = None, subspace_from: int = 300,
                 subspace_modes: int = DEFAULT_MODES, subspace_extra: np.ndarray | None = None,
                 subspace_rounds: int = 4, subspace_ktol: float = 1e-6, k_start: float = 1.0,
                 interior_solver=None, refine_rule: dict | None = None, map_error: float | None = None,
                 unsettled_map_error: float | None = None, exact_fallbacks: bool = True) -> None:
        lap = sp.csr_matrix(laplacian, dtype=np.float64)
        n = lap.shape[0]
        if lap.shape != (n, n):
            raise InvalidInputError(f"the Laplacian must be square, got {lap.shape}.")
        rowsum = np.abs(np.asarray(lap.sum(axis=1)).ravel())
        if rowsum.max() > 1e-8 * max(abs(lap).max(), 1.0):
            raise InvalidInputError("the Laplacian's rows do not sum to zero; build it as L = D - W "
                                    "(parambench.methods.mesh.weights.laplacian).")
        self.laplacian = lap
        self.n = n
        self.loops = check_loops(loops, n)
        self.boundary = np.concatenate(self.loops)
        self.area = area_matrix(self.loops, n)
        if isinstance(b_matrix, str):
            if b_matrix != "boundary":
                raise UnknownNameError(f"unknown b_matrix {b_matrix!r}; use 'boundary' or pass a sparse matrix "
                                       "(e.g. a mass matrix).")
            self.b = boundary_indicator(self.loops, n)
            self.b_on_boundary = True
        else:
            b = sp.csr_matrix(b_matrix, dtype=np.float64)
            if b.shape != (n, n):
                raise InvalidInputError(f"b_matrix must have shape ({n}, {n}), got {b.shape}.")
            if np.any(b.diagonal() < 0) or not np.all(b.diagonal()[self.boundary] > 0):
                raise InvalidInputError("b_matrix must have a non-negative diagonal, positive at boundary vertices.")
            self.b = b
            self.b_on_boundary = False
        self.hermitian = is_symmetric(lap)
        self.points = None if points is None else np.asarray(points, dtype=np.float64)
        self.max_boundary_dense = int(max_boundary_dense)
        self.psd_from_k = psd_from_k
        self.subspace_from = int(subspace_from)
        self.subspace_modes = int(subspace_modes)
        self.subspace_rounds = int(subspace_rounds)
        self.subspace_ktol = float(subspace_ktol)
        if not k_start > 0:
            raise InvalidInputError(f"k_start must be positive, got {k_start}.")
        self.k_start = float(k_start)
        self.subspace_extra = None if subspace_extra is None else np.asarray(subspace_extra, dtype=np.float64)
        if self.subspace_extra is not None and self.subspace_extra.shape[0] != self.boundary.size:
            raise InvalidInputError(f"subspace_extra must have one row per boundary vertex ({self.boundary.size}), "
                                    f"got shape {self.subspace_extra.shape}.")
        self._counts = {"eigen_solves": 0, "linear_solves": 0, "factorizations": 0, "triangular_solves": 0}
        self._retired_solves = 0
        self._perm: np.ndarray | None = None
        self._reductions: dict[tuple, BoundaryReduction] = {}
        self._interior_solver = interior_solver
        self.refine_rule = dict(refine_rule or {})
        if map_error is not None and not map_error > 0:
            raise InvalidInputError(f"map_error must be positive, got {map_error}.")
        self.map_error = None if map_error is None else float(map_error)
        if unsettled_map_error is not None and not unsettled_map_error > 0:
            raise InvalidInputError(f"unsettled_map_error must be positive, got {unsettled_map_error}.")
        self.unsettled_map_error = None if unsettled_map_error is None else float(unsettled_map_error)
        self.exact_fallbacks = bool(exact_fallbacks)

    # ------------------------------------------------------------------ helpers
    @property
    def counts(self) -> dict[str, int]:
        """Solver work so far: eigen-solves, linear solves, factorisations, triangular solves."""
        out = dict(self._counts)
        out["triangular_solves"] += self._retired_solves + sum(r.n_solves for r in self._reductions.values())
        return out

    def _release_reductions(self) -> None:
        """Drop the interior factorisations (memory) but keep their solve counts."""
        self._retired_solves += sum(r.n_solves for r in self._reductions.values())
        self._reductions.clear()

    def _area_block(self, keep: np.ndarray) -> np.ndarray:
        """(K, K) numpy.ndarray of complex128: the area matrix on the kept vertices, dense."""
        return self.area[keep][:, keep].toarray()

    def operator(self, k: float) -> sp.csr_matrix:
        """The sparse conformal operator ``k L / 2 - M``."""
        return conformal_operator(self.laplacian, self.area, k)

    def _order(self) -> np.ndarray | None:
        if self.points is None:
            return None
        if self._perm is None:
            self._perm = nested_dissection(self.points, self.laplacian + abs(self.area))
        return self._perm

    def reduction(self) -> BoundaryReduction:
        """The reduction onto the boundary loops (its interior factorisation computed on first use).

        It is cached until the solver releases its factorisations; a caller that keeps the
        returned object keeps its factorisation alive (the coarse level of :mod:`.multilevel`
        hands it to the fine level's two-grid solves).
        """
        return self._reduction()

    def _reduction(self, extra: Sequence[int] = ()) -> BoundaryReduction:
        extra = tuple(int(v) for v in extra if int(v) not in set(self.boundary.tolist()))
        if extra not in self._reductions:
            keep = np.concatenate([self.boundary, np.asarray(extra, dtype=np.int64)])
            perm, root = None, None
            if not extra and self._interior_solver is not None:
                red = BoundaryReduction(self.laplacian, keep, interior_solver=self._interior_solver)
                self._reductions[extra] = red
                return red
            if self.points is not None:
                mask = np.ones(self.n, dtype=bool)
                mask[keep] = False
                interior = np.flatnonzero(mask)
                perm, root = nested_dissection_with_root(self.points[interior], self.laplacian[interior][:, interior])
            red = BoundaryReduction(self.laplacian, keep, perm, root_separator=root)
            self._counts["factorizations"] += 1
            self._reductions[extra] = red
        return self._reductions[extra]

    def _local_loops(self, keep: np.ndarray) -> list[np.ndarray]:
        pos = np.full(self.n, -1, dtype=np.int64)
        pos[keep] = np.arange(keep.size)
        return [pos[loop] for loop in self.loops]

    def _use_boundary(self, backend: str) -> bool:
        if backend not in BACKENDS:
            raise UnknownNameError(f"unknown backend {backend!r}; choose one of {', '.join(BACKENDS)}.")
        if backend == "boundary":
            return True
        if backend in ("sparse", "subspace"):
            return False
        return self.b_on_boundary and self.boundary.size <= self.max_boundary_dense

    def exact_fallback_affordable(self) -> bool:
        """May a failed search fall back to the exact ones on the dense boundary reduction?

        Those take one dense eigen-solve per k tried (up to 40 for the line search, one
        per near-real candidate, up to about 150, for the direct k), each cubic in the
        boundary's size: 0.6-1.6 s at 800-1000 boundary points on 2 cores
        (``real/cortex-lh`` as bare points with four detected loops: 338 solves, 9
        minutes before its ConvergenceError). Above :data:`EXACT_FALLBACK_MAX_BOUNDARY`
        the failure is reported at once; asking for ``k_search="direct"`` still runs it.
        """
        return (self.exact_fallbacks and self.b_on_boundary
                and self.boundary.size <= min(self.max_boundary_dense, EXACT_FALLBACK_MAX_BOUNDARY))

    def _use_subspace(self, backend: str) -> bool:
        """SCP k search on the boundary subspace?"""
        if backend == "subspace":
            if not self.b_on_boundary:
                raise InvalidInputError("the subspace back end needs B on the boundary (b_matrix='boundary').")
            return True
        return backend == "auto" and self.b_on_boundary and (self.boundary.size > self.subspace_from
                                                            or self.subspace_extra is not None)

    def _pins(self, pins: Sequence[int], pin_values: Sequence[complex]) -> tuple[np.ndarray, np.ndarray]:
        p = np.asarray(pins, dtype=np.int64).ravel()
        vals = np.asarray(pin_values, dtype=np.complex128).ravel()
        if p.size != 2 or p[0] == p[1] or p.min() < 0 or p.max() >= self.n:
            raise InvalidInputError(f"DNCP needs two distinct pinned vertices in [0, {self.n - 1}], got {p.tolist()}.")
        if vals.size != 2 or vals[0] == vals[1]:
            raise InvalidInputError("the two pinned positions must differ.")
        return p, vals

    # ----------------------------------------------------------- reduced solves
    def _scp_reduced(self, k: float) -> KPoint:
        red = self._reduction()
        m_kk = self._area_block(red.keep)
        op = (0.5 * k) * red.schur - m_kk
        several = len(self.loops) > 1
        # Three values for the tie test, the second vector only where the first two tie.
        vals, vecs = dense_smallest(op, hermitian=self.hermitian, count=3 if several else 1, vectors=1)
        self._counts["eigen_solves"] += 1
        local_loops = self._local_loops(red.keep)
        z_k, energy = vecs[:, 0], float(vals[0].real)
        if several and tied_pair(vals):
            _, pair = dense_smallest(op, hermitian=self.hermitian, count=2)
            z_k = outer_rim_mode(pair, None, local_loops, None if self.points is None else self.points[red.keep])
            energy = rayleigh_energy(z_k, op, np.ones(op.shape[0]))
        turning = loop_turning_numbers(z_k, local_loops)
        return KPoint(k=k, energy=energy, turning=turning, state=(z_k, complex(vals[0])))

    def _dncp_reduced(self, k: float, pins: np.ndarray, pin_values: np.ndarray) -> KPoint:
        red = self._reduction(pins)
        keep = red.keep
        pos = np.full(self.n, -1, dtype=np.int64)
        pos[keep] = np.arange(keep.size)
        ip = pos[pins]
        free = np.setdiff1d(np.arange(keep.size), ip)
        m_kk = self._area_block(keep)
        op = (0.5 * k) * red.schur - m_kk
        z_k = np.empty(keep.size, dtype=np.complex128)
        z_k[ip] = pin_values
        try:
            # The k search steps past the k where this system is singular (an open cylinder
            # at rcond 1.9e-16: LAPACK's warning reached the user, then a correct map): such a
            # k is a point of the search, not the map, which the self-check judges.
            with single_threaded_blas(), warnings.catch_warnings():
                warnings.simplefilter("ignore", la.LinAlgWarning)
                z_k[free] = la.solve(op[np.ix_(free, free)], -op[np.ix_(free, ip)] @ pin_values)
        except la.LinAlgError:
            raise hinted(SolverError, f"the DNCP system is singular at k = {k:g}",
                         Hint("move the pins apart", "pins"), Hint("change k", "k")) from None
        self._counts["linear_solves"] += 1
        w = np.zeros(keep.size)
        w[: self.boundary.size] = 1.0
        zc = z_k - np.dot(w, z_k) / w.sum()
        energy = float(np.real(np.vdot(zc, op @ zc))) / float(np.dot(w, np.abs(zc) ** 2))
        turning = loop_turning_numbers(z_k, self._local_loops(keep))
        return KPoint(k=k, energy=energy, turning=turning, state=(z_k, None))

    def _scp_subspace_search(self, line_kwargs: dict, exact_fallback: bool = False) -> tuple[ConformalSolution, dict]:
        """k_opt by the line search on the boundary subspace, then the exact map there.

        With ``exact_fallback``, a refinement that did not converge (residual above
        :attr:`TRUSTED_RESIDUAL`) raises SolverError, so that the caller runs the exact
        search: the subspace's k_opt is then as doubtful as its map (normalized cotangent
        weights on real/cortex-lh: residual 1.3e-4, the subspace's k_opt 3.2610 against
        the exact 3.2593; the maps there differ by 7.8e-4 of the diameter).
        """
        red, sub, result, point, info = self._subspace_search(line_kwargs)
        if exact_fallback and info["boundary_residual"] > self.TRUSTED_RESIDUAL:
            self._release_reductions()
            raise SolverError(f"the subspace refinement did not converge (boundary residual "
                              f"{info['boundary_residual']:.2g} > {self.TRUSTED_RESIDUAL:g})")
        trusted = point.regular and info["boundary_residual"] <= self.TRUSTED_RESIDUAL
        z = sub.extend(point.state[0]) if trusted else None
        # The interior factorisation is done with; free it before any fallback factorises.
        self._release_reductions()
        backend = "subspace"
        if z is None:
            point = self._scp_sparse_regular(result.best.k)
            z, backend = point.state[0], "subspace+sparse"
        sol = ConformalSolution(z=z, k=point.k, energy=point.energy, turning=point.turning,
                                eigenvalue=point.state[1], diagnostics={"backend": backend})
        diag = {"landscape": result.landscape, "bracket": list(result.bracket),
                "n_k_evaluations": result.n_evaluations,
                "subspace_k_opt": float(result.best.k), "subspace_energy": float(result.best.energy), **info}
        return sol, diag

    @staticmethod
    def _search_first(sub: BoundarySubspace, line_kwargs: dict):
        """The first k search on ``sub``: a root find from the Ritz pencil's k_opt estimate, else the line search.

        The line search from k = 1 took 24-30 evaluations at 10k-20k points; the pencil
        (:meth:`~parambench.methods.spectral.subspace.BoundarySubspace.k_estimates`) puts
        k within ~1e-6 of the zero of q, where
        :func:`~parambench.methods.spectral.ksearch.root_search_near` needs 4-7. Where
        that estimate does not lead to a plain sign change of q between regular maps,
        the line search runs as before.
        """
        if line_kwargs.get("bracket") is None:
            estimates = sub.k_estimates()
            if estimates.size:
                near = root_search_near(sub.evaluate, float(estimates[0]), r=line_kwargs.get("r", DEFAULT_R))
                if near is not None:
                    return near
        return line_search(sub.evaluate, **line_kwargs)

    @staticmethod
    def _search_near(sub: BoundarySubspace, k: float, line_kwargs: dict, width: float = 4e-3):
        """The k search on ``sub`` near the previous round's k_opt.

        First a root find on q from k (:func:`~parambench.methods.spectral.ksearch.root_search_near`,
        5-7 evaluations where the line search in a bracket took about 20; measured at 10k-20k
        points, the same k_opt to the polish's tolerance); when the landscape there is not
        a plain sign change between regular maps, the line search in a bracket of relative
        ``width`` around k, or a full one if k_opt left it.
        """
        if line_kwargs.get("bracket") is None:
            near = root_search_near(sub.evaluate, k, r=line_kwargs.get("r", DEFAULT_R), width=width)
            if near is not None:
                return near
            try:
                return line_search(sub.evaluate, **{**line_kwargs, "bracket": (k * (1 - width), k * (1 + width))})
            except ConvergenceError:
                pass
        return line_search(sub.evaluate, **line_kwargs)

    def scp_subspace_estimate(self, **line_kwargs) -> tuple[KPoint, dict]:
        """k_opt and the boundary map of the subspace k search, without the sparse fallback.

        The subspace search and Davidson refinement of ``backend="subspace"``, but the
        refined boundary map is returned even when it is not regular (a coarse level's
        estimate, :mod:`.multilevel`, only needs it as a direction).

        Parameters
        ----------
        **line_kwargs
            Passed to :func:`parambench.methods.spectral.ksearch.line_search`.

        Returns
        -------
        point : KPoint
            ``state`` = (boundary values on the concatenated loops, Ritz value).
        info : dict
            ``subspace_size`` (the search basis), ``subspace_final_size`` (grown by the
            refinements), ``subspace_rounds``, ``subspace_settled``, ``refine_steps``, ``boundary_residual``, ``regular``.

        Raises
        ------
        InvalidInputError
            B is not the boundary indicator.
        ConvergenceError
            The k search found no t = 1 crossing.
        """
        if not self.b_on_boundary:
            raise InvalidInputError("the subspace estimate needs B on the boundary (b_matrix='boundary').")
        with single_threaded_blas():
            _, _, _, point, info = self._subspace_search(line_kwargs)
            self._release_reductions()
        return point, {"regular": bool(point.regular), **info}

    def _subspace_search(self, line_kwargs: dict):
        """(reduction, subspace, search result, refined point at k_opt, refine info); the factorisation is kept.

        The Ritz k_opt of a subspace lies off the exact one (measured at 20k points: 1.4e-3
        on a jittered cylinder, 5.6e-2 on a random-sampled bump, 32 modes), so the
        refinement's new directions are kept and the k search repeated on the grown
        subspace until k_opt moves by less than ``subspace_ktol`` relative (at most
        ``subspace_rounds`` searches).
        """
        red = self._reduction()
        sub = BoundarySubspace(red, self.area, self.loops, self.points, self.subspace_modes, self.subspace_extra)
        initial = sub.size
        result = self._search_first(sub, line_kwargs)
        point, info = sub.refine(result.best.k, absorb=True, **self.refine_rule)
        evaluations = result.n_evaluations
        result, point, info, counts, settled = self._settle(sub, result, point, info, line_kwargs)
        evaluations += counts.evaluations
        rounds = 1 + counts.searches
        target = self._polish_target(red, info, settled)
        polish_rtol = None if target is None else self._polish_rtol(red, info, target)
        polished = polish_rtol is not None and red.tighten(polish_rtol)
        if polished:
            # The map is limited by the interior solves' accuracy where the spectral gap is
            # small: the products are solved again from their kept interior values to
            # the tolerance the gap asks for, and the k search settles again on them.
            sub.resolve()
            rule = dict(self.refine_rule, rtol=max(target * info["ritz_gap"], 1e-12))
            point, info = sub.refine(point.k, absorb=True, **rule)
            result, point, info, more, settled = self._settle(sub, result, point, info, line_kwargs, rule)
            rounds, evaluations = rounds + more.searches, evaluations + more.evaluations
        self._counts["eigen_solves"] += evaluations + rounds
        return red, sub, result, point, {**info, "subspace_rounds": rounds, "subspace_size": initial,
                                         "subspace_final_size": sub.size, "subspace_settled": settled,
                                         "polish_rtol": float(polish_rtol) if polished else None}

    def _settle(self, sub: BoundarySubspace, result, point, info: dict, line_kwargs: dict,
                rule: dict | None = None):
        """Repeat the k search on the refined subspace until k_opt moves by less than ``subspace_ktol``.

        At most ``subspace_rounds - 1`` searches after the one that gave ``point``.

        Returns
        -------
        result, point, info
            The last search's result, the refined point at its k_opt and its refinement's info.
        counts : SimpleNamespace
            ``searches`` and line-search ``evaluations`` made here.
        settled : bool
        """
        rule = self.refine_rule if rule is None else rule
        counts = SimpleNamespace(searches=0, evaluations=0)
        settled = self.subspace_rounds <= 1  # one search asked for: nothing to settle
        while counts.searches + 1 < self.subspace_rounds:
            again = self._search_near(sub, point.k, line_kwargs)
            counts.searches += 1
            counts.evaluations += again.n_evaluations
            moved = abs(again.best.k - point.k) > self.subspace_ktol * abs(point.k)
            result = again
            if not moved:
                settled = True
                break
            point, info = sub.refine(again.best.k, absorb=True, **rule)
        return result, point, info, counts, settled

    def _polish_target(self, red: BoundaryReduction, info: dict, settled: bool) -> float | None:
        """The error estimate a polish must reach, or None if none is due.

        Due, with iterative interior solves, when the map's error estimate (residual over
        the Ritz gap) is above ``map_error``, or above ``unsettled_map_error`` when the k
        search did not settle although the refinement reached the solves' floor
        (:attr:`BoundarySubspace.SOLVE_FLOOR` times their tolerance): the solves'
        error then moves k_opt from round to round.
        """
        if red.solve_rtol == 0.0:
            return None
        floor = BoundarySubspace.SOLVE_FLOOR * red.solve_rtol
        targets = [self.map_error]
        if not settled and info.get("boundary_residual", np.inf) <= 2.0 * floor:
            targets.append(self.unsettled_map_error)
        targets = [t for t in targets if t is not None]
        if not targets or not info.get("map_error_estimate", 0.0) > min(targets):
            return None
        return min(targets)

    def _polish_rtol(self, red: BoundaryReduction, info: dict, target: float) -> float:
        """The interior solves' tolerance that lets the map's error estimate reach ``target``.

        The refinement's residual floors at :attr:`BoundarySubspace.SOLVE_FLOOR` times the
        solves' tolerance, and the estimate is that residual over the Ritz gap.
        """
        wanted = target * info["ritz_gap"] / BoundarySubspace.SOLVE_FLOOR
        return max(min(wanted, red.solve_rtol), self.MIN_SOLVE_RTOL)

    def _scp_sparse_regular(self, k: float, max_steps: int = 6) -> KPoint:
        """Exact SCP at k, nudged upwards if it still spins just below the exact transition.

        The fallback when the refined subspace map at k_opt is not regular: the
        subspace's k_opt is an approximation, so when the exact map there is not regular
        or its energy is clearly negative, k grows by 1e-4, 2e-4, 4e-4, ... relative.
        """
        p = self._scp_sparse(k, True)
        step = 1e-4
        for _ in range(max_steps):
            if p.regular and p.energy >= -1e-6 * abs(k):
                return p
            p = self._scp_sparse(k * (1.0 + step), True)
            step *= 2.0
        if not p.regular:
            raise hinted(SolverError, f"the exact SCP map near the subspace k_opt = {k:.6g} is not regular "
                         f"(turning numbers {p.turning.tolist()})",
                         Hint("use backend='boundary' for an exact k search", "backend", "boundary"))
        return p

    # ------------------------------------------------------------- sparse solves
    def _scp_sparse(self, k: float, allow_negative: bool) -> KPoint:
        known_psd = self.psd_from_k is not None and k >= self.psd_from_k
        res = smallest_eigenpair(self.operator(k), self.b, hermitian=self.hermitian, perm=self._order(),
                                 allow_negative=allow_negative, check_inertia=not known_psd,
                                 nev=3 if len(self.loops) > 1 else 2)
        self._counts["eigen_solves"] += 1
        self._counts["factorizations"] += res.n_factorizations
        self._counts["triangular_solves"] += res.n_solves
        z, energy = res.vector, float(res.value.real)
        untied = outer_rim_if_tied(res.values, res.vectors, self.b, self.loops, self.points)
        if untied is not None:
            z, energy = untied, rayleigh_energy(untied, self.operator(k), self.b)
        turning = loop_turning_numbers(z, self.loops)
        return KPoint(k=k, energy=energy, turning=turning, state=(z, res.value))

    def _untied_dncp(self, k: float, z: np.ndarray) -> np.ndarray:
        """DNCP's map at k_opt, or where two zero-energy maps tie there, the one with the longest loop outside.

        On an annulus both ``e^z`` and ``e^-z`` have zero energy at k_opt, so the pinned
        system is near-singular and its solution a mix of the two set by roundoff (an open
        cylinder of 100 x 17 vertices: rims not round, QC mean 1.06, max 2.4); see
        :mod:`parambench.methods.spectral.tied_modes`. One more sparse eigen-solve (three
        pairs) on surfaces with two or more loops.
        """
        if len(self.loops) < 2:
            return z
        res = smallest_eigenpair(self.operator(k), self.b, hermitian=self.hermitian, perm=self._order(),
                                 allow_negative=True, check_inertia=False, nev=3)
        self._counts["eigen_solves"] += 1
        untied = outer_rim_if_tied(res.values, res.vectors, self.b, self.loops, self.points)
        return z if untied is None else untied

    def _dncp_sparse(self, k: float, pins: np.ndarray, pin_values: np.ndarray) -> KPoint:
        op = self.operator(k)
        free = np.setdiff1d(np.arange(self.n), pins)
        perm = self._order()
        sub_perm = None
        if perm is not None:
            pos = np.full(self.n, -1, dtype=np.int64)
            pos[free] = np.arange(free.size)
            sub_perm = pos[perm]
            sub_perm = sub_perm[sub_perm >= 0]
        with single_threaded_blas():
            factor = SparseFactor(op[free][:, free], sub_perm)
            z = np.empty(self.n, dtype=np.complex128)
            z[pins] = pin_values
            z[free] = factor.solve(-(op[free][:, pins] @ pin_values))
        self._counts["factorizations"] += 1
        self._counts["linear_solves"] += 1
        self._counts["triangular_solves"] += factor.n_solves
        energy = rayleigh_energy(z, op, self.b)
        return KPoint(k=k, energy=energy, turning=loop_turning_numbers(z, self.loops), state=(z, None))

    # ------------------------------------------------------------------ public
    def k_direct(self, extra: Sequence[int] = (), max_candidates: int | None = None,
                 imag_tol: float | None = None) -> tuple[float, np.ndarray]:
        """k_opt from the generalised eigenproblem ``M z = k (L / 2) z``, without a search.

        E(k) = 0 exactly when ``(k L / 2 - M) z = 0`` has a non-translation solution z.
        For symmetric L the largest such k is where the smallest SCP eigenvalue crosses
        zero and z is the SCP map there. For non-symmetric L the smallest SCP eigenvalue
        is complex, so its real part crosses zero where the pencil has an eigenvalue mu
        with a small imaginary part (measured 1e-5 to 2e-4 relative on the point-set
        Laplacians), at k = Re mu to about 6 digits. Candidates are taken largest first;
        the first whose map is regular wins. For non-symmetric L that map is the SCP
        eigenvector computed at k = Re mu (not the pencil's eigenvector).

        Parameters
        ----------
        extra : sequence of int
            Vertices kept besides the boundary (DNCP pins); does not change k_opt.
        max_candidates : int, optional
            Near-real eigenvalues examined, largest first (default: all).
        imag_tol : float, optional
            Largest ``|Im mu| / |mu|`` of a candidate; default 1e-8 for symmetric L and
            1e-2 otherwise.

        Returns
        -------
        k_opt : float
        z : (V,) numpy.ndarray of complex128
            The map at k_opt.

        Raises
        ------
        SolverError
            No near-real positive eigenvalue with a regular map.
        """
        red = self._reduction(extra)
        m_kk = self._area_block(red.keep)
        tol = (1e-8 if self.hermitian else 1e-2) if imag_tol is None else float(imag_tol)
        mus, vecs = dense_real_pencil(m_kk, 0.5 * red.schur, hermitian=self.hermitian, imag_tol=tol)
        self._counts["eigen_solves"] += 1
        local = self._local_loops(red.keep)
        n_cand = mus.size if max_candidates is None else min(mus.size, max_candidates)
        for i in range(n_cand):
            if self.hermitian or len(extra):
                z_k = vecs[:, i]
            else:
                z_k = self._scp_reduced(float(mus[i])).state[0]
            if is_regular_turning(loop_turning_numbers(z_k, local)):
                return float(mus[i]), red.extend(z_k)
        raise hinted(
            SolverError,
            f"none of the {n_cand} largest near-real k with zero conformal energy gives a regular "
            f"map (largest: {mus[0]:.6g}); with these non-symmetric weights the optimum has positive energy",
            Hint("use k_search='line'", "k_search", "line"),
        )

    def scp(self, k: float = 1.0, *, backend: str = "sparse", allow_negative: bool = False) -> ConformalSolution:
        """SCP at a fixed k: the smallest eigenpair of ``(k L/2 - M) z = lambda B z``.

        Raises
        ------
        SolverError
            The energy is indefinite at this k (negative eigenvalues: the map would spin)
            and ``allow_negative`` is False, or the solve failed.
        ConvergenceError
            The eigen-solve did not converge.
        """
        if self._use_boundary(backend) and self.b_on_boundary:
            p = self._scp_reduced(k)
            if not allow_negative and p.energy < -1e-10 * abs(k):
                raise hinted(SolverError, f"the conformal energy is indefinite at k = {k:g} (smallest eigenvalue "
                             f"{p.energy:.3e} < 0), so the map spins", Hint("use k_search='line'", "k_search", "line"), Hint("use k_search='direct'", "k_search", "direct"))
            z = self._reduction().extend(p.state[0])
            used = "boundary"
        else:
            p = self._scp_sparse(k, allow_negative)
            z = p.state[0]
            used = "sparse"
        return ConformalSolution(z=z, k=k, energy=p.energy, turning=p.turning, eigenvalue=p.state[1],
                                 diagnostics={"backend": used})

    def dncp(self, k: float, pins: Sequence[int], pin_values: Sequence[complex] = (0.0, 1.0), *,
             backend: str = "auto") -> ConformalSolution:
        """DNCP at a fixed k: minimise the conformal energy with two vertices pinned.

        Raises
        ------
        InvalidInputError
            Pins not two distinct vertices, or equal pinned positions.
        SolverError
            Singular system.
        """
        pins_a, vals = self._pins(pins, pin_values)
        if self._use_boundary(backend):
            p = self._dncp_reduced(k, pins_a, vals)
            z = self._reduction(pins_a).extend(p.state[0])
            used = "boundary"
        else:
            p = self._dncp_sparse(k, pins_a, vals)
            z = p.state[0]
            used = "sparse"
        return ConformalSolution(z=z, k=k, energy=p.energy, turning=p.turning, diagnostics={"backend": used})

    def solve(self, mode: str, k_search: str = "none", *, k: float = 1.0, pins: Sequence[int] | None = None,
              pin_values: Sequence[complex] = (0.0, 1.0), backend: str = "auto", r: float = DEFAULT_R,
              growth: float = 1.25, bracket: tuple[float, float] | None = None, xatol: float = 1e-9,
              k0: float | None = None, max_candidates: int | None = None) -> ConformalSolution:
        """SCP or DNCP with k fixed, searched along a line (Eq. 16) or computed directly.

        Parameters
        ----------
        mode : {"scp", "dncp"}
        k_search : {"none", "line", "direct"}
        k : float
            The k used when ``k_search="none"``.
        pins, pin_values
            DNCP's pinned vertices and their positions (complex).
        backend : {"auto", "sparse", "boundary", "subspace"}
        r, growth, bracket, xatol, k0
            See :func:`parambench.methods.spectral.ksearch.line_search` (``k0``: where the
            line search starts stepping; default ``k_start``).
        max_candidates : int, optional
            ``k_search="direct"``: near-real eigenvalues examined (see :meth:`k_direct`).

        Returns
        -------
        ConformalSolution
            ``diagnostics`` holds ``k_opt``, ``k_search``, the solver counts, and for the
            line search ``landscape`` (lists k, E, q, t) and ``bracket``.

        Raises
        ------
        UnknownNameError
            Unknown mode, k_search or backend.
        SolverError
            Solve failed; the energy is indefinite at the fixed k; or a searched k_opt
            gives a map that is not regular. (With ``k_search="none"`` an irregular
            boundary is reported as ``diagnostics["regular_boundary"] = False``.)
        ConvergenceError
            The k search found no t = 1 crossing or did not converge.
        """
        with single_threaded_blas():  # many small dense calls; see parambench.methods.spectral.threads
            mode, k_search = _checked_names(mode, k_search)
            pins_a, vals = self._dncp_pins(mode, pins, pin_values)
            diag: dict = {"k_search": k_search}
            if k_search == "none":
                sol = self._solve_fixed(mode, k, pins_a, vals, backend)
            elif k_search == "direct":
                sol = self._solve_direct(mode, pins_a, vals, backend, max_candidates)
            else:
                sol, extra = self._solve_line(mode, pins_a, vals, backend,
                                              dict(growth=growth, r=r, bracket=bracket, xatol=xatol,
                                                   k0=self.k_start if k0 is None else float(k0)))
                diag.update(extra)
            return self._finish(sol, mode, k_search, diag)

    # ------------------------------------------------------- stages of solve()
    def _dncp_pins(self, mode: str, pins: Sequence[int] | None,
                   pin_values: Sequence[complex]) -> tuple[np.ndarray | None, np.ndarray | None]:
        """The checked DNCP pins and their positions; (None, None) for SCP, whose pins are ignored."""
        if mode != "dncp":
            return None, None
        if pins is None:
            raise InvalidInputError("DNCP needs two pinned vertices.")
        return self._pins(pins, pin_values)

    def _solve_fixed(self, mode: str, k: float, pins: np.ndarray | None, pin_values: np.ndarray | None,
                     backend: str) -> ConformalSolution:
        """``k_search="none"``: the map at the given k.

        SCP at a single k is fastest on the sparse back end, so ``"auto"`` means sparse here.
        """
        if mode == "scp":
            return self.scp(k, backend="sparse" if backend == "auto" else backend)
        return self.dncp(k, pins, pin_values, backend=backend)

    def _solve_direct(self, mode: str, pins: np.ndarray | None, pin_values: np.ndarray | None,
                      backend: str, max_candidates: int | None = None) -> ConformalSolution:
        """``k_search="direct"``: k_opt from the generalised eigenproblem, then the map there.

        SCP takes the pencil's own map (eigenvalue 0 at k_opt); DNCP solves its pinned
        system at k_opt, since its map is not the pencil's eigenvector.
        """
        k_opt, z_star = self.k_direct(pins if mode == "dncp" else (), max_candidates=max_candidates)
        if mode == "dncp":
            sol = self.dncp(k_opt, pins, pin_values, backend=backend)
            untied = self._untied_dncp(k_opt, sol.z)
            if untied is sol.z:
                return sol
            return ConformalSolution(z=untied, k=k_opt, energy=rayleigh_energy(untied, self.operator(k_opt), self.b),
                                     turning=loop_turning_numbers(untied, self.loops), diagnostics=sol.diagnostics)
        op = self.operator(k_opt)
        return ConformalSolution(z=z_star, k=k_opt, energy=rayleigh_energy(z_star, op, self.b),
                                 turning=loop_turning_numbers(z_star, self.loops), eigenvalue=0.0,
                                 diagnostics={"backend": "boundary"})

    def _solve_line(self, mode: str, pins: np.ndarray | None, pin_values: np.ndarray | None, backend: str,
                    line_kwargs: dict) -> tuple[ConformalSolution, dict]:
        """``k_search="line"``: the line search (Eq. 16) for k_opt and the map there.

        Returns the solution and the search's diagnostics (landscape, bracket, evaluations).
        """
        if mode == "scp" and self._use_subspace(backend):
            try:
                # Not with iterative interior solves (the two-level path's fine level): the
                # exact search would run on them, minutes at 300k points.
                exact = backend == "auto" and self.exact_fallback_affordable() and self._interior_solver is None
                return self._scp_subspace_search(line_kwargs, exact_fallback=exact)
            except SolverError as err:
                # The subspace's k_opt is an estimate; where the exact map there still spins
                # and the nudges of _scp_sparse_regular do not reach the exact k_opt
                # (normalized cotangent on real/cortex-lh, 451 boundary vertices: subspace
                # 3.20485, exact 3.25935), the exact search on the boundary reduction decides.
                # Not with iterative interior solves either: the reduction takes one solve
                # per boundary point (550 s at 300k points on the two-level path's fine
                # level, where ocp's solver="auto" falls back to the direct path instead).
                if backend != "auto" or not self.exact_fallback_affordable() or self._interior_solver is not None:
                    raise
                subspace_error = str(err)
            backend = "boundary"
            sol, diag = self._solve_line(mode, pins, pin_values, backend, line_kwargs)
            diag["subspace_fallback"] = subspace_error
            return sol, diag
        evaluate, reduced = self._line_evaluator(mode, backend, pins, pin_values)
        result = None
        if mode == "scp" and reduced and line_kwargs.get("bracket") is None:
            result = self._reduced_root_search(line_kwargs.get("r", DEFAULT_R))
        if result is None:
            result = line_search(evaluate, **line_kwargs)
        best = result.best
        z = self._reduction(pins if mode == "dncp" else ()).extend(best.state[0]) if reduced else best.state[0]
        if mode == "dncp":
            untied = self._untied_dncp(best.k, z)
            if untied is not z:
                z = untied
                best = replace(best, turning=loop_turning_numbers(z, self.loops))
        sol = ConformalSolution(z=z, k=best.k, energy=best.energy, turning=best.turning,
                                eigenvalue=best.state[1], diagnostics={"backend": "boundary" if reduced else "sparse"})
        return sol, {"landscape": result.landscape, "bracket": list(result.bracket),
                     "n_k_evaluations": result.n_evaluations}

    def _reduced_root_search(self, r: float):
        """The SCP k search on the dense boundary reduction from the pencil's k_opt estimate, or None.

        As the subspace search's first round (:meth:`_search_first`): the largest near-real
        root of ``M_KK z = k (S / 2) z`` (one eigenvalue solve) starts a root find of q
        (:func:`~parambench.methods.spectral.ksearch.root_search_near`), where the line
        search from k = 1 took 20-30 evaluations, each a dense K x K eigenvalue solve
        (2000 points: 26 evaluations, 1.0 s of ocp's 1.3 s solve). None where the estimate
        does not lead to a plain sign change of q between regular maps: the caller then
        runs the line search.
        """
        red = self._reduction()
        q = deflation_basis(red.keep.size)
        m_kk = self._area_block(red.keep)
        estimates = pencil_k_estimates(0.5 * (q.T @ red.schur @ q), q.T @ m_kk @ q)
        self._counts["eigen_solves"] += 1
        if estimates.size == 0:
            return None
        return root_search_near(self._scp_reduced, float(estimates[0]), r=r)

    def _line_evaluator(self, mode: str, backend: str, pins: np.ndarray | None = None,
                        pin_values: np.ndarray | None = None) -> tuple[Callable[[float], KPoint], bool]:
        """The function k -> KPoint the line search evaluates, and whether it works on the boundary reduction.

        The reduced SCP needs B on the boundary (it is B's support); DNCP's reduction keeps
        the pins, so any B works there. SCP is evaluated with ``allow_negative`` because
        the search has to cross the region where the energy is negative.
        """
        use_b = self._use_boundary(backend)
        if mode == "scp":
            if use_b and self.b_on_boundary:
                return self._scp_reduced, True
            return partial(self._scp_sparse, allow_negative=True), False
        if use_b:
            return partial(self._dncp_reduced, pins=pins, pin_values=pin_values), True
        return partial(self._dncp_sparse, pins=pins, pin_values=pin_values), False

    def _finish(self, sol: ConformalSolution, mode: str, k_search: str, diag: dict) -> ConformalSolution:
        """Refuse an irregular searched map or non-finite coordinates; fill in the diagnostics."""
        regular = is_regular_turning(sol.turning)
        if not regular and k_search != "none":
            raise hinted(
                SolverError,
                f"the {mode} map at k_opt = {sol.k:.6g} is not a regular flattening: boundary turning numbers "
                f"{sol.turning.tolist()} (expected one +1 and -1 per hole)",
                Hint("try other weights", "weights"), Hint("try other pins", "pins"),
            )
        # With k fixed the map is the method's answer even when its boundary curls over
        # (a quality defect the benchmark measures, like foldovers), so it is returned
        # with regular_boundary = False rather than refused.
        diag["regular_boundary"] = bool(regular)
        if not np.all(np.isfinite(sol.z)):
            raise SolverError(f"the {mode} solve produced non-finite coordinates; the system is near-singular.")
        sol.diagnostics.update(diag)
        sol.diagnostics.update(k_opt=float(sol.k), energy=float(sol.energy), turning_numbers=sol.turning.tolist(),
                               hermitian=bool(self.hermitian), **{f"n_{key}": int(v) for key, v in self.counts.items()})
        if sol.eigenvalue is not None:
            sol.diagnostics["eigenvalue"] = float(np.real(sol.eigenvalue))
        return sol


def _checked_names(mode: str, k_search: str) -> tuple[str, str]:
    """``(mode, k_search)`` unchanged when both are known.

    Raises
    ------
    UnknownNameError
        Unknown mode or k_search (mode is checked first).
    """
    if mode not in ("scp", "dncp"):
        raise UnknownNameError(f"unknown mode {mode!r}; choose 'scp' or 'dncp'.")
    if k_search not in K_SEARCH_MODES:
        raise UnknownNameError(f"unknown k_search {k_search!r}; choose one of {', '.join(K_SEARCH_MODES)}.")
    return mode, k_search


def solve_line_then_direct(problem: ConformalProblem, mode: str, pins=None, hints: Sequence[Hint] = ()
                           ) -> ConformalSolution:
    """The line search; where it finds no bracket, k_opt from the generalised eigenproblem.

    The good region (regular and q >= 0) can be far narrower than a geometric step: DNCP
    on ``real/bunny10k`` (cotangent, 5 boundary loops) is regular only within about 1e-3
    of k_opt = 0.97456, and the small holes turn inside out on either side, so stepping
    up from k = 1 never found it. ``k_search="direct"`` computes that k without stepping.

    Parameters
    ----------
    problem : ConformalProblem
    mode : {"scp", "dncp"}
    pins : (int, int), optional
        DNCP's pinned vertices.
    hints : sequence of Hint
        Remedies the caller knows when both searches fail (each search's own hint names
        the other, which was just tried, so neither is repeated).

    Returns
    -------
    ConformalSolution
        ``diagnostics["k_search_fallback"] = "direct"`` and ``line_search_error`` when the
        direct search gave it.

    Raises
    ------
    ConvergenceError
        Both searches failed; the message names both failures and ``hints``.
    """
    try:
        return problem.solve(mode, "line", pins=pins)
    except ConvergenceError as err:
        line_error = err
    if not problem.exact_fallbacks:
        # No k_search hint: the caller runs the exact searches itself if its fallback fails.
        raise hinted(ConvergenceError,
                     f"no regular {mode} map found: the line search failed ({_first_clause(line_error)}); "
                     f"the exact searches were left for the caller's fallback", *hints) from None
    if not problem.exact_fallback_affordable():
        raise hinted(ConvergenceError,
                     f"no regular {mode} map found: the line search failed ({_first_clause(line_error)}); "
                     f"k_search='direct' was not tried on {problem.boundary.size} boundary points (over "
                     f"{EXACT_FALLBACK_MAX_BOUNDARY}, its dense eigen-solves take minutes)",
                     *hints, Hint("use k_search='direct' to try it anyway", "k_search", "direct")) from None
    try:
        # Non-symmetric weights: each candidate costs a dense eigen-solve, and only the largest
        # are plausible (see FALLBACK_NONSYMMETRIC_CANDIDATES).
        sol = problem.solve(mode, "direct", pins=pins,
                            max_candidates=None if problem.hermitian else FALLBACK_NONSYMMETRIC_CANDIDATES)
    except (SolverError, ConvergenceError) as direct_error:
        raise hinted(ConvergenceError,
                     f"no regular {mode} map at any k: the line search failed ({_first_clause(line_error)}) and "
                     f"k_search='direct' too ({_first_clause(direct_error)})", *hints) from None
    sol.diagnostics["k_search_fallback"] = "direct"
    sol.diagnostics["line_search_error"] = str(line_error)
    return sol


def _first_clause(err: Exception) -> str:
    """An error's message without its trailing hints (they follow the first '; ')."""
    return str(err).split("; ")[0].rstrip(".")
