"""Glue between a triangle mesh and the spectral core: Laplacian, loops, B, pins, output scale."""

from __future__ import annotations

from typing import Any

import igl
import numpy as np

from parambench.datasets_gen.errors import ConvergenceError, InvalidInputError, SolverError, UnknownNameError
from parambench.datasets_gen.surface import MethodInput

from ..base import StageTimer
from ..hints import Hint, hinted
from ..spectral import ConformalProblem
from ..spectral.problem import solve_line_then_direct
from .pins import farthest_pair
from .quad_splits import split_averaged_cotangent
from .topology import require_connected_disk_like
from .weights import laplacian, mesh_weights, uniform_vertex_mask

__all__ = ["B_MATRICES", "build_mesh_problem", "resolve_pins", "scale_to_surface_area", "default_k_search",
           "solve_with_k_rule", "k_start_estimate"]

B_MATRICES = ("boundary", "mass")


def default_k_search(weights: str, normalized: bool) -> str:
    """``"none"`` (k = 1) for weights at the cotangent scale, ``"line"`` for the others.

    Cotangent, (regular-polygon scaled) uniform and hybrid weights (a mix of the two) have
    k_opt within about 1e-3 of 1 where k = 1 is positive semi-definite; authalic,
    mean-value and every normalized kind need the search. Where k = 1 is indefinite
    (uniform weights on an irregular scan) :func:`solve_with_k_rule` falls back to the search.
    """
    return "none" if weights in ("cotangent", "uniform", "hybrid") and not normalized else "line"


#: :func:`k_start_estimate` keeps k = 1 unless the estimate is below 1 / K_START_FACTOR.
K_START_FACTOR = 2.0


def k_start_estimate(points: np.ndarray, faces: np.ndarray, lap) -> float:
    """Where the k line search starts: ``A / E_L(x)`` where that is below 1/2, else 1.

    ``A`` is the surface area and ``E_L(x) = 1/2 tr(X^T L X)`` the energy of the 3D
    embedding X under the Laplacian L. For cotangent weights ``E_L(x) = A`` exactly (the
    Dirichlet energy of the identity on each triangle is its area), so the ratio is 1;
    for weights at another scale it is the k at which ``k E_L`` matches the conformal
    scale, a rough estimate of k_opt (measured: 0.00096 vs k_opt 0.00096-0.0015 for
    authalic weights on ``real/bump-domain``; 80x low on ``real/camelhead``). It is only
    used below 1 (the search steps *up* from a map that is not regular, and above k_opt
    a pinned (DNCP) map degenerates rather than settling: authalic DNCP on
    ``real/bump-domain`` stepped up from k = 1 to 7523 without finding k_opt = 0.001, so
    starting below k_opt is safe, far above it is not), and only below 1/2: see the comment
    in the code.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    faces : (M, 3) numpy.ndarray of int64
    lap : (N, N) scipy.sparse matrix of float64
        L = D - W.

    Returns
    -------
    float
        In (0, 1/2) or exactly 1 (also when the embedding energy is not positive).
    """
    area = float(np.sum(igl.doublearea(points, faces)) / 2.0)
    energy = 0.5 * float(np.einsum("ij,ij->", points, lap @ points))
    if not (energy > 0 and area > 0):
        return 1.0
    ratio = area / energy
    # Within a factor K_START_FACTOR of the cotangent scale (uniform: 0.70-0.98 on the real
    # meshes; hybrid) the paper's start k = 1 is kept: the landscape can have several
    # good windows near 1, and a different start picks a different one (hybrid
    # "negative" on a spiked saddle: k_opt 1.0169 with 1 foldover instead of 1.0226 with 0).
    return float(ratio) if ratio < 1.0 / K_START_FACTOR else 1.0


def _line_then_direct(problem: ConformalProblem, mode: str, pins):
    """:func:`~parambench.methods.spectral.problem.solve_line_then_direct` with the mesh methods' remedies."""
    hints = [Hint("try normalized=False", "normalized", False)]
    if mode == "dncp":
        # With non-symmetric weights no map has zero energy, so DNCP's answer depends on
        # the pins: authalic normalized DNCP on real/bump-domain curls (turning 3) at every
        # k with the farthest pins, and is regular for 7 of 10 other boundary pairs tried.
        hints.append(Hint("try other pins ('i,j', two boundary vertices)", "pins"))
    hints.append(Hint("try other weights", "weights"))
    return solve_line_then_direct(problem, mode, pins, hints)


