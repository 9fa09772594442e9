"""``ocp``: the conformal energy on W^tan with the k search (Sec. 4.2).

``scp-tan`` (:mod:`parambench.methods.plugins.scp_tan`) is the ``"paper"`` energy below at a fixed k,
without the search.

``ocp``'s ``energy`` option chooses the Laplacian of the conformal energy ``k L / 2 - M``:

* ``"paper"``: ``L = I - W^tan`` as in Sec. 4.2; the global k of Eq. 15 (k_opt ~ 10-25)
  stands in for the per-point scale of Eq. 14 and for the boundary term of the
  Dirichlet energy that row-normalised, linear-reproducing rows lose.
* ``"neumann-tan"``: W^tan rows scaled by their Eq. 14 factor plus the Neumann boundary
  term (:func:`parambench.methods.pointset.neumann_laplacian.neumann_laplacian` with W^tan rows).
* ``"neumann"`` (default): the same with quadratic-consistent interior weights and
  linear-exact boundary weights; k_opt ~ 1, and exact (k = 1, identity map) on planar
  regions.

Measured on bump, saddle, cap and holes at 5k points, grid and jittered sampling, QC mean
on the ground-truth mesh relative to cotangent SCP (scp-igl): "paper" +0.8 to +6.7 %,
"neumann" +0.00 to +0.06 %, 0 foldovers in both (see tests/methods/test_ocp_accuracy.py).
"""

from __future__ import annotations

import numpy as np

from parambench.datasets_gen.errors import (ConvergenceError, InvalidInputError, ParambenchError, SolverError,
                                            TopologyError, UnknownNameError, released)
from parambench.datasets_gen.surface import MethodInput

from ..base import Method, MethodOutput, StageTimer, retry_memo
from ..memory_budget import PeakMemory
from ..hints import Hint, error_note, hinted
from ..geometry2d import signed_area_2d
from ..mesh.holes import HOLES_MODES, solve_with_holes
from ..mesh.quad_splits import SPLIT_TOLERANCE_DEG
from ..pointset.boundary_first_map import boundary_first_map
from ..pointset.hole_filling import fill_point_holes, is_slot
from ..pointset.laplacian import graph_laplacian
from ..pointset.mesh_refine import MAX_MESH_PASSES, first_map_faces, mesh_passes, refine_on_uv_mesh
from ..pointset.two_level import coarse_subsample, two_level_sdp_pair
from ..pointset.neumann_laplacian import DEFAULT_AREA_FACTOR, neumann_laplacian
from ..pointset.plugin_support import (BOUNDARY_HINTS, FRONTEND_DEFAULTS, check_inputs_of, coverage_retries,
                                      frontend_diagnostics, restore_check_inputs, run_frontend, scale_to_spacing,
                                      with_shape_cause)
from ..registry import register
from ..spectral import ConformalProblem
from ..spectral.dirichlet import b_orthonormalize, direct_sdp_pair
from ..spectral.problem import solve_line_then_direct
from ..spectral.multilevel import FINE_SOLVERS, MultilevelSettings

#: ``solver`` values of ``ocp``: the single-level solve, the two-level one of
#: :mod:`parambench.methods.spectral.multilevel`, or ``"auto"`` (the default): two-level
#: from :data:`MULTILEVEL_FROM` points on, with the line search.
OCP_SOLVERS = ("auto", "direct", "multilevel")

#: Points from which ``solver="auto"`` takes the two-level path. Measured (jittered, 2
#: cores, same process, end to end): at 300k points multilevel 30.3 / 42.8 / 35.9 s
#: against direct 48.1 / 42.7 / 46.9 s on bump / holes / cap, k_opt equal to 4e-6, QC to
#: 4e-6, uv to 4.7e-4 of the diameter, 0 foldovers both; at 100k (bump) the two within
#: 10 % of each other (fine level 3.7 s against 4.0 s); below that the direct path wins.
#: Since the two-grid workers and the leaf order (one run each, quiet): at 100k bump /
#: holes / cap multilevel 5.4 / 4.6 / 8.6 s against direct 7.9 / 6.2 / 8.3 s (the cap's
#: Davidson steps take 62 cycles), so the threshold stays until the cap's steps are cheaper.
MULTILEVEL_FROM = 200_000

#: ``polish_spread`` default: a two-level map whose local scale varies more than this
#: many times is polished in the full space (protrusions 329 at 100k points, the other
#: generated surfaces 1.0-1.7; two-level maps, on the coarse points).
POLISH_SPREAD = MultilevelSettings.polish_spread


#: ``refine`` values of ``ocp``: ``"auto"`` refines only a map the point-set energies
#: could not give (:func:`_mesh_fallback`), ``"mesh"`` every map, ``"none"`` never.
REFINE_MODES = ("auto", "mesh", "none")


#: ``energy`` values of ``ocp`` -> (interior rows, boundary rows) of the Neumann Laplacian.
OCP_ENERGIES = {"paper": None, "neumann-tan": ("tangent", "tangent"), "neumann": ("quadratic", "linear")}


def conformal_problem(front, laplacian=None, **options) -> ConformalProblem:
    """The conformal problem of a front end: its boundary loops, B the boundary indicator.

    Parameters
    ----------
    front : parambench.methods.pointset.frontend.FrontEnd
    laplacian : (N, N) scipy.sparse matrix, optional
        The Laplacian L; ``front.L`` (``I - W^tan``) when omitted.
    **options
        Further keyword arguments of :class:`~parambench.methods.spectral.ConformalProblem`.

    Returns
    -------
    parambench.methods.spectral.ConformalProblem
    """
    lap = front.L if laplacian is None else laplacian
    return ConformalProblem(lap, front.boundary_loops, b_matrix="boundary", points=front.points, **options)


def ocp_laplacian(front, energy: str = "neumann", area_factor: float = DEFAULT_AREA_FACTOR):
    """The Laplacian of ``ocp`` for an ``energy`` option (see the module docstring).

    Parameters
    ----------
    front : parambench.methods.pointset.frontend.FrontEnd
    energy : {"paper", "neumann-tan", "neumann"}
    area_factor : float
        Area per point in units of l^2 (Neumann energies only).

    Returns
    -------
    (N, N) scipy.sparse.csr_matrix of float64

    Raises
    ------
    UnknownNameError
        Unknown ``energy``.
    """
    if energy not in OCP_ENERGIES:
        raise UnknownNameError(f"unknown energy {energy!r}; choose one of {', '.join(OCP_ENERGIES)}.")
    rows = OCP_ENERGIES[energy]
    if rows is None:
        return front.L
    return neumann_laplacian(front.ball_indices, front.tangent_coords, front.boundary_loops, front.local_spacing,
                             interior=rows[0], boundary=rows[1], tangent_w=front.W, area_factor=float(area_factor))


#: ``retry_k_nn`` default (see :meth:`Ocp.retry_params`).
RETRY_K_NN = 12


