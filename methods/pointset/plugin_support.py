"""Glue shared by the point-set method plugins: front-end parameters, stage timings, output scale."""

from __future__ import annotations

import time
import weakref
from dataclasses import dataclass
from typing import Any

import numpy as np

from parambench.datasets_gen.errors import ParambenchError, SolverError, TooFewPointsError
from parambench.datasets_gen.surface import MethodInput

from ..base import StageTimer
from ..hints import Hint, hinted
from .failure_causes import cause_advice, describe_causes, protrusion_shrink
from .boundary import LOWER_ANGLES_DEG
from .frontend import STAGES, FrontEnd, build_frontend
from .loop_side import surface_on_the_left
from .normals import fit_error_median
from .params import FRONTEND_PEAK, frontend_params, method_defaults
from .row_chunks import for_each_chunk

__all__ = ["FRONTEND_DEFAULTS", "FRONTEND_PEAK", "run_frontend", "require_neighbours", "scale_to_spacing",
           "frontend_diagnostics", "frontend_candidates", "selfcheck_result", "boundary_doubt", "BOUNDARY_HINTS",
           "with_shape_cause", "check_inputs_of", "restore_check_inputs", "coverage_retries"]

#: Front-end parameters every point-set method accepts, with the front end's defaults
#: (the method-parameter fields of :class:`~parambench.methods.pointset.params.FrontEndParams`).
FRONTEND_DEFAULTS: dict[str, Any] = method_defaults()


def run_frontend(surface: MethodInput, params: dict, timer: StageTimer, *, weights: str = "tangent",
                 given_loops: list | None = None) -> FrontEnd:
    """Run the front end with the front-end keys of ``params``; its stage timings go to ``timer``.

    Parameters
    ----------
    surface : MethodInput
    params : dict
        The method's parameters; the keys of :data:`FRONTEND_DEFAULTS` among them are
        passed on (see :func:`~parambench.methods.pointset.params.frontend_params`).
    timer : StageTimer
    weights : {"tangent", "lle3d"}
        The front end's weights.
    given_loops : list of (L_i,) numpy.ndarray of int64, optional
        Loops to use instead of detected ones (``build_frontend``'s ``given_loops``); the
        self-check then judges the map on them.

    Returns
    -------
    FrontEnd

    Raises
    ------
    TooFewPointsError
        ``k_nn`` is not below the number of points (each point needs ``k_nn`` others).
    ParambenchError
        Whatever :func:`~parambench.methods.pointset.frontend.build_frontend` raises.
    """
    options = frontend_params(params, weights=weights)
    require_neighbours(surface.n_points, options.k_nn, "k_nn")
    front = build_frontend(surface.points, surface.normals, options, given_loops=given_loops)
    for stage in STAGES:
        timer.timings[stage] = timer.timings.get(stage, 0.0) + front.timings.get(stage, 0.0)
    _CHECK_INPUTS[surface] = _check_inputs(front)
    _require_simple_loops(front.boundary_loops, options.k_nn)
    return front


def _require_simple_loops(loops, k_nn: int) -> None:
    """Refuse detected loops that pass a point twice, as a failed solve the retries can take up.

    The conformal problem refused them as bad input, "split pinched boundary vertices
    first", which a point set's user cannot do: scan lines 5 spacings apart, rolled on a
    cylinder, gave such loops with 8 neighbours and the exact map with 16 or 24.
    """
    flat = np.concatenate([np.asarray(lp, dtype=np.int64) for lp in loops]) if loops else np.zeros(0, np.int64)
    repeated = flat.size - np.unique(flat).size
    if repeated:
        raise hinted(SolverError, f"the detected boundary loops pass {repeated} point(s) twice (a boundary "
                     f"too sparsely sampled for {k_nn} neighbours, such as scan lines far apart)",
                     Hint(f"raise k_nn (e.g. {2 * k_nn})", "k_nn", 2 * k_nn, 1))


@dataclass(frozen=True, eq=False)
class _CheckInputs:
    """What the self-check reuses from the front end (normals, kNN graph, candidates)."""

    normals: np.ndarray
    knn_indices: np.ndarray
    spacing: float
    loops: list
    candidates: np.ndarray | None
    #: Median predicted error of the normals stage's kNN fits (degrees), None if not fitted.
    normal_error_deg: float | None = None


#: Front-end facts of the last run on each surface, taken (and dropped) by
#: :func:`selfcheck_result` so the check does not recompute normals and neighbours.
_CHECK_INPUTS: "weakref.WeakKeyDictionary[MethodInput, _CheckInputs]" = weakref.WeakKeyDictionary()