def solve_with_k_rule(problem: ConformalProblem, mode: str, k_search: str, *, weights: str, normalized: bool,
                      pins: tuple[int, int] | None = None):
    """Solve with the given ``k_search``, or for ``"auto"`` with k = 1 and the line search as fallback.

    Parameters
    ----------
    problem : ConformalProblem
    mode : {"scp", "dncp"}
    k_search : {"auto", "none", "line", "direct"}
        ``"auto"``: :func:`default_k_search`; when that is k = 1 and the solve fails (the
        energy is indefinite at k = 1, so the map would spin) or the boundary spins, the
        line search (Eq. 16). ``"line"`` (and the line search of ``"auto"``) falls back to
        ``"direct"`` where the search finds no t = 1 crossing (a good region narrower than
        its steps); ``diagnostics["k_search_fallback"]`` is then ``"direct"``.
    weights, normalized
        The weights the problem was built with.
    pins : (int, int), optional
        DNCP's pinned vertices.

    Returns
    -------
    ConformalSolution
        ``diagnostics["k_fallback"]`` is True when k = 1 failed or spun and the searched
        map is returned.

    Raises
    ------
    SolverError, ConvergenceError
        From :meth:`ConformalProblem.solve` (for ``"auto"``, the search's error).
    """
    if k_search == "line":
        return _line_then_direct(problem, mode, pins)
    if k_search != "auto":
        return problem.solve(mode, k_search, pins=pins)
    k_search = default_k_search(weights, normalized)
    if k_search != "none":
        return _line_then_direct(problem, mode, pins)
    try:
        sol = problem.solve(mode, "none", pins=pins)
    except SolverError:
        # k = 1 is only guaranteed positive semi-definite for cotangent weights; where it
        # is not, the search finds the k at which the map stops spinning instead of refusing.
        sol = _line_then_direct(problem, mode, pins)
        sol.diagnostics["k_fallback"] = True
        return sol
    if sol.diagnostics.get("regular_boundary", True):
        return sol
    # A boundary that spins at k = 1 (uniform or hybrid weights are not the exact Dirichlet
    # energy) is what the search of Eq. 16 is for; if it finds nothing, the k = 1 map is
    # the answer, reported with regular_boundary = False as before.
    try:
        searched = _line_then_direct(problem, mode, pins)
    except (SolverError, ConvergenceError):
        return sol
    searched.diagnostics["k_fallback"] = True
    return searched