@register
class Ocp(Method):
    """Optimized conformal parameterization: SCP on ``k L - A`` with k from Eq. 16.

    ``k_search="line"``: search forward from k = 1 until the boundary turning number is
    1, then minimise within that step (the paper's procedure; the landscape is kept).
    ``"direct"``: k_opt as the largest (near-)real generalised eigenvalue of the
    area/Dirichlet pencil with a regular map; it matches the line search to ~1e-7 in k
    at a fifth to a third of its time (``bench/benchmarks/bench_ksearch.py``).
    ``energy``: the Laplacian L, see the module docstring ("paper" is Sec. 4.2 to the
    letter; "neumann", the default, adds the per-point scale of Eq. 14 and the boundary
    term of the Dirichlet energy). ``area_factor``: area per point / l^2 ("neumann*" only).
    ``solver``: ``"auto"`` (default) is ``"multilevel"`` from :data:`MULTILEVEL_FROM`
    points on (line search only) and ``"direct"`` below; ``"direct"`` solves on every point; ``"multilevel"`` first
    solves on a Poisson-disk subsample (radius 2 l, boundary loops kept) and uses that
    map to shrink the fine k search to a ~20-function boundary subspace
    (:mod:`parambench.methods.spectral.multilevel`; line search only). Measured against "direct"
    at 20k-300k points: the same k_opt to 3e-5 and map to 8.3e-4 of the diameter
    (1e-4 or better except on a random sampling). ``fine_solver``: ``"twogrid"``
    (default) solves the fine interior by two-grid cycles on the coarse factorisation
    (no fine factorisation), ``"direct"`` factorises it. ``map_error`` (two levels,
    two-grid solves): when the fine map's error estimate (boundary residual over the gap
    to the next Ritz value, ``map_error_estimate`` in the diagnostics; at a million
    points 0.08-0.19 with the default solves, 1e-3 to 1e-2 at 20k) is above this, the
    solves are tightened and the search settled again (:mod:`parambench.methods.spectral.multilevel`);
    null (default): only where the fine k search did not settle while its refinement
    sat at the solves' floor (a jittered cylinder at 1M points: 4.2e-3 -> 3.4e-5 of the
    diameter from the direct map). ``polish_residual`` (two levels; default null = off):
    when the fine map's relative residual in the full space (``k L / 2 - M`` and B on
    every point, a sparse product; ``full_space_residual_before`` in the diagnostics) is
    above this (0: always), the map is polished there by Davidson steps with a two-grid
    preconditioner (:mod:`parambench.methods.spectral.full_space_polish`): at 1M points on
    ``protrusions`` 2.5e-3 of the diameter off the exact eigenvector -> 2.4e-5 (the direct
    path's map: 5.5e-4) in 20 steps. Off by default: the residual does not tell the maps
    that need it (protrusions 3.8e-8) from those that do not (cap 2.3e-8, whose polish
    took it from 55 to 85 s). ``polish_spread`` (two levels; default 20, null = never)
    tells them apart: the map is polished whatever its residual when its local scale
    (uv over 3D distance to its neighbours in the Laplacian, at the coarse points) varies more than
    this many times between the 1st and 99th percentile, as a conformal map shrinks a
    protrusion (``map_scale_spread`` in the diagnostics; at 100k points protrusions 329,
    every other generated surface 1.0-1.7; at 1M protrusions 361, bump 1.71, cap 1.33).
    Protrusions at 1M then take 108-110 s instead of 72 s and 3.9 GiB peak instead of
    3.5, and their map is 1.5e-6 of the diameter from the polished one above. A map whose
    fine k search did not settle is polished too (``polish_unsettled`` in the
    diagnostics; :class:`~parambench.methods.spectral.multilevel.MultilevelSettings`). End to end at 1M points
    (bump / holes / cap, quiet 2 cores) 51 / 52 / 48 s and 2.8 GiB peak; at 300k 0.37-0.39x
    the time of ``scp-igl`` on the true mesh (see bench/MEASUREMENTS.md).
    ``retry_k_nn``: when the map fails its self-check with flipped triangles and
    ``k_nn`` is smaller, ocp runs once more with this ``k_nn`` and keeps that map if it
    passes (:meth:`retry_params`); 0 turns the retry off. A map of the default Neumann
    energy that crosses its boundary or spins is tried once more with the paper's energy
    (after the ``k_nn`` retry, if that ran). ``holes``: ``"auto"`` (default)
    solves with the holes free and, where that raises ConvergenceError / SolverError or
    turns a hole inside out, fills each hole with points and solves again
    (:mod:`parambench.methods.pointset.hole_filling`; ``holes_filled`` and
    ``n_fill_points`` in the diagnostics); ``"free"`` / ``"filled"`` force one. With the
    default ``energy="neumann"``, a k search that finds no regular map is followed by one
    with the paper's energy (:func:`_paper_energy_fallback`; ``energy_used`` in the
    diagnostics), before any hole is filled. ``refine``: ``"mesh"`` triangulates the map
    in uv (the self-check's triangulation) and returns cotangent SCP on that mesh, on
    clean points solved again on the refined map's own triangulation until it stops
    changing (:mod:`parambench.methods.pointset.mesh_refine`); ``"auto"`` (default) does so only
    where the Neumann energy gave no map (from the paper energy's map, or where that
    failed too from the map of the unrolled boundary (one loop), an SDP map, or, where
    those give no mesh and the surface is a height field over the plane across its mean
    normal, from the points projected on it, :func:`_mesh_fallback`, ``energy_used`` then
    ``"mesh"``, ``refined["first_map"]`` which;
    from :data:`MULTILEVEL_FROM` points on W^tan for these is rebuilt,
    :class:`TangentWeights`, and on the two-level path they keep to two levels), where
    the points are a lattice (a raster, a range image, a grid sampling; below
    :data:`MULTILEVEL_FROM` points; see :func:`_refines`) and as the last retry of a
    map that fails its self-check; ``"none"`` never. ``refined`` in the diagnostics says
    from which map (``first_map``, and its k as ``first_k_opt``), with how many
    triangles and solves (``n_passes``); ``k_opt`` is then the mesh's (1 for cotangent
    weights).
    """

    name = "ocp"
    description = "optimized conformal parameterization, k line search (points only; Sec. 4.2)"
    conformal_map = True
    nullable = frozenset({"polish_spread"})  # null: never polish whatever the spread
    # Uniform random points (bump), where the two-grid solve diverges and falls back to a
    # factorisation: 1M points 5.43 GiB at the peak, 3M 16.99 GiB (jittered 1M: 2.7 GiB).
    peak_memory = PeakMemory(3_000_000, 16.99 * 2**30, 1.04)
    defaults = {**FRONTEND_DEFAULTS, "k_search": "line", "energy": "neumann", "area_factor": DEFAULT_AREA_FACTOR,
                "solver": "auto", "fine_solver": "twogrid", "map_error": None, "polish_residual": None,
                "polish_spread": POLISH_SPREAD, "retry_k_nn": RETRY_K_NN,
                "holes": "auto", "refine": "auto"}
    param_grid = {"k_search": ["line", "direct"], "energy": list(OCP_ENERGIES)}
    choices = {"solver": OCP_SOLVERS, "energy": tuple(OCP_ENERGIES), "fine_solver": FINE_SOLVERS, "holes": HOLES_MODES,
               "refine": REFINE_MODES}

    def inert_params(self, params: dict, n_points: int | None = None) -> dict[str, str]:
        """``reg_eps`` under ``energy="neumann"``, ``area_factor`` under ``energy="paper"``, and
        the two-level parameters where the direct path runs (``solver="direct"``, or
        ``"auto"`` below :data:`MULTILEVEL_FROM` points: ``map_error=0.02`` on 2,000 points
        said nothing and changed nothing).

        ``reg_eps`` regularises the W^tan rows, which the default Neumann energy does not
        use (its rows are moment fits) but in its fallback to the paper's energy: passed
        with the default energy it changed no map (bump, 1500 random points: uv identical
        for 0.01 and 0.3).
        """
        inert = {}
        if params["energy"] == "neumann":
            inert["reg_eps"] = ("does not act on the default energy: it regularises the W^tan weights, which "
                                "energy='neumann' uses only if it falls back to the paper's energy; pass "
                                "energy='paper' or 'neumann-tan' for it to act")
        if params["energy"] == "paper":
            inert["area_factor"] = ("has no effect: only the Neumann energies have an area term; pass energy='neumann' "
                                    "or 'neumann-tan'")
        direct = params["solver"] == "direct" or (
            params["solver"] == "auto" and n_points is not None
            and resolve_solver("auto", n_points, params["k_search"]) == "direct")
        if direct:
            where = ("solver='direct' takes the direct one" if params["solver"] == "direct" else
                     f"on {n_points} points solver='auto' takes the direct one (two levels from {MULTILEVEL_FROM} "
                     "points on, or with solver='multilevel')")
            for key in ("fine_solver", "map_error", "polish_residual", "polish_spread"):
                inert[key] = f"acts only on the two-level path, and {where}"
        return inert

    def check_params(self, params: dict) -> None:
        """Refuse ``solver="multilevel"`` with a k search other than the line search, and a bad ``retry_k_nn``.

        Raises
        ------
        InvalidInputError
            ``solver="multilevel"`` and ``k_search`` is not ``"line"``; ``retry_k_nn``
            not a whole number >= 0; ``map_error`` not positive; ``polish_residual`` negative;
            ``polish_spread`` under 1.
        """
        map_error = params["map_error"]
        if map_error is not None and (isinstance(map_error, bool) or not isinstance(map_error, (int, float))
                                      or not map_error > 0):
            raise InvalidInputError(f"map_error must be a positive number (or null for none), got {map_error!r}.")
        polish = params["polish_residual"]
        if polish is not None and (isinstance(polish, bool) or not isinstance(polish, (int, float)) or not polish >= 0):
            raise InvalidInputError(f"polish_residual must be a number >= 0 (0: always; null: never), got {polish!r}.")
        spread = params["polish_spread"]
        if spread is not None and (isinstance(spread, bool) or not isinstance(spread, (int, float)) or not spread >= 1):
            raise InvalidInputError(f"polish_spread must be a number >= 1 (null: never), got {spread!r}.")
        retry = params["retry_k_nn"]
        if isinstance(retry, bool) or not isinstance(retry, (int, np.integer)) or retry < 0:
            raise InvalidInputError(f"retry_k_nn must be a whole number >= 0 (0: no retry), got {retry!r}.")
        if params["solver"] == "multilevel" and params["k_search"] != "line":
            raise InvalidInputError(f"solver='multilevel' searches k along a line; use k_search='line', "
                                    f"or solver='direct' for k_search={params['k_search']!r}.")

    def error_retry_params(self, params: dict, exc: Exception) -> dict | None:
        """``k_nn = retry_k_nn`` once when every search failed, if that is more neighbours.

        Found on points scattered over matplotlib's jacksboro DEM (20k points, no point on
        the rim): with 8 neighbours no regular map at any k (ConvergenceError, turning
        number -6), with 12 QC 1.0007x scp-igl's on the reference triangulation, 0
        foldovers, self-check passed; the error's own advice was that same ``k_nn=12``.
        """
        if params["retry_k_nn"] and params["retry_k_nn"] > params["k_nn"]:
            return {**params, "k_nn": int(params["retry_k_nn"])}
        return None

    def retry_params(self, params: dict, check: dict) -> dict | None:
        """First, after loops that missed boundary candidates, a lower ``boundary_angle_deg``
        (:func:`~parambench.methods.pointset.plugin_support.coverage_retries`); then
        ``k_nn = retry_k_nn`` after a map with flipped triangles, if that is more neighbours;
        then the paper's energy after a Neumann-energy map that folds at its boundary or spins;
        then, with ``refine="auto"``, the map refined on its own uv mesh (``refine="mesh"``),
        after flipped triangles refined with ``k_nn = retry_k_nn``, and last after flipped
        triangles (and no fold at the boundary or spin, which asked for it already) the
        paper's energy refined the same way; and at the very last, after flipped triangles
        the check finds at a thin part, the neighbourhoods pruned of every edge whose
        ends' normals or tangent offsets disagree (``neighbours="pruned"``); after a loop
        that crosses itself or turns the wrong way, a stretched map, or points beyond the
        loops (and no flip, which asked for it first), ``k_nn = retry_k_nn`` last. When every run fails its
        check, the least doubtful map is kept
        (:func:`~parambench.methods.base.selfcheck_doubt`).

        The last: pymeshlab's cow, cut open and subdivided (22k points), folds 17 true-mesh
        triangles at an ear thinner than the sampling: the default ``neighbours="auto"``
        keeps the kNN edges across it, whose detour round the ear's rim is short. Pruned,
        its map folds none (QC 1.009x ``scp-igl``'s); its check still flags 2 triangles
        there (it cannot tell the ear's sides apart either), so it is the map kept, not
        one that passes.

        Retries that would run what an earlier run's fallbacks already ran are left out
        (:meth:`repeats_a_run`).

        The second: on a ragged boundary (random points over a real mesh, see
        :func:`_paper_energy_fallback`) the Neumann energy's map crossed its own boundary
        (``real/lilium``, 2k points: 21 flipped, boundary crossing, and the same with
        ``k_nn=12``) where the paper's energy's passes.

        Folds at under-resolved curvature come from normals and tangent coordinates
        fitted on too few neighbours: on "protrusions" with random sampling (fingertips
        of radius of curvature 1-2 spacings) k_nn = 12 took 20k points from 4 to 0
        foldovers and 100k from 16 to 0 (QC within 0.05 % of scp-igl), where 8 suits
        the other surfaces (spot-top's QC 1.008x at 8, 1.011x at 12).
        """
        failed = set(check.get("failed", ()))
        retries = coverage_retries(params, check)  # first: loops that missed candidates
        if "flipped" in failed and params["retry_k_nn"] > params["k_nn"]:
            retries.append({**params, "k_nn": int(params["retry_k_nn"])})
        if params["energy"] == ENERGY_FALLBACK_FROM and failed & {"boundary-crossing", "turning"}:
            # The paper's energy where the Neumann one failed: refined as its fallback is (_refines).
            retries.append({**params, "energy": "paper", **({"refine": "mesh"} if params["refine"] == "auto" else {})})
        if params["refine"] == "auto":
            retries.append({**params, "refine": "mesh"})
            if "flipped" in failed and params["retry_k_nn"] > params["k_nn"]:
                # Both at once: on "protrusions" (jittered, 2k) each alone left flipped
                # triangles at the fingertips, together 0 (QC 1.02x scp-igl's).
                retries.append({**params, "refine": "mesh", "k_nn": int(params["retry_k_nn"])})
            if params["energy"] == ENERGY_FALLBACK_FROM and "flipped" in failed and not failed & {
                    "boundary-crossing", "turning"}:
                # Last, after folds the retries above all kept: the paper's energy, refined
                # as its fallback is (unrefined, its map is 1-7 % further from conformal:
                # with refine="none" it passed on protrusions, random 20k, at 1.09x
                # scp-igl's QC with 2 folds of the true mesh). Points scattered over
                # real/spot-top at 5k: the Neumann map (k_opt 2.74, QC 2.42x scp-igl's)
                # folds 3 triangles at its boundary with or without k_nn=12 and its own uv
                # mesh; the paper's energy refined passes (QC 1.003x).
                retries.append({**params, "energy": "paper", "refine": "mesh"})
        if "flipped" in failed and "thin" in (check.get("causes") or {}) and params["neighbours"] == "auto":
            # Last, where the flipped triangles sit at a part thinner than the sampling: no
            # kNN edge across it ("auto" cuts only edges across a gap with no short detour,
            # and round the rim of an ear the detour is short).
            retries.append({**params, "neighbours": "pruned"})
        if failed & {"boundary-crossing", "turning", "distorted", "outside"} and "flipped" not in failed \
                and params["retry_k_nn"] > params["k_nn"]:
            # Last, a loop that still crosses itself in uv, or a map still stretched, with
            # every energy and mesh: more neighbours for a smoother rim. Uniform random
            # points in a square (2k, seed 10) get their rim only from the cycle cover, with
            # 66 points put back, and every map's loop crossed itself; with k_nn=12 the
            # loop is 209 points and passes.
            retries.append({**params, "k_nn": int(params["retry_k_nn"])})
        if params["holes"] == "auto" and len(check.get("turning_numbers") or ()) > 1 \
                and failed & {"flipped", "turning", "distorted"}:
            # Last, with two or more loops: the holes filled, as where the free search fails.
            # Points of an elliptic cylinder (4,800, rims of 160): the free search failed
            # with the Neumann energy, the paper energy's map took the pure annulus mode
            # (methods/spectral/tied_modes.py) and its refinement folded 1,086 triangles;
            # filled, the map passes (radius ratio 2.17 against the exact 2.21).
            retries.append({**params, "holes": "filled"})
        return retries or None

    def repeats_a_run(self, retry: dict, runs: list[tuple[dict, dict]]) -> bool:
        """Whether ``retry`` would run again what one of ``runs`` ran through its fallbacks
        (:func:`_repeats_the_fallbacks`): its map would be that run's again, and from
        :data:`MULTILEVEL_FROM` points on, where no solve is kept between runs, each such
        retry cost a whole run (points scattered over ``real/lilium`` at 300k: 3 of the 4
        retries left out, 567 s -> 257 s for the same map)."""
        return any(_repeats_the_fallbacks(params, retry, diagnostics or {}) for params, diagnostics in runs)

    def solve(self, surface: MethodInput, params: dict, timer: StageTimer) -> MethodOutput:
        solver = resolve_solver(params["solver"], surface.n_points, params["k_search"])
        unrefined, inputs = _memoised(_unrefined_key(params, surface.n_points), lambda: (
            self._unrefined(surface, params, timer, solver), check_inputs_of(surface)))
        restore_check_inputs(surface, inputs)  # a reused map is checked on its own front end's facts
        sol, counts, extra, work, n_filled, n_thin, front = unrefined
        lattice = bool(front.diagnostics.get("lattice")) and surface.n_points < MULTILEVEL_FROM
        if _refines(params["refine"], extra, lattice, float(sol.k), params["energy"]):
            sol, extra = _refined(sol, extra, front, surface.n_points, params, timer)
        with timer("solve"):
            uv = scale_to_spacing(sol.uv[:surface.n_points], front)
        diag = {**frontend_diagnostics(front), **sol.diagnostics, **counts, "solver": solver, **extra,
                "energy": params["energy"], "energy_used": extra.get("energy_used", params["energy"]),
                "solver_option": params["solver"], "k_opt": float(sol.k),
                "turning": np.asarray(sol.turning).tolist(), "holes_filled": int(n_filled + n_thin),
                "thin_holes_filled": int(n_thin), "n_fill_points": int(work.n_points - surface.n_points),
                "refined": extra.get("refined")}
        return MethodOutput(uv, diag)

    def _unrefined(self, surface: MethodInput, params: dict, timer: StageTimer, solver: str) -> tuple:
        """The map before the uv-mesh refinement: (solution, counts, diagnostics, the input
        solved (holes filled or not), holes filled, thin holes filled, the front end of
        ``surface``)."""
        fronts = []  # the front end of each attempt, without its balls; the first is the surface's
        ready = {}  # a front end already run on the surface itself (for the thin-hole test)

        def attempt(work: MethodInput):
            front = ready.pop(id(work), None) or run_frontend(work, params, timer)
            with timer("laplacian"):
                lap = ocp_laplacian(front, params["energy"], params["area_factor"])
            small = front.points.shape[0] < MULTILEVEL_FROM
            w_tan = None
            if params["energy"] == ENERGY_FALLBACK_FROM:
                w_tan = TangentWeights(front.W) if small else TangentWeights(rebuild=lambda: run_frontend(
                    work, params, timer).W)
            front = front.without_balls()
            fronts.append(front)
            if w_tan is not None:
                # The first attempt's Laplacian, for the exact searches run last, only
                # where its memory does not count: from MULTILEVEL_FROM points on they are
                # not run.
                tried.append((front, w_tan, lap if small and not tried else None, work))
            # Handed over in a list: the two-level path reorders it and drops this copy.
            box = [lap]
            del lap
            try:
                # With the paper-energy and mesh fallbacks at hand, a failed Neumann search
                # goes to them at once; its exact searches come last (_exact_last_resort).
                return (front, *_solve_front(front, box, solver, params, timer, exact_fallbacks=w_tan is None))
            except (ConvergenceError, SolverError) as exc:
                if w_tan is None:
                    raise
                return (front, *_paper_energy_fallback(front, w_tan.matrix(), solver, params, timer, released(exc),
                                                       exact_fallbacks=small))

        thin = []  # holes filled before the first attempt
        # (front, W^tan, Laplacian of the first, input) of each attempt, for the fallbacks after them
        tried = []
        n_filled_in = {}  # id of a filled input -> holes filled

        def fill(work: MethodInput):
            if not fronts:  # holes="filled": the loops come from a front end of its own
                fronts.append(run_frontend(work, params, timer).without_balls())
            loops = fronts[0].boundary_loops
            rest = [loop for loop in loops[1:] if not any(loop is t for t in thin)]
            with timer("fill_holes"):
                filled, n = fill_point_holes(work, fronts[0].normals, [loops[0], *rest], fronts[0].local_spacing)
            n_filled_in[id(filled)] = n
            return filled, n

        start, n_thin = surface, 0
        try:
            if params["holes"] == "auto":
                start, n_thin = self._thin_holes_filled(surface, params, timer, fronts, ready, thin)
            try:
                try:
                    (_, sol, counts, extra), work, n_filled = solve_with_holes(start, params["holes"], attempt, fill)
                except (TopologyError, InvalidInputError):
                    if start is surface:
                        raise
                    # The fill points are ours: where they split the graph (scan lines
                    # 10 spacings apart, k_nn=12, taken for slots), the holes stay free.
                    start, n_thin = surface, 0
                    thin.clear()
                    (_, sol, counts, extra), work, n_filled = solve_with_holes(start, params["holes"], attempt, fill)
            except (ConvergenceError, SolverError) as exc:
                if not tried:
                    raise
                sol, counts, extra, which = _after_failed_searches(tried, solver, params, timer, released(exc))
                work, n_filled = (tried[0][0], 0) if which == 0 else (tried[which][3], n_filled_in.get(id(tried[which][3]), 0))
        except SolverError as exc:  # no map came out: say so where the shape explains it
            named = with_shape_cause(exc, fronts[0] if fronts else None)
            if named is exc:
                raise
            raise named from exc
        del tried
        # fronts[0]: loops, spacing and neighbours of the points the user gave
        return sol, counts, extra, work, n_filled, n_thin, fronts[0]

    @staticmethod
    def _thin_holes_filled(surface: MethodInput, params: dict, timer: StageTimer, fronts: list,
                           ready: dict, thin: list) -> tuple[MethodInput, int]:
        """``surface`` with its thin holes filled (``holes="auto"``), and how many.

        A slot (:func:`~parambench.methods.pointset.hole_filling.is_slot`: the slit's, its
        lips 2 spacings apart) maps badly with a free boundary: before its end caps were put
        on the loop it turned inside out, and finding that out cost the failed k search
        first (6.6 s at 2k points and 330 s at 20k on the random slit, against 1.0 and 2.6 s
        when filled first); with them, the free map is still off on the jittered slit at 20k
        (k_opt 1.08, QC 1.044, 1 foldover, 52 s, against QC 1.00002 in 4 s filled) and on the
        random one at 2k seed 1 (QC 1.0069 against 1.0001). Such holes are
        filled before the first attempt; the others stay free as ``holes="auto"`` says.
        The front end run here is the first attempt's when nothing is filled; the filled
        loops are appended to ``thin``.
        """
        front = run_frontend(surface, params, timer)
        loops = front.boundary_loops
        thin.extend(loop for loop in loops[1:]
                    if is_slot(front.points, front.normals, loop, float(np.median(front.local_spacing[loop]))))
        if not thin:
            ready[id(surface)] = front
            return surface, 0
        fronts.append(front.without_balls())
        with timer("fill_holes"):
            return fill_point_holes(surface, front.normals, [loops[0], *thin], front.local_spacing)