def check_inputs_of(surface: MethodInput) -> _CheckInputs | None:
    """The front-end facts the next self-check on ``surface`` will take, or None."""
    return _CHECK_INPUTS.get(surface)


def restore_check_inputs(surface: MethodInput, inputs: _CheckInputs | None) -> None:
    """Give the next self-check on ``surface`` the facts of a front end run earlier.

    For a run that reuses an earlier attempt's map (``ocp``'s retry with only ``refine``
    changed runs no front end): without them its check estimated normals and neighbours
    and had no boundary candidates, so a map whose loops missed a hole passed (a hole 5
    spacings across in a jittered grid: the first map failed for the ring of candidates
    round it, the refined one passed).
    """
    if inputs is not None:
        _CHECK_INPUTS[surface] = inputs


#: Rows of balls per chunk when the candidates are recomputed.
_CANDIDATE_CHUNK = 100_000


def frontend_candidates(front: FrontEnd) -> np.ndarray | None:
    """The angle-criterion boundary candidates of a front end, or None if it cannot tell.

    Taken from ``front.boundary_candidates`` when the front end keeps them, otherwise
    recomputed with :func:`parambench.methods.pointset.boundary.angular_gaps` on its balls (None
    once the balls are dropped), at the angle its loops were found at (lowered where the
    one asked for missed a hole).
    """
    given = getattr(front, "boundary_candidates", None)
    if given is not None:
        return np.asarray(given, dtype=bool)
    if front.ball_indices is None or front.tangent_coords is None:
        return None
    from .boundary import angular_gaps  # the angle criterion of the front end, on its own balls

    angle = ((front.diagnostics.get("boundary") or {}).get("angle_lowered_to")
             or front.params.get("boundary_angle_deg", FRONTEND_DEFAULTS["boundary_angle_deg"]))
    threshold = np.deg2rad(float(angle))
    out = np.empty(front.n_points, dtype=bool)
    for lo in range(0, front.n_points, _CANDIDATE_CHUNK):  # bounded temporaries at 1M points
        sl = slice(lo, lo + _CANDIDATE_CHUNK)
        out[sl] = angular_gaps(front.tangent_coords[sl], front.ball_indices[sl] >= 0)[0] > threshold
    return out


def _check_inputs(front: FrontEnd) -> _CheckInputs:
    try:
        candidates = frontend_candidates(front)
    except Exception:  # the check is optional; a changed front end must not fail a method
        candidates = None
    return _CheckInputs(normals=front.normals, knn_indices=front.knn_indices, spacing=front.mean_spacing,
                        loops=list(front.boundary_loops), candidates=candidates,
                        normal_error_deg=fit_error_median((front.diagnostics or {}).get("normal_fit")))


def _estimated_inputs(surface: MethodInput, result) -> _CheckInputs:
    """Normals and neighbours for a method that ran no front end (e.g. the sklearn peers)."""
    from .neighbourhoods import knn_graph
    from .normals import noise_adaptive_normals, orient_normals

    graph = knn_graph(surface.points, FRONTEND_DEFAULTS["k_nn"])
    normals = surface.normals
    if normals is None:  # as the front end's: refitted where the residual says noise
        fitted, _, fit_error = noise_adaptive_normals(surface.points, graph.indices, return_error=True)
        normals = orient_normals(surface.points, fitted, graph.indices, fit_error)
    loops = result.diagnostics.get("boundary_loops") or []
    loops = [surface_on_the_left(surface.points, normals, np.asarray(lp, dtype=np.int64), graph.indices)
             for lp in loops]
    return _CheckInputs(normals=normals, knn_indices=graph.indices, spacing=graph.mean_spacing,
                        loops=loops, candidates=None)


def selfcheck_result(surface: MethodInput, result, conformal: bool = False) -> dict:
    """Check a point-set result and store the facts in ``result.diagnostics["selfcheck"]``.

    Uses the front end of the method's own run on ``surface`` when there was one,
    otherwise estimates normals and neighbours. ``seconds`` in the facts is the time of
    the whole check, estimation included. Never raises: a check that cannot run
    records ``passed=False`` with the reason, and the map is always kept.

    Parameters
    ----------
    surface : MethodInput
        The surface the method ran on.
    result : parambench.methods.base.Parameterization
    conformal : bool
        The method promises a conformal map: its check judges ``coherent_beltrami``
        (:func:`~parambench.methods.pointset.selfcheck.check_pointset_map`).

    Returns
    -------
    dict
        The facts of :func:`parambench.methods.pointset.selfcheck.check_pointset_map`.
    """
    from .selfcheck import check_pointset_map

    start = time.perf_counter()
    try:
        inputs = _CHECK_INPUTS.pop(surface, None) or _estimated_inputs(surface, result)
        check = check_pointset_map(surface.points, result.uv, inputs.normals, inputs.loops,
                                   knn_indices=inputs.knn_indices, spacing=inputs.spacing,
                                   candidates=inputs.candidates, normal_error_deg=inputs.normal_error_deg,
                                   conformal=conformal)
    except Exception as exc:  # checking must never hide a result
        check = {"passed": False, "reason": f"the self-check could not run ({type(exc).__name__}: {exc})",
                 "failed": ["check-error"]}
    check["seconds"] = round(time.perf_counter() - start, 4)  # with the inputs' estimation, if any
    result.diagnostics["selfcheck"] = check
    return check


