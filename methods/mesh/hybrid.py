"""Hybrid weights as Sec. 5 (Fig. 12) means them: uniform only where cotangent weights fold the map.

Negative cotangent weights are common (every non-Delaunay edge has one) and mostly
harmless; only some of them fold the map over. The rule here is local and driven by the
map itself: solve with cotangent weights, take the flipped triangles, make their vertices
and ``rings`` rings of neighbours uniform (:func:`parambench.methods.mesh.weights.mesh_weights` with a
vertex mask), solve again, and repeat while folds remain, growing the uniform region
around the flipped triangles and the vertices already chosen by ``r * rings`` rings in
round r (at most ``max_rounds`` rounds). A mesh whose cotangent map does not
fold keeps pure cotangent weights. (The earlier rule, uniform at every vertex with a
negative cotangent weight, made 51 % of the vertices of ``real/camelhead`` uniform and
raised its QC from 1.073 to 2.017, where this rule makes none uniform because the
cotangent map does not fold; it is still available as ``uniform_at="negative"``.)
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import scipy.sparse as sp

from parambench.datasets_gen.surface import MethodInput

from ..base import StageTimer
from ..geometry2d import flipped_triangles
from ..spectral import ConformalProblem
from ..spectral.problem import ConformalSolution
from .conformal_setup import build_mesh_problem

__all__ = ["HYBRID_RINGS", "HYBRID_MAX_ROUNDS", "flipped_faces", "grow_rings", "fold_driven_hybrid"]

#: Rings of neighbours made uniform around the vertices of flipped triangles in the first
#: round; round r grows the region by r * HYBRID_RINGS rings where folds are left.
HYBRID_RINGS = 1
#: Re-solves at most.
HYBRID_MAX_ROUNDS = 8


def flipped_faces(z: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Triangles whose orientation in the map opposes the majority (a global mirror is no flip).

    Parameters
    ----------
    z : (N,) numpy.ndarray of complex128
        The map, ``u + i v``.
    faces : (M, 3) numpy.ndarray of int64

    Returns
    -------
    (M,) numpy.ndarray of bool
        Collapsed triangles (zero uv area) are not flipped
        (:func:`parambench.methods.geometry2d.flipped_triangles` of ``(u, v)``).
    """
    return flipped_triangles(np.column_stack([z.real, z.imag]), faces)


def grow_rings(mask: np.ndarray, faces: np.ndarray, rings: int) -> np.ndarray:
    """``mask`` and every vertex within ``rings`` edges of it.

    Parameters
    ----------
    mask : (N,) numpy.ndarray of bool
    faces : (M, 3) numpy.ndarray of int64
    rings : int
        Non-negative.

    Returns
    -------
    (N,) numpy.ndarray of bool
    """
    n = mask.shape[0]
    i = faces.ravel()
    j = np.roll(faces, -1, axis=1).ravel()
    adj = sp.csr_matrix((np.ones(2 * i.size, dtype=np.int8), (np.concatenate([i, j]), np.concatenate([j, i]))),
                        shape=(n, n))
    out = mask.copy()
    for _ in range(rings):
        out |= np.asarray(adj @ out.astype(np.int8)).ravel() > 0
    return out


def fold_driven_hybrid(surface: MethodInput, timer: StageTimer, solve: Callable[[ConformalProblem], ConformalSolution], *,
                       normalized: bool, b_matrix: str, rings: int = HYBRID_RINGS,
                       max_rounds: int = HYBRID_MAX_ROUNDS
                       ) -> tuple[ConformalProblem, ConformalSolution, list[np.ndarray], dict]:
    """Solve with cotangent weights, then with uniform weights around the folds until none are left.

    Parameters
    ----------
    surface : MethodInput
        With faces.
    timer : StageTimer
        Records ``topology`` and ``weights`` (as :func:`build_mesh_problem`); the solves are
        timed by the caller's ``solve``.
    solve : callable
        ``solve(problem) -> ConformalSolution``: the method's own solve (SCP or DNCP, with
        its k rule), called once per round.
    normalized, b_matrix
        As in :func:`build_mesh_problem`.
    rings : int
        Rings of neighbours made uniform around each flipped triangle in the first round
        (``r * rings`` in round r).
    max_rounds : int
        Re-solves at most; the last map is returned even if folds are left
        (``diagnostics["hybrid_foldovers"] > 0``), since the benchmark measures them.

    Returns
    -------
    problem : ConformalProblem
        Of the last round.
    solution : ConformalSolution
    loops : list of (L_i,) numpy.ndarray of int64
    info : dict
        ``n_boundary_loops``, ``n_uniform_rows`` and ``uniform_share`` (vertices with uniform
        weights), ``hybrid_rounds`` (re-solves), ``cotangent_foldovers`` (flipped triangles
        of the cotangent map) and ``hybrid_foldovers`` (of the returned map).

    Raises
    ------
    SolverError, ConvergenceError, DisconnectedError, NotADiskError, InvalidInputError
        From :func:`build_mesh_problem` and ``solve``.
    """
    faces = surface.faces
    problem, loops, info = build_mesh_problem(surface, timer, weights="cotangent", normalized=normalized,
                                              uniform_at=None, b_matrix=b_matrix)
    sol = solve(problem)
    flipped = flipped_faces(sol.z, faces)
    n_cot_folds = int(flipped.sum())
    chosen = np.zeros(surface.n_points, dtype=bool)
    rounds = 0
    while flipped.any() and rounds < max_rounds:
        rounds += 1
        seeds = chosen.copy()
        seeds[faces[flipped].ravel()] = True
        # Growing faster each round keeps the number of solves small where a fold needs a
        # wide uniform region, while a fold that one ring removes costs only that ring.
        chosen = grow_rings(seeds, faces, rings * rounds)
        problem, loops, info = build_mesh_problem(surface, timer, weights="hybrid", normalized=normalized,
                                                  uniform_at=chosen, b_matrix=b_matrix)
        sol = solve(problem)
        flipped = flipped_faces(sol.z, faces)
    info.update(n_uniform_rows=int(chosen.sum()), uniform_share=float(chosen.mean()), hybrid_rounds=rounds,
                cotangent_foldovers=n_cot_folds, hybrid_foldovers=int(flipped.sum()))
    return problem, sol, loops, info