def _repeats_the_fallbacks(params: dict, retry: dict, diagnostics: dict) -> bool:
    """Whether ``retry`` would only run again what the run with ``params`` (and
    ``diagnostics``) ran through its fallbacks.

    That is so when that run's map came from the fallbacks (``energy_used`` "paper" or
    "mesh": the Neumann search had failed) and was refined on its uv mesh, and the retry
    changes nothing but ``refine`` to ``"mesh"`` and, or, ``energy`` to ``"paper"``: the
    Neumann search fails again and the same fallbacks give the same refined map, or the
    paper energy's search, already tried, is run alone. Also when the retry only fills the
    holes and that run's ``holes="auto"`` had filled them.
    """
    changed = {key for key, value in retry.items() if params.get(key) != value}
    if changed == {"holes"} and retry["holes"] == "filled" and diagnostics.get("holes_filled"):
        return True  # that run's holes="auto" filled them already
    refined = diagnostics.get("refined") or {}
    if diagnostics.get("energy_used") not in ("paper", "mesh") or not refined or "error" in refined:
        return False
    return bool(changed) and changed <= {"refine", "energy"}


def _unrefined_key(params: dict, n_points: int) -> tuple | None:
    """What the map before refinement depends on: every parameter but ``refine``, and
    whether ``refine`` is ``"none"`` (then a failed search raises instead of falling back
    on the mesh); None (not kept) from :data:`MULTILEVEL_FROM` points on, where a kept
    front end would hold hundreds of MB."""
    if n_points >= MULTILEVEL_FROM:
        return None
    rest = tuple(sorted((name, repr(value)) for name, value in params.items() if name != "refine"))
    return ("ocp-unrefined", params["refine"] == "none", rest)