def coverage_retries(params: dict, check: dict) -> list[dict]:
    """Retries with a lower ``boundary_angle_deg`` after a check whose loops missed candidates.

    The angle criterion's own remedy, which the check's line offers too, as
    :meth:`~parambench.methods.base.Method.retry_params` answers (every point-set
    method's default). A hole of a LiDAR tile's ground returns 5.7 mean spacings across
    (laspy's test tile ``file_with_both_wkt_and_geotiff_vlrs.las``, class 2, 9,808
    points): at 120 degrees 15 of its ~20 rim points pass and no loop closes; at 100 it is
    a loop and the map passes. Holes 5.4 grid steps across in flat jittered grids: 100
    finds some, 90 the others.

    Parameters
    ----------
    params : dict
        The run's parameters; none are offered without ``boundary_angle_deg``, or with
        loops given (``boundary="given"``), or below the angle already used.
    check : dict
        Its self-check facts (``failed``).

    Returns
    -------
    list of dict
        Parameters of the retries, in order.
    """
    if "coverage" not in (check.get("failed") or ()) or "boundary_angle_deg" not in params \
            or params.get("boundary") == "given":
        return []
    # The angles the front end's boundary stage tries itself, run again as a whole method
    # where a map's check still finds candidates off its loops.
    return [{**params, "boundary_angle_deg": angle} for angle in LOWER_ANGLES_DEG
            if angle < float(params["boundary_angle_deg"])]


#: Remedies for loops that miss boundary candidates, in the order offered (the
#: parameters of every point-set method; :func:`~parambench.methods.hints.fit_hints`
#: drops those a method lacks); first in errors that point upstream.
BOUNDARY_HINTS = (Hint("lower boundary_angle_deg (e.g. 100)", "boundary_angle_deg", 100.0, -1),
                  Hint("raise ball_eps_factor (e.g. 3.5)", "ball_eps_factor", 3.5, 1),
                  Hint("raise k_nn (e.g. 12)", "k_nn", 12, 1))


def boundary_doubt(surface: MethodInput, exc: ParambenchError) -> ParambenchError | None:
    """``exc`` restated when the front end's loops fail the coverage check, or None.

    A k search or eigen-solve on a wrong boundary fails with advice about the solver
    (a real face range scan, 85k points: the line search "use k_search='direct'", the
    direct search "use k_search='line'"), which sends the user in a circle; the cause is
    upstream. When the run's front end left its facts (:func:`run_frontend`) and its
    loops miss a connected group of boundary candidates
    (:func:`~parambench.methods.pointset.selfcheck.loop_coverage`), the error keeps its
    type and says so first, with front-end parameters as remedies before the solver's.

    Parameters
    ----------
    surface : MethodInput
        The surface the failed run was given.
    exc : ParambenchError
        What the run raised.

    Returns
    -------
    ParambenchError or None
        An error of the same type to raise from ``exc``; None when the loops pass (or
        there is nothing to check them with).
    """
    from .selfcheck import loop_coverage, uncovered_phrase

    inputs = _CHECK_INPUTS.pop(surface, None)
    if inputs is None or inputs.candidates is None:
        return None
    cov = loop_coverage(surface.points, inputs.loops, inputs.candidates, inputs.knn_indices, inputs.spacing)
    if cov["passed"]:
        return None
    stem, hints = getattr(exc, "parambench_hints", None) or (str(exc).rstrip("."), ())
    doubt = (f"the detected boundary looks wrong: {uncovered_phrase(cov)} "
             f"({cov['n_uncovered']} of {cov['n_candidates']} off the {len(inputs.loops)} loops: "
             f"a missed boundary or hole), and the solve on it failed ({stem})")
    return hinted(type(exc), doubt, *BOUNDARY_HINTS, *hints)


def require_neighbours(n_points: int, k: Any, param: str) -> None:
    """Raise unless ``n_points`` points can each have ``k`` neighbours (the parameter named ``param``).

    Raises
    ------
    TooFewPointsError
        ``n_points <= k``; the message names ``param``, both numbers and the largest usable value.
    """
    if isinstance(k, (int, np.integer)) and n_points <= k:
        raise TooFewPointsError(
            f"{param}={k} asks for {k} neighbours per point but there are only {n_points} points; "
            f"lower {param} to at most {n_points - 1}, or sample the surface more densely."
        )