def build_mesh_problem(surface: MethodInput, timer: StageTimer, *, weights: str, normalized: bool, uniform_at: Any,
                       b_matrix: str, averaged_quads: tuple[np.ndarray, np.ndarray] | None = None
                       ) -> tuple[ConformalProblem, list[np.ndarray], dict]:
    """Check the mesh and set up the conformal problem.

    Parameters
    ----------
    surface : MethodInput
        With faces.
    timer : StageTimer
        Stages ``topology`` and ``weights`` are recorded.
    weights, normalized, uniform_at
        See :func:`parambench.methods.mesh.weights.mesh_weights` (a hybrid ``uniform_at`` of
        ``"auto"`` must be resolved first: :mod:`parambench.methods.mesh.hybrid`; an authalic
        one is the fallback of :mod:`parambench.methods.mesh.fallbacks`).
    b_matrix : {"boundary", "mass"}
        Mullen's boundary indicator, or libigl's Voronoi mass matrix (what
        ``igl.spectra.lscm`` uses).
    averaged_quads : (split, flipped), optional
        Quads whose two splits' cotangent weights are averaged
        (:func:`parambench.methods.mesh.quad_splits.ambiguous_quads`); cotangent weights
        without ``normalized`` only.

    Returns
    -------
    problem : ConformalProblem
    loops : list of (L_i,) numpy.ndarray of int64
        Boundary loops, longest first, oriented with the faces.
    info : dict
        Diagnostics: ``n_boundary_loops``, ``n_uniform_rows`` (hybrid, and authalic with
        ``uniform_at``, then also ``uniform_share``).

    Raises
    ------
    DisconnectedError, NotADiskError
        From :func:`parambench.methods.mesh.topology.require_connected_disk_like`.
    UnknownNameError
        Unknown weights or b_matrix.
    InvalidInputError
        Bad uniform_at or unnormalizable weights.
    """
    if b_matrix not in B_MATRICES:
        raise UnknownNameError(f"unknown b_matrix {b_matrix!r}; choose one of {', '.join(B_MATRICES)}.")
    pts, faces = surface.points, surface.faces
    with timer("topology"):
        loops = require_connected_disk_like(pts, faces)
    info: dict = {"n_boundary_loops": len(loops)}
    with timer("weights"):
        if weights == "hybrid" or (weights == "authalic" and uniform_at is not None):
            uniform_at = uniform_vertex_mask(uniform_at, pts, faces, kind=weights)
            info["n_uniform_rows"] = int(uniform_at.sum())
            if weights == "authalic":
                info["uniform_share"] = float(uniform_at.mean())
        w = mesh_weights(pts, faces, weights, normalized=bool(normalized), uniform_at=uniform_at)
        if averaged_quads is not None:
            if weights != "cotangent" or normalized:
                raise InvalidInputError("averaged_quads averages cotangent weights; it does not apply to "
                                        f"{'normalized ' if normalized else ''}{weights} weights.")
            w = split_averaged_cotangent(pts, w, *averaged_quads)
            info["n_averaged_quads"] = int(averaged_quads[0].shape[0] // 2)
        b = "boundary" if b_matrix == "boundary" else igl.massmatrix(pts, faces, igl.MASSMATRIX_TYPE_VORONOI)
        # Cotangent weights give the exact Dirichlet energy of the piecewise-linear map,
        # which bounds the image area on every triangle: the energy is PSD for k >= 1
        # (averaged quads too: both splits' images cover the same quadrilateral).
        psd = 1.0 if weights == "cotangent" and not normalized else None
        lap = laplacian(w)
        problem = ConformalProblem(lap, loops, b_matrix=b, points=pts, psd_from_k=psd,
                                   k_start=k_start_estimate(pts, faces, lap))
    return problem, loops, info


def resolve_pins(pins: Any, points: np.ndarray, loops: list[np.ndarray]) -> tuple[int, int]:
    """The two pinned vertices of DNCP.

    Parameters
    ----------
    pins : "farthest", "i,j" or a pair of int
        ``"farthest"``: the two boundary vertices farthest apart in 3D.
    points : (N, 3) numpy.ndarray of float64
    loops : list of (L_i,) numpy.ndarray of int64

    Returns
    -------
    (int, int)

    Raises
    ------
    InvalidInputError
        Not two distinct in-range vertex indices.
    """
    if isinstance(pins, str):
        if pins == "farthest":
            return farthest_pair(points, np.concatenate(loops))
        try:
            pair = [int(s) for s in pins.replace(";", ",").split(",")]
        except ValueError:
            raise InvalidInputError(f"pins={pins!r} is neither 'farthest' nor 'i,j' (two vertex indices).") from None
    else:
        pair = [int(v) for v in np.asarray(pins).ravel()]
    n = points.shape[0]
    if len(pair) != 2 or pair[0] == pair[1] or min(pair) < 0 or max(pair) >= n:
        raise InvalidInputError(f"pins must be two distinct vertex indices in [0, {n - 1}], got {pins!r}.")
    return pair[0], pair[1]


def scale_to_surface_area(z: np.ndarray, problem: ConformalProblem, points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """uv = z scaled so that the area enclosed by its boundary equals the 3D surface area.

    Returns
    -------
    (N, 2) numpy.ndarray of float64

    Raises
    ------
    SolverError
        The map encloses no positive area (collapsed or inverted).
    """
    area_uv = float(np.real(np.vdot(z, problem.area @ z)))
    area_3d = float(np.sum(igl.doublearea(points, faces)) / 2.0)
    if not area_uv > 0:
        raise hinted(SolverError, f"the map encloses area {area_uv:.3g} <= 0 (collapsed or inverted)",
                     Hint("try other weights", "weights"))
    zc = (z - z.mean()) * np.sqrt(area_3d / area_uv)
    return np.column_stack([zc.real, zc.imag])