def _memoised(key: tuple | None, compute):
    """``compute()``, or what it gave (or raised) for ``key`` earlier in this checked run.

    The self-check's retries (:meth:`Ocp.retry_params`) include ``refine="mesh"`` with
    otherwise unchanged parameters: that retry refines the map an earlier attempt solved
    instead of solving it again (on points scattered over real meshes a solve took most
    of each attempt's 3-15 s). A failure is kept too, and raised again.
    """
    memo = retry_memo()
    if key is None or memo is None:
        return compute()
    if key not in memo:
        try:
            memo[key] = compute()
        except ParambenchError as exc:
            memo[key] = exc
    if isinstance(memo[key], ParambenchError):
        raise memo[key]
    return memo[key]


#: How far from 1 the Neumann energy's k_opt may lie before ``refine="auto"`` refines its map (:func:`_refines`).
NEUMANN_K_TOLERANCE = 0.1


#: The ``energy`` whose failed k search is followed by one with the paper's energy.
ENERGY_FALLBACK_FROM = "neumann"


class TangentWeights:
    """The W^tan of a front end, for the fallbacks after a failed Neumann-energy search.

    Below :data:`MULTILEVEL_FROM` points the front end's matrix is held (``matrix``).
    From there on it is not held through the Neumann solve (about 0.3 GB at a million
    points, on top of that solve's peak); ``rebuild`` runs the front end again when a
    fallback needs it, and only then. ``real/meg-helmet`` loop-subdivided (pymeshlab) to
    32k, 128k and 511k points, given as bare points: the Neumann energy finds no regular
    map at any of these sizes (its Hermitian part has negative modes on the most curved
    stretches of the rim), the paper energy's map refined on its uv mesh is within
    0.0013 / 0.0006 / 0.0003 % of the QC of ``scp-igl`` on the subdivided mesh, 0
    foldovers. At 511k that took 120-130 s (``scp-igl``: 137 s) and 5.9 GB peak (the
    cotangent solves of the refinement); before, with no fallback at that size, ``ocp``
    raised ConvergenceError, after 274 s with ``solver="direct"``.

    Parameters
    ----------
    matrix : (N, N) scipy.sparse.csr_matrix of float64, optional
        W^tan, held.
    rebuild : callable, optional
        Returns W^tan; called at most once, by the first :meth:`matrix` call.
    """

    def __init__(self, matrix=None, rebuild=None):
        if (matrix is None) == (rebuild is None):
            raise ValueError("give exactly one of matrix and rebuild")
        self._matrix, self._rebuild = matrix, rebuild

    def matrix(self):
        """W^tan, built on first use when it was not held."""
        if self._matrix is None:
            self._matrix, self._rebuild = self._rebuild(), None
        return self._matrix