#: Points per chunk of :func:`scale_to_spacing`'s edge lengths (on worker threads).
_SCALE_CHUNK = 65536


def with_shape_cause(exc: SolverError, front: FrontEnd | None) -> SolverError:
    """``exc`` with the protrusion the points show named first among its remedies, if they show one.

    For a solver error that left no map to check: its hints name front-end parameters,
    which cannot help where the surface has a protrusion a conformal map shrinks
    exponentially (pymeshlab's cow cut to its side with two leg stumps, 8k points: every
    k search fails although the three loops are found, and the hints led from
    ``boundary_angle_deg`` to ``ball_eps_factor`` to ``k_nn``). The test is
    :func:`~parambench.methods.pointset.failure_causes.protrusion_shrink` on ``front``'s
    points and outer loop; the parameter hints stay, after the cut advice. Parts that hang
    on the rest by single points (the harmonic map constant on them) are named as such,
    not as a protrusion: pymeshlab's range scan ``face000`` was said to have one shrunk
    1.8e15 times.

    Parameters
    ----------
    exc : SolverError
    front : FrontEnd or None
        The front end of the points the user gave (None: ``exc`` is returned).

    Returns
    -------
    SolverError
        ``exc`` itself when no protrusion shows, else a new error of its type.
    """
    if front is None or not front.boundary_loops:
        return exc
    causes = protrusion_shrink(front.points, front.knn_indices, front.boundary_loops[0])
    if not causes:
        return exc
    stem, hints = getattr(exc, "parambench_hints", None) or (str(exc).rstrip("."), ())
    advice, _ = cause_advice(causes, [])
    said = describe_causes(causes)
    named = hinted(type(exc), f"{stem}. {said[:1].upper()}{said[1:]}", Hint(advice), *hints)
    named.parambench_causes = causes
    return named


def scale_to_spacing(uv: np.ndarray, front: FrontEnd) -> np.ndarray:
    """Scale uv so that its mean kNN edge length equals the 3D mean spacing ``l``.

    Point sets have no surface area to match; matching the sampling scale makes uv
    lengths comparable with 3D lengths (a conformal map's local scale averages to ~1).

    Raises
    ------
    SolverError
        The map collapses the neighbourhoods (zero mean edge length).
    """
    centred = uv - uv.mean(axis=0)
    nbr = front.knn_indices
    lengths = np.empty(nbr.shape)

    def rows_of(rows: slice) -> None:  # each edge's length as one pass would give it
        lengths[rows] = np.linalg.norm(centred[nbr[rows]] - centred[rows, None, :], axis=-1)

    for_each_chunk(rows_of, nbr.shape[0], _SCALE_CHUNK)
    edge = lengths.mean()
    if not edge > 0 or not np.isfinite(edge):
        raise SolverError("the map collapses every neighbourhood to a point; the solve failed.")
    return centred * (front.mean_spacing / edge)


def frontend_diagnostics(front: FrontEnd) -> dict:
    """The facts of the front end worth keeping with a result (JSON-serialisable).

    ``slots`` (:mod:`parambench.methods.pointset.slot_cuts`' facts) is there only where
    edges across a slot were cut; ``boundary_angle_lowered_to`` only where the loops at
    the angle asked for missed a hole and a lower angle's did not
    (:func:`~parambench.methods.pointset.frontend.boundary_stage`); ``dem`` is the DEM kind the balls were built with
    (what ``dem="auto"`` chose); ``lattice`` whether the points are a lattice
    (:func:`~parambench.methods.pointset.lattice.is_lattice`).
    """
    diag = front.diagnostics
    slots = diag.get("neighbours", {}).get("slots") or {}
    lowered = (diag.get("boundary") or {}).get("angle_lowered_to")
    return {
        "mean_spacing": front.mean_spacing,
        "n_boundary_points": int(front.boundary_mask.sum()),
        "n_detected_loops": len(front.boundary_loops),
        "boundary_method": front.params.get("boundary_method", "angle"),
        "dem": diag.get("dem", front.params.get("dem")),
        "lattice": bool(diag.get("lattice", False)),
        "negative_weight_fraction": diag["negative_weights"]["negative_fraction"],
        "reconstruction_error": diag["reconstruction_error"],
        "boundary_loops": [loop.tolist() for loop in front.boundary_loops],
        **({"slots": dict(slots)} if slots.get("n_slot_edges") else {}),
        **({"boundary_angle_lowered_to": float(lowered)} if lowered else {}),
    }