def _paper_energy_fallback(front, w_tan, solver: str, params: dict, timer: StageTimer, exc: Exception,
                           exact_fallbacks: bool = True):
    """(solution, counts, diagnostics) with the paper's energy after the Neumann energy's search failed.

    The Neumann energy's boundary rows assume boundary points that lie on the boundary.
    Where the sampling leaves the boundary ragged (points scattered at random over a
    mesh, as a scan or photogrammetry gives, not placed along the boundary curve as the
    generated surfaces do), its k search can find no regular map while the paper's
    ``I - W^tan`` does: points drawn at random on ``real/lilium`` (2k / 5k) and
    ``real/bump-domain`` (5k) gave ConvergenceError or 51 foldovers with the Neumann
    energy and passing maps with the paper's (QC 1.10-1.28x that of the scp-igl map
    carried to the points). ``energy_used`` and ``energy_error`` in the diagnostics
    say so; if this search fails too, the first error is raised. So it is when the map
    gives no mesh of the surface (:func:`~parambench.methods.pointset.mesh_refine.first_map_faces`:
    its boundary folds, and the refinement would have nothing to refine on): on
    ``real/meg-helmet`` scattered at 20k its loop crossed itself in uv and its triangulation
    held 25 of 20,000 points, where the mesh an sdp map triangulates, the next fallback,
    gives QC 1.0001-1.0002x that of scp-igl with 0 foldovers (whatever ``refine``: under
    ``"none"`` the exact searches come next). From :data:`MULTILEVEL_FROM` points on,
    ``w_tan`` comes from a second run of the front end (:class:`TangentWeights`), and
    ``exact_fallbacks=False`` keeps the search on its path (:func:`_solve_front`): on
    points scattered over ``real/lilium`` at 300k the two-level search failed, and the
    direct solve after it took minutes and gigabytes to fail too.
    """
    try:
        with timer("laplacian"):
            box = [graph_laplacian(w_tan)]
        sol, counts, extra = _solve_front(front, box, solver, params, timer, exact_fallbacks)
    except (ConvergenceError, SolverError):
        raise exc from None
    try:
        with timer("refine_mesh"):
            first_map_faces(front.points, sol.uv[:front.points.shape[0]], front.boundary_loops)
    except (SolverError, InvalidInputError):  # folded or collapsed: no map of the surface
        raise exc from None
    return sol, counts, {**extra, "energy_used": "paper", "energy_error": error_note(exc, Ocp.defaults, params)}


def _refined(sol, extra: dict, front, n_points: int, params: dict, timer: StageTimer):
    """(solution, diagnostics) of ``sol``'s map refined on its uv mesh, or ``sol`` itself
    with the reason in ``refined["error"]`` when its triangulation is not a disk-like mesh
    or the mesh has no regular map (the unrefined map then faces the self-check)."""
    refined = {"first_map": f"ocp ({extra.get('energy_used', params['energy'])} energy)", "first_k_opt": float(sol.k)}
    try:  # the triangulation and the similarity placement do not depend on the first map's scale
        mesh_sol, info = refine_on_uv_mesh(front.points, sol.uv[:n_points], front.boundary_loops, timer,
                                           _passes(front), _split_tolerance(front))
    except ParambenchError as exc:
        return sol, {**extra, "refined": {**refined, "error": error_note(exc, Ocp.defaults, params)}}
    return mesh_sol, {**extra, "refined": {**refined, **info}}


def _passes(front) -> int:
    """Solves of the uv-mesh refinement: repeated on clean points (:func:`mesh_passes`) and
    on lattices.

    A lattice's map triangulates to the lattice's own cells whatever the noise, so a second
    solve only settles the cells a distorted first map cut across; the noise gate was
    measured on scattered points, whose triangulation noise does change. pymeshlab's fractal
    terrain at height 0.3 (129 x 129, knife-edge ridges, which the fits take for noise):
    QC over ``scp-igl``'s 1.0886 with 9 foldovers -> 1.0107 with 1; rasters with height
    noise of 0.1-0.5 spacings or with knife-edge ridges, jacksboro, topobathy, terrain at
    0.2 and grid samplings: within 4e-4 of the one-solve QC ratio, no foldover gained.
    """
    diagnostics = front.diagnostics or {}
    if diagnostics.get("lattice"):
        return MAX_MESH_PASSES
    return mesh_passes(diagnostics.get("normal_fit"), int(diagnostics.get("k_nn") or front.knn_indices.shape[1]))


def _split_tolerance(front) -> float:
    """Cells of a lattice whose diagonal the uv mesh nearly ties on are solved with both
    splits' weights averaged (:data:`~parambench.methods.mesh.quad_splits.SPLIT_TOLERANCE_DEG`);
    other points' meshes are solved on their own split (negative tolerance).

    Only lattices: a raster's cells are split by whatever rule the tool that meshes it
    follows, and their maps came nearer conformal on both splits. Elsewhere the near ties
    are chance: on ``protrusions`` (jittered, 2k points) averaging them let the
    ``refine="mesh"`` retry pass its self-check while it folded 1 true-mesh triangle at a
    fingertip (the map kept before folds none), and the scattered real meshes moved by at
    most 4e-4 of QC either way.
    """
    return SPLIT_TOLERANCE_DEG if (front.diagnostics or {}).get("lattice") else -1.0


def _refines(refine: str, extra: dict, lattice: bool = False, k: float = 1.0, energy: str = "neumann") -> bool:
    """Whether a point-set map is refined on its uv mesh: always with ``"mesh"``; with
    ``"auto"`` when it came from the paper-energy fallback (the Neumann search failed),
    when the points are a lattice below :data:`MULTILEVEL_FROM` points (``lattice``:
    the front end's :func:`~parambench.methods.pointset.lattice.is_lattice`), or when the
    Neumann energy's ``k`` (k_opt) lies more than ``NEUMANN_K_TOLERANCE`` from 1.

    A lattice's uv triangulation is its own regular mesh, and cotangent SCP on it is
    nearer conformal than the point-set energies. Measured (QC mean over ``scp-igl``'s on
    the true mesh, unrefined -> refined): matplotlib's jacksboro DEM at every second
    sample (34,744 points) 1.0076 -> 1.0016; grid samplings, 2k points, bump 1.0016 ->
    1.0001, saddle 1.0010 -> 1.00004, cylinder 1.0012 -> 1.0000 (distance from the exact
    map 1.7e-3 -> 2.5e-5 of the diameter; the cap's 4.4e-4 -> 8.8e-5, the plane's at 20k
    points 1.1e-6 -> 4.9e-11); 0.1-1.1 s more at 20k points. From :data:`MULTILEVEL_FROM` points on the
    refinement (one sparse factorisation of the uv mesh) would cost the two-level path
    its speed: lattices that large are left unrefined.

    Measured on points scattered over real meshes (reference: the scp-igl map of the
    true mesh carried to the points), the fallback's maps passed their self-checks at QC
    1.10 / 1.11 / 1.27 / 1.66x the reference (lilium 5k, bump-domain 5k / 20k, meg-helmet
    5k), with 0 / 1 / 0 / 1 folded reference triangles; refined, 1.0000 / 1.0001 / 1.0000 /
    0.998x with none. Maps the Neumann energy gives are left alone where its k_opt is
    within ``NEUMANN_K_TOLERANCE`` of 1 (its area term then agrees with its Dirichlet
    term, as on a fine enough clean sampling: the quick suite's maps 0.924-1.013; of the
    84 cases of ``bench_realdata.py`` the rule changes only ``real/bunny10k``'s, which fails
    its check either way); on the generated surfaces they are within 0.05 % of scp-igl
    already. Further off, the map is a compromise between
    terms that disagree: the ground returns of laspy's LiDAR test tile with the hole found
    (9,808 points) gave k_opt 1.15 and a fan-shaped map, QC 1.076 against ``scp-igl``'s
    1.0075 on the points' xy Delaunay mesh, 6 % of the extent off the xy similarity, which
    passed its check; refined, 1.0085.
    """
    if "refined" in extra or refine == "none":
        return False
    inconsistent = (energy == "neumann" and extra.get("energy_used", "neumann") == "neumann"
                    and abs(k - 1.0) > NEUMANN_K_TOLERANCE)
    return (refine == "mesh" or (extra.get("energy_used") == "paper" and bool(extra.get("energy_error"))) or lattice
            or inconsistent)


def _mesh_fallback(front, w_tan, timer: StageTimer, exc: Exception, params: dict, solver: str = "direct"):
    """(solution, counts, diagnostics) of cotangent SCP on the mesh a first map of ``front`` triangulates.

    After both energies' k searches failed (``refine="auto"`` or ``"mesh"``): on points
    scattered over a real mesh the point Laplacians have negative boundary modes, and no
    k gives a regular map (:mod:`parambench.methods.pointset.mesh_refine`). The first
    maps, tried in this order until one's uv triangulation gives a mesh with a regular
    map (:func:`_first_maps`), need no k:

    - on a surface with one loop, that loop unrolled in the plane and the rest harmonic
      (:func:`~parambench.methods.pointset.boundary_first_map.boundary_first_map`; second,
      after the sdp pair, where ``solver`` is ``"multilevel"``: its solve is direct).
      scikit-learn's swiss roll and S-curve (uniform random points, 2k-20k): no map
      (ConvergenceError), or a map 3.8e-2 of the diameter off its exact unrolling that
      passed its check (the roll, 2k, seed 2, from the sdp map's mesh), now 8e-6 to
      2e-4 off; points scattered over ``real/lilium`` and ``real/bump-domain`` (20k),
      where the sdp map came first: the same QC to 1e-6;
    - the SDP pair of the paper's ``I - W^tan`` (B-orthonormal, as ``sdp``; on two levels
      where ``solver`` is ``"multilevel"``, :func:`_sdp_pair`);
    - from ``k_nn = retry_k_nn`` on, where the points are a height field over the plane
      across their mean normal (:func:`height_field_projection`), their projection
      (uniform random points on flat 4:1 to 100:1 strips at 20k points, 10:1 at 8k,
      before the unrolled boundary: ConvergenceError; then their own plane's map to 1e-8
      of the diagonal). Not at 8 neighbours: points scattered over the jacksboro DEM
      (20k) map at 1.0007x scp-igl's QC with 12 neighbours through the sdp map, at 8
      through the projection at 1.0073x with 2 folded reference triangles.

    If none gives one, ``exc`` (the first error) is raised. ``energy_used`` is ``"mesh"``,
    ``energy_error`` keeps the first error and ``refined["first_map"]`` names the first map.
    """
    for name, first_map in _first_maps(front, graph_laplacian(w_tan), solver, params, timer):
        try:
            sol, info = _refined_from(front, first_map(), timer)
        except ParambenchError:
            continue
        return sol, {}, {"energy_used": "mesh", "energy_error": error_note(exc, Ocp.defaults, params),
                         "refined": {"first_map": name, **info}}
    raise exc from None


def _first_maps(front, lap, solver: str, params: dict, timer: StageTimer) -> list:
    """(name, function giving an (N, 2) first map) pairs of :func:`_mesh_fallback`, in its order."""

    def unrolled():
        with timer("solve"):
            return boundary_first_map(front.points, front.normals, front.boundary_loops[0], lap)

    def projected():
        plane = height_field_projection(front.points, front.normals)
        if plane is None:
            raise SolverError("the points are no height field over a plane.")
        return plane

    maps = [("sdp", lambda: _sdp_pair(front, lap, solver, params, timer))]
    if len(front.boundary_loops) == 1:
        # On two levels the sdp pair is the cheaper: the unrolled map's solve is direct.
        maps.insert(1 if solver == "multilevel" else 0, ("unrolled boundary", unrolled))
    if params["k_nn"] >= params["retry_k_nn"]:
        maps.append(("plane projection", projected))
    return maps


def _refined_from(front, first_map: np.ndarray, timer: StageTimer):
    """Cotangent SCP on the mesh ``first_map`` (N, 2) triangulates, facing the normals."""
    # A map from an eigenvector pair or a projection has no handedness: mirrored, its
    # triangulation would face away from the normals and so would the refined map (loops
    # turning -1).
    if signed_area_2d(first_map[front.boundary_loops[0]]) < 0:
        first_map = first_map * [1.0, -1.0]
    return refine_on_uv_mesh(front.points, first_map, front.boundary_loops, timer, _passes(front),
                             _split_tolerance(front))


#: A point set is a height field over the plane across its mean normal when every normal
#: makes at most this angle with the mean one (degrees).
HEIGHT_FIELD_MAX_DEG = 75.0


def height_field_projection(points: np.ndarray, normals: np.ndarray) -> np.ndarray | None:
    """The points projected on the plane across their mean normal, if the surface is a height field over it.

    The mean normal, not the least-squares plane's: a long strip with more relief than
    width (z = sin(x / 2) over 20 x 1) has its least-squares plane upright.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    normals : (N, 3) numpy.ndarray of float64
        Consistently oriented unit normals.

    Returns
    -------
    (N, 2) numpy.ndarray of float64 or None
        Coordinates in the plane; None when some normal lies more than
        :data:`HEIGHT_FIELD_MAX_DEG` from the mean normal (the projection could fold).
    """
    up = normals.mean(axis=0)
    length = float(np.linalg.norm(up))
    if not length > 0.0:
        return None
    up = up / length
    if float((normals @ up).min()) < np.cos(np.deg2rad(HEIGHT_FIELD_MAX_DEG)):
        return None
    # Two axes across it: the points' own principal directions, projected and orthonormalised.
    centred = points - points.mean(axis=0)
    _, _, axes = np.linalg.svd(centred - np.outer(centred @ up, up), full_matrices=False)
    return centred @ axes[:2].T


def _sdp_pair(front, lap, solver: str, params: dict, timer: StageTimer) -> np.ndarray:
    """SDP's B-orthonormal pair of ``lap`` for :func:`_mesh_fallback`, (N, 2) float64.

    On two levels (:func:`~parambench.methods.pointset.two_level.two_level_sdp_pair`)
    where ``solver`` is ``"multilevel"``, with no direct solve after a failure: on points
    scattered over ``real/lilium`` at 300k the direct pair took 4 minutes and 8 GB.
    """
    if solver == "multilevel":
        pair, _ = two_level_sdp_pair(front, lap, params["fine_solver"], timer)
        return b_orthonormalize(pair, front.boundary_mask.astype(np.float64))
    with timer("solve"):
        return direct_sdp_pair(lap, front.boundary_mask, front.points)[1]


def _after_failed_searches(tried: list, solver: str, params: dict, timer: StageTimer, exc: Exception):
    """(solution, counts, diagnostics, index into ``tried``) once both energies' searches failed.

    ``tried`` holds each attempt's (front end, W^tan, Laplacian, input): the surface's,
    then with its holes filled (``holes="auto"``). The mesh a first map triangulates
    (:func:`_mesh_fallback`; not under ``refine="none"``) on each in turn, the holes free
    first. The unrolled boundary's map unrolls only one loop, so a surface with holes
    reaches it filled; that map, of the filled surface, is then the first map of the
    surface's own mesh with its holes free (:func:`_holes_freed`): scikit-learn's S-curve,
    20k points less a disk 0.4 across, ConvergenceError before, now 9.0e-6 of the
    diameter from the holed strip's unrolling. Else the first attempt's exact searches,
    last (its Laplacian None: they ran in the first search, and ``exc`` is raised)."""
    if params["refine"] != "none":
        for which, (front, w_tan, _, _) in enumerate(tried):
            try:
                sol, counts, extra = _mesh_fallback(front, w_tan.matrix(), timer, exc, params, solver)
            except (ConvergenceError, SolverError):
                continue
            freed = _holes_freed(tried[0][0], sol, extra, timer) if which else None
            return (*freed, 0) if freed is not None else (sol, counts, extra, which)
    front, _, lap, _ = tried[0]
    if lap is None:
        raise exc
    return (*_exact_last_resort(front, lap, solver, params, timer), 0)


def _holes_freed(front, filled: "ConformalSolution", extra: dict, timer: StageTimer):
    """(solution, counts, diagnostics) of cotangent SCP with the holes free on the mesh
    ``filled``'s map (of the surface with its holes filled) triangulates on ``front``, or
    None where that mesh has no regular map. The filled map is a map of another surface
    (the fill patch's distortion: 4.2e-3 of the diameter off the unrolling of the holed
    S-curve below); as a first map it gives the surface's own, 9.0e-6 off."""
    try:
        sol, info = _refined_from(front, filled.uv[:front.points.shape[0]], timer)
    except ParambenchError:
        return None
    first = f"{extra['refined']['first_map']}, holes filled"
    return sol, {}, {**extra, "refined": {**extra["refined"], **info, "first_map": first}}


def _exact_last_resort(front, lap, solver: str, params: dict, timer: StageTimer):
    """(solution, counts, diagnostics) of the Neumann energy's search with its exact searches on.

    The first attempt left them out for the cheaper fallbacks (paper energy, then the
    mesh an sdp map triangulates; see :func:`_solve_front`); when those failed too, they
    run here, so no search the method has is left untried. Their failure is raised as
    the method's error, with ``refine='auto'`` first among the remedies under
    ``refine="none"``.
    """
    try:
        return _solve_front(front, [lap], solver, params, timer)
    except (ConvergenceError, SolverError) as exc:
        if params["refine"] != "none":
            raise
        stem, hints = getattr(exc, "parambench_hints", None) or (str(exc).rstrip("."), ())
        raise hinted(type(exc), stem, Hint("use refine='auto'", "refine", "auto"), *hints) from exc


#: Largest boundary on which a failed line search is followed by ``k_search="direct"``: its
#: dense pencil costs O(K^3) (451 boundary points: 3.6 s; 4000 would take minutes).
DIRECT_FALLBACK_MAX_BOUNDARY = 1000


def _solve_front(front, box: list, solver: str, params: dict, timer: StageTimer, exact_fallbacks: bool = True):
    """(solution, counts, diagnostics) of the conformal problem of ``front`` on the ``solver`` path.

    ``box`` holds the Laplacian (see :func:`~parambench.methods.spectral.multilevel.multilevel_scp`).

    ``exact_fallbacks=False`` leaves out the exact searches on the dense boundary
    reduction after a failed subspace search (the exact line search, then the direct
    k), and the direct solve after a failed two-level one: the caller tries a cheaper
    fallback first (the exact searches come last below :data:`MULTILEVEL_FROM` points;
    from there on not at all). On ``real/meg-helmet`` loop-subdivided to 511k points the
    Neumann energy's direct solve took 260 s to fail after its two-level one (274 s
    with its exact searches), where the paper energy's two-level search and the
    refinement on its uv mesh gave the map in 120 s all told (383 s with that direct
    solve tried first). On points scattered
    over the real meshes (lilium, bump-domain, meg-helmet, spot-top at 5k and 20k) the
    Neumann energy's exact searches found a map once in 8 runs (meg-helmet 20k, which
    then failed its self-check) and took most of ``ocp``'s 9-50 s there; the paper
    energy's search and the refinement on the uv mesh after it gave the same QC (within
    0.01 %) and foldovers in 3.6-12.3 s (twenty-third session).

    With ``solver="auto"`` resolved to the two-level path, a ConvergenceError or
    SolverError there falls back to the direct solve: a safety net, since the two-level
    path has failed where the direct one did not (the fold at 100k points, before its
    coarse interpolation kept to each sheet and its fine search learned to do without a
    coarse map). ``solver`` then reads ``"direct"`` and ``multilevel_error`` says why. An
    explicit ``solver="multilevel"`` raises instead, its message suggesting ``solver='direct'``.
    A fine level whose subspace search fails does not run the exact boundary search
    (:meth:`ConformalProblem.solve`): with two-grid interior solves its reduction took
    550 s at 300k points, and the direct path here is bounded by one factorisation.
    """
    if solver == "multilevel":
        try:
            return _multilevel_solve(front, box, timer, params["fine_solver"], params["map_error"],
                                     params["polish_residual"], params["polish_spread"])
        except (ConvergenceError, SolverError) as exc:
            if params["solver"] != "auto":
                stem, hints = getattr(exc, "parambench_hints", None) or (str(exc).rstrip("."), ())
                raise hinted(type(exc), stem, *hints, Hint("use solver='direct'", "solver", "direct")) from exc
            if not exact_fallbacks:  # the caller's cheaper fallback comes first
                raise
            fallback = {"solver": "direct", "multilevel_error": error_note(released(exc), Ocp.defaults, params)}
    else:
        fallback = {}
    with timer("solve"):
        problem = conformal_problem(front, box.pop(), exact_fallbacks=exact_fallbacks)
        if params["k_search"] == "line" and problem.boundary.size <= DIRECT_FALLBACK_MAX_BOUNDARY:
            # The line search's own advice is k_search='direct', and the direct search's is
            # k_search='line': tried here, so a failure of both points upstream instead (a
            # cut cow from pymeshlab's samples, 1451 points whose second loop was missed).
            sol = solve_line_then_direct(problem, "scp", hints=BOUNDARY_HINTS)
        else:
            sol = problem.solve("scp", params["k_search"])
    return sol, problem.counts, fallback


def resolve_solver(option: str, n_points: int, k_search: str) -> str:
    """The path ``solver=option`` takes for ``n_points`` points: ``"direct"`` or ``"multilevel"``.

    ``"auto"`` is ``"multilevel"`` from :data:`MULTILEVEL_FROM` points on when the k
    search is the line search (the only one the two-level path has), ``"direct"`` otherwise.
    """
    if option != "auto":
        return option
    return "multilevel" if n_points >= MULTILEVEL_FROM and k_search == "line" else "direct"


def _multilevel_solve(front, box: list, timer: StageTimer, fine_solver: str = "twogrid",
                      map_error: float | None = None, polish_residual: float | None = None,
                      polish_spread: float | None = None):
    """The two-level solve of ``solver="multilevel"``: (solution, fine counts, diagnostics).

    Stages: ``subsample``, ``coarse`` (prolongation, Galerkin product, coarse search) and
    ``solve`` (the fine level, as on the direct path).
    """
    from ..spectral.multilevel import MultilevelSettings, multilevel_scp

    settings = MultilevelSettings(fine_solver=fine_solver, map_error=map_error, polish_from=polish_residual,
                                  polish_spread=polish_spread)
    with timer("subsample"):
        coarse = coarse_subsample(front, settings)
    sol, info = multilevel_scp(box, front.boundary_loops, front.points, coarse, normals=front.normals,
                               settings=settings, stage=lambda name: timer("solve" if name == "fine" else name))
    counts = info.pop("fine_counts")
    return sol, counts, info
