"""One entry point for the point-set front end: kNN graph, normals, DEM balls, weights, boundary.

The point-set methods (LEM, LLE, SDP, OCP) call :func:`build_frontend` and use ``W``,
``L`` and the boundary loops of the returned :class:`FrontEnd`. Its options are a
:class:`~parambench.methods.pointset.params.FrontEndParams`. Each timed stage is a function of its
own (:func:`knn_stage`, :func:`normals_stage`, :func:`dem_stage`, :func:`weights_stage`,
:func:`boundary_stage`) working on the points in kd-tree order; ``build_frontend``
chains them and maps the results back to the input order.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any, NamedTuple

import numpy as np
import scipy.sparse as sp

from parambench.datasets_gen.errors import InvalidInputError, NoBoundaryError
from parambench.datasets_gen.surface import (MIN_POINTS, core_box, duplicate_tolerance, require_unique_points,
                                             validate_normals, validate_points)

from ..base import StageTimer
from .boundary import LOWER_ANGLES_DEG, find_boundary, no_boundary_error
from .boundary_rings import find_boundary_rings
from .dem import DEM_KINDS, dem_balls
from .laplacian import graph_laplacian
from .lattice import is_lattice
from .lattice_loops import lattice_loops
from .loop_side import surface_on_the_left
from .neighbourhoods import _component_sizes, knn_graph, local_spacing, require_connected, symmetric_adjacency
from .slot_cuts import cut_ends, slot_cut_graph, slots_on_loops
from .surface_neighbours import gap_aware_knn_graph, gap_suspected, pruned_knn_graph, surface_knn_graph
from .normals import (NOISY_MAX_K, NOISY_TARGET_DEG, check_user_normals, fit_error_median, noise_adaptive_normals,
                      orient_normals)
# Aliased: FrontEndParams has a boolean field of the same name.
from .normals import smooth_normals as neighbourhood_smoothed
from .params import FrontEndParams
from .reorder import renumbered_rows, spatial_order, take_rows
from .row_chunks import for_each_chunk
from .tangent_weights import (
    DEFAULT_REG_EPS,
    lle3d_weights,
    negative_weight_stats,
    reconstruction_error,
    tangent_weights,
    weight_matrix,
)

__all__ = ["FrontEnd", "FrontEndParams", "build_frontend", "WEIGHT_KINDS", "DEM_VARIANTS", "STAGES",
           "Neighbourhoods", "validate_inputs", "knn_stage", "slot_stage", "normals_stage", "resolved_dem", "dem_stage",
           "weights_stage", "DEM_CHOICES", "AUTO_PROJECTED_ERROR_DEG", "AUTO_CLOSE_PAIR_SHARE",
           "CLOSE_PAIR_SPACINGS", "close_pair_share", "noisy_fits",
           "boundary_stage", "stage_diagnostics"]

WEIGHT_KINDS = ("tangent", "lle3d")

#: ``dem`` settings: the kinds of :func:`~parambench.methods.pointset.dem.dem_balls`, and
#: "auto" (default), which chooses among them by :func:`resolved_dem`.
DEM_CHOICES = DEM_KINDS + ("auto",)

#: With ``dem="auto"``, the median predicted error of the normals stage's kNN plane fits
#: (degrees) from which the points count as noisy and the balls get ``"projected"``
#: coordinates instead of the upwind DEM. Measured median errors: clean generated
#: surfaces 0-2.4 (random, graded and jittered samplings, 2k and 20k points), the real
#: meshes as points 0-4.7 except ``real/cortex-lh`` (16); normal noise of 0.1 / 0.25 / 0.5
#: spacings: 3.5-3.7 / 8.4-8.6 / 14.5-14.8 on jittered samplings, 4.4-4.5 / 10.3-10.5 /
#: 16.3-16.6 on random ones. ``ocp``, seed 0, foldovers on the true mesh upwind ->
#: projected: noise 0.5, random 20k: 696 / 276 / 279 -> 54 / 56 / 67 (plane, bump, saddle),
#: ConvergenceError / SolverError -> 44 / 68 (cap, holes); random 2k: 15-32 -> 4-11;
#: noise 0.25, random 20k: 18-32 -> 5-13, random 2k: 0 / 4 / 113 -> 0 / 1 / 1 (plane,
#: bump, cap). The map's distance to the exact one (plane, holes; similarity-aligned RMS
#: over the diameter) mostly falls with it (noise 0.5 jittered 20k: 5.4e-2 / 4.3e-2 ->
#: 2.3e-2 / 2.4e-2; noise 0.25 random 20k: 6.6e-2 / 2.1e-1 -> 1.1e-2 / 8.1e-3), but on
#: jittered samplings at noise 0.25, where neither folds, the DEM's map was the nearer on
#: 3 of 4 (2.5e-3-3.3e-2 against 8.8e-3-2.8e-2); jittered and graded samplings keep the DEM
#: at any noise (:data:`AUTO_CLOSE_PAIR_SHARE`).
AUTO_PROJECTED_ERROR_DEG = 9.5

#: With ``dem="auto"``, noisy points get ``"projected"`` coordinates only where the sampling
#: also has close pairs: at least this share of points whose nearest neighbour lies within
#: :data:`CLOSE_PAIR_SPACINGS` local spacings in the tangent plane (:func:`close_pair_share`).
#: That is where the DEM's fronts fail: they run through short edges whose offsets are
#: mostly noise. Measured shares: random samplings 0.11-0.16 (bump, saddle, 20k, noise 0 to
#: 0.5), jittered and graded 0.000, the real meshes as points 0-0.007 (``real/cortex-lh``
#: 0.084). On jittered samplings at noise 0.5 both kinds gave 0 foldovers; on graded 20k
#: samplings at noise 0.5 the projection lost 2 of 5 (bump: a self-check failure, saddle:
#: ConvergenceError, where the DEM's maps passed), so those keep the DEM.
AUTO_CLOSE_PAIR_SHARE = 0.02

#: Tangent-plane nearest-neighbour distance, in local spacings, below which a point counts
#: as one of a close pair (:func:`close_pair_share`).
CLOSE_PAIR_SPACINGS = 0.2

#: Rows per chunk of :func:`close_pair_share` (bounded (chunk, K, 3) temporaries).
_CLOSE_PAIR_CHUNK = 65536

#: ``dem_variant`` settings: "paper" is Secs. 3-3.1 to the letter; "robust" (default) adds
#: the midpoint projection, front-aligned upwind weights and local-linear normal
#: smoothing (see :mod:`parambench.methods.pointset.dem` and :func:`parambench.methods.pointset.normals.smooth_normals`).
DEM_VARIANTS = {
    "robust": {"projection": "midpoint", "front_weight": True, "smoothing": "linear"},
    "paper": {"projection": "length", "front_weight": False, "smoothing": "average"},
}

#: Neighbourhood averages of the local spacing that sizes balls and area terms.
SMOOTH_SPACING_PASSES = 10

#: ``spacing`` settings of :func:`build_frontend`.
SPACING_MODES = ("local", "global")

#: ``boundary_method`` settings of :func:`build_frontend`.
BOUNDARY_METHODS = ("angle", "rings")

#: ``neighbours`` settings of :func:`build_frontend`.
NEIGHBOUR_MODES = ("auto", "surface", "euclidean", "pruned")

#: When no boundary loop closes, the boundary stage is retried on balls this much wider.
_RETRY_BALL_SCALE = 1.6

#: Keys of ``FrontEnd.timings``, in execution order.
STAGES = ("knn", "normals", "dem", "weights", "boundary")


@dataclass(frozen=True, eq=False)
class FrontEnd:
    """Everything the point-set methods need, computed once.

    Attributes
    ----------
    points : (N, 3) numpy.ndarray of float64
    normals : (N, 3) numpy.ndarray of float64
        Consistently oriented unit normals (the given ones, or PCA normals oriented by
        the rule of :mod:`parambench.methods.pointset.normals`); not smoothed.
    knn_indices : (N, K) numpy.ndarray of int64
        K nearest neighbours, nearest first, self excluded.
    mean_spacing : float
        ``l``, mean kNN edge length.
    local_spacing : (N,) numpy.ndarray of float64
        The spacing of ocp's area terms: around each point
        (:func:`parambench.methods.pointset.neighbourhoods.local_spacing`, ten averages; points on
        or next to a loop take their interior neighbours' value) when
        ``spacing="local"``, ``l`` everywhere when ``spacing="global"``. Ball radii are
        ``ball_eps_factor * max(local_spacing, l)``.
    ball_indices : (N, B) numpy.ndarray of int64
        Geodesic K-eps ball members (-1 padding), see :mod:`parambench.methods.pointset.dem`.
    tangent_coords : (N, B, 2) numpy.ndarray of float64
        DEM tangent coordinates of the ball members.
    W : (N, N) scipy.sparse.csr_matrix of float64
        Row-normalised weights (W^tan or 3D LLE) over the balls; no diagonal.
    L : (N, N) scipy.sparse.csr_matrix of float64
        ``I - W`` (a property, built on first use: ``ocp``'s default energy never reads
        it, and at 1M points it is ~0.35 GB).
    boundary_mask : (N,) numpy.ndarray of bool
        Points of ``boundary_loops``.
    boundary_loops : list of (L_i,) numpy.ndarray of int64
        Ordered loops, longest first; outer counter-clockwise, holes clockwise, seen
        from the normals' side.
    reconstruction_error : (N,) numpy.ndarray of float64
        ``R_x`` per point (tangent plane for W^tan, 3D for LLE), in squared length units.
    diagnostics : dict
        JSON-serialisable facts (see :func:`build_frontend`).
    timings : dict of str to float
        Seconds per stage: knn, normals, dem, weights, boundary.
    params : dict
        The parameters used.
    """

    points: np.ndarray
    normals: np.ndarray
    knn_indices: np.ndarray
    mean_spacing: float
    local_spacing: np.ndarray
    ball_indices: np.ndarray
    tangent_coords: np.ndarray
    W: sp.csr_matrix
    boundary_mask: np.ndarray
    boundary_loops: list
    reconstruction_error: np.ndarray
    diagnostics: dict = field(default_factory=dict)
    timings: dict = field(default_factory=dict)
    params: dict = field(default_factory=dict)

    @property
    def n_points(self) -> int:
        """N."""
        return int(self.points.shape[0])

    @property
    def L(self) -> sp.csr_matrix | None:  # noqa: N802 - the paper's name
        """``I - W``, built on first use and kept; None once :meth:`without_balls` dropped W."""
        if self.W is None:
            return None
        cached = self.__dict__.get("_laplacian")
        if cached is None:
            cached = graph_laplacian(self.W)
            object.__setattr__(self, "_laplacian", cached)  # a cache, not state: frozen otherwise
        return cached

    def without_balls(self) -> "FrontEnd":
        """A copy without the per-ball data (balls, tangent coordinates, W, L): set to None.

        Solvers that have built their operator call this before factorising, so that at
        1M points the ~1.3 GB of ball data is not held through the factorisation.
        """
        return replace(self, ball_indices=None, tangent_coords=None, W=None)


#: Spread of the points across their principal line over their spread along it, below which
#: they sample a curve, not a surface (a 20:1 strip spreads 0.05 across, 400:1 0.0025).
MIN_CROSS_SPREAD = 1e-3


def require_two_dimensional(points: np.ndarray) -> None:
    """Raise unless the points spread in two directions (they are no line or curve segment).

    Collinear points reached the boundary search, which took them for a set with no inside
    ("500 of the 500 points pass ...: sample the surface more densely") or for several
    components, neither of which says what is wrong.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64

    Raises
    ------
    InvalidInputError
        The standard deviation across the principal line is under ``MIN_CROSS_SPREAD`` of
        that along it, among the points of :func:`~parambench.datasets_gen.surface.core_box`.
    """
    lo, hi = core_box(points)
    core = points[np.all((points >= lo) & (points <= hi), axis=1)]
    # A junk row far away (0 0 0 in a georeferenced scan) would be the line's direction.
    core = core if core.shape[0] >= MIN_POINTS else points
    centred = core - core.mean(axis=0)
    variances = np.sort(np.linalg.eigvalsh(centred.T @ centred))[::-1]
    spread = float(np.sqrt(max(variances[1], 0.0) / variances[0])) if variances[0] > 0 else 0.0
    if spread < MIN_CROSS_SPREAD:
        raise InvalidInputError(
            f"the points lie on a line (their spread across it is {spread:.1e} of their spread along it): they "
            "sample a curve, not a surface; pass points that cover the surface in two directions.")


def validate_inputs(points: Any, normals: Any, params: FrontEndParams) -> tuple[np.ndarray, np.ndarray | None]:
    """Check the options and the arrays of :func:`build_frontend` (its first step, not timed).

    Parameters
    ----------
    points : (N, 3) array_like of float
    normals : (N, 3) array_like of float or None
    params : FrontEndParams

    Returns
    -------
    points : (N, 3) numpy.ndarray of float64
    normals : (N, 3) numpy.ndarray of float64 or None
        The given normals, checked for shape and finiteness (their orientation is
        checked by :func:`normals_stage`).

    Raises
    ------
    InvalidInputError
        An option outside its allowed values, or bad arrays.
    TooFewPointsError
        Fewer than ``k_nn + 1`` points.

    Coincident points are refused by :func:`knn_stage`, from the kNN graph's distances
    (a separate check built its own kd-tree: 1.3 s at a million points).
    """
    k_nn = params.k_nn
    if params.dem_variant not in DEM_VARIANTS:
        raise InvalidInputError(f"dem_variant must be one of {', '.join(DEM_VARIANTS)}, got {params.dem_variant!r}.")
    if params.weights not in WEIGHT_KINDS:
        raise InvalidInputError(f"weights must be one of {', '.join(WEIGHT_KINDS)}, got {params.weights!r}.")
    if params.dem not in DEM_CHOICES:
        raise InvalidInputError(f"dem must be one of {', '.join(DEM_CHOICES)}, got {params.dem!r}.")
    if int(k_nn) != k_nn or k_nn < 2:
        raise InvalidInputError(f"k_nn must be an integer >= 2, got {k_nn}.")
    pts = validate_points(points, min_points=max(MIN_POINTS, int(k_nn) + 1))
    require_two_dimensional(pts)
    nrm = None if normals is None else validate_normals(normals, pts.shape[0])
    # Checked after the arrays, as before the stages were split (the first error reported stays the same).
    if params.spacing not in SPACING_MODES:
        raise InvalidInputError(f"spacing must be one of {', '.join(SPACING_MODES)}, got {params.spacing!r}.")
    if params.boundary_method not in BOUNDARY_METHODS:
        raise InvalidInputError(f"boundary_method must be one of {', '.join(BOUNDARY_METHODS)}, "
                                f"got {params.boundary_method!r}.")
    if params.neighbours not in NEIGHBOUR_MODES:
        raise InvalidInputError(f"neighbours must be one of {', '.join(NEIGHBOUR_MODES)}, "
                                f"got {params.neighbours!r}.")
    return pts, nrm


class Neighbourhoods(NamedTuple):
    """What :func:`knn_stage` computes; every array is in kd-tree order (``points``).

    Attributes
    ----------
    order : (N,) numpy.ndarray of int64
        ``points = input_points[order]``.
    inv : (N,) numpy.ndarray of int64
        The inverse permutation: ``input_points = points[inv]``.
    points : (N, 3) numpy.ndarray of float64
        The points in kd-tree order.
    graph : parambench.methods.pointset.neighbourhoods.KnnGraph
        K nearest neighbours (indices into ``points``).
    neighbour_diagnostics : dict
        Facts of the surface neighbour search (empty for "euclidean").
    adjacency : (N, N) scipy.sparse.csr_matrix or None
        The symmetrised kNN graph (None once dropped by :func:`build_frontend`).
    spacing : float
        ``l``, the mean kNN edge length.
    h_around : (N,) numpy.ndarray of float64
        Spacing around each point, one average (the boundary's loop-spacing rule).
    h_local : (N,) numpy.ndarray of float64
        Spacing field of balls and area terms: ten averages for ``spacing="local"``,
        ``l`` everywhere for "global".
    lips : (N,) numpy.ndarray of bool or None
        Points that lost a kNN edge to :func:`slot_stage`, and those edges' other ends (the
        slots' front rows); None when nothing was cut.
    slot_ends : (N,) numpy.ndarray of bool or None
        Ends of every edge :func:`slot_stage` cut (also candidates beyond the K nearest).
    """

    order: np.ndarray
    inv: np.ndarray
    points: np.ndarray
    graph: Any
    neighbour_diagnostics: dict
    adjacency: sp.csr_matrix | None
    spacing: float
    h_around: np.ndarray
    h_local: np.ndarray
    lips: np.ndarray | None = None
    slot_ends: np.ndarray | None = None


def knn_stage(pts: np.ndarray, k_nn: int, neighbours: str = "auto", spacing_mode: str = "local", *,
              unique_checked: bool = False) -> Neighbourhoods:
    """Stage ``knn``: kd-tree order, the kNN graph, its connectedness, and the spacing fields.

    Parameters
    ----------
    pts : (N, 3) numpy.ndarray of float64
        Checked points, input order.
    k_nn : int
    neighbours : {"auto", "euclidean", "surface", "pruned"}
    spacing_mode : {"local", "global"}
    unique_checked : bool
        The points were found free of copies already (a second graph on the same points).

    Returns
    -------
    Neighbourhoods

    Raises
    ------
    DuplicatePointsError
        Coincident points (within :func:`~parambench.datasets_gen.surface.duplicate_tolerance`).
    DisconnectedError
        The kNN graph has several components.
    """
    n = pts.shape[0]
    # Every stage runs on the points in kd-tree order (memory locality of the graph
    # searches; see spatial_order) and the results are mapped back to the input order.
    order = spatial_order(pts)
    inv = np.empty_like(order)
    inv[order] = np.arange(n, dtype=np.int64)
    p = pts[order]
    if neighbours in ("surface", "pruned") and not unique_checked:
        # Their plane tests divide by edge lengths: a copy must be refused before them.
        require_unique_points(pts)
        unique_checked = True
    if neighbours == "surface":
        graph, nbr_diag = surface_knn_graph(p, k_nn)
    elif neighbours == "pruned":
        graph, nbr_diag = pruned_knn_graph(p, k_nn)
    elif neighbours == "auto":
        graph, nbr_diag = gap_aware_knn_graph(p, k_nn)
    else:
        graph, nbr_diag = knn_graph(p, k_nn), {}
    # A point with a copy has it as its nearest neighbour in the Euclidean graph; the
    # other graphs may leave it out, so they are checked on their own.
    euclidean = neighbours in ("euclidean", "auto") and not nbr_diag.get("pruned", False)
    if not unique_checked and (not euclidean or graph.distances[:, 0].min() <= duplicate_tolerance(pts)):
        require_unique_points(pts)  # the exact check, and its message naming a pair
    adjacency = symmetric_adjacency(graph)
    require_connected(adjacency, k_nn, p)
    spacing = graph.mean_spacing
    # The loop-spacing rule of the boundary needs the spacing right at the loop (one
    # average); balls and area terms need a smooth field (ten: noise-free on uniform
    # random samples, still following a graded sampling's density).
    h_around = local_spacing(graph, passes=1)
    h_local = local_spacing(graph, passes=SMOOTH_SPACING_PASSES) if spacing_mode == "local" else np.full(n, spacing)
    return Neighbourhoods(order=order, inv=inv, points=p, graph=graph, neighbour_diagnostics=nbr_diag,
                          adjacency=adjacency, spacing=spacing, h_around=h_around, h_local=h_local)


def slot_stage(nb: Neighbourhoods, normals: np.ndarray, k_nn: int, spacing_mode: str = "local") -> Neighbourhoods:
    """Part of stage ``knn``: the graph without its edges across slots (:mod:`.slot_cuts`).

    Parameters
    ----------
    nb : Neighbourhoods
    normals : (N, 3) numpy.ndarray of float64
        Normals of ``nb.points`` (orientation does not matter).
    k_nn : int
    spacing_mode : {"local", "global"}

    Returns
    -------
    Neighbourhoods
        ``nb`` with ``neighbour_diagnostics["slots"]`` (:func:`.slot_cuts.slot_cut_graph`'s
        facts, and ``disconnected``: True when the cut left the graph in pieces, so
        nothing was cut); where edges were cut, its graph, adjacency and spacing fields
        follow the cut graph.
    """
    graph, facts, lips = slot_cut_graph(nb.points, nb.graph, normals, nb.h_local, nb.h_around)
    diagnostics = dict(nb.neighbour_diagnostics, slots=facts)
    if not facts["n_slot_edges"]:
        return nb._replace(neighbour_diagnostics=diagnostics)
    adjacency = symmetric_adjacency(graph)
    if _component_sizes(adjacency).size > 1:
        # A slot ends somewhere: cuts that split the surface cut along a sampling's rows
        # (scan lines 10 spacings apart at k_nn=12: 7169, 2446 and 1242 points), and
        # the uncut graph, which is connected, maps (exactly, at k_nn=16).
        diagnostics["slots"] = dict(facts, n_slot_edges=0, disconnected=True)
        return nb._replace(neighbour_diagnostics=diagnostics)
    h_local = (local_spacing(graph, passes=SMOOTH_SPACING_PASSES) if spacing_mode == "local"
               else np.full(graph.indices.shape[0], graph.mean_spacing))
    return nb._replace(graph=graph, neighbour_diagnostics=diagnostics, adjacency=adjacency,
                       spacing=graph.mean_spacing, h_around=local_spacing(graph, passes=1), h_local=h_local,
                       lips=cut_ends(nb.graph, graph), slot_ends=lips)


def normals_stage(points: np.ndarray, given: np.ndarray | None, graph: Any, spacing: float, *,
                  smooth: bool = True, smoothing: str = "linear", noisy: bool = False
                  ) -> tuple[np.ndarray, np.ndarray, dict]:
    """Stage ``normals``: oriented unit normals, the (smoothed) normals of the DEM frames, fit facts.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    given : (N, 3) numpy.ndarray of float64 or None
        The caller's normals, same order as ``points``; PCA normals oriented along a
        minimum spanning tree when None.
    graph : parambench.methods.pointset.neighbourhoods.KnnGraph
        kNN graph of ``points``.
    spacing : float
        Mean spacing ``l``.
    smooth : bool
        Smooth the frame normals (``smooth_normals``).
    smoothing : {"linear", "average"}
        How (the DEM variant's rule, :func:`parambench.methods.pointset.normals.smooth_normals`).
    noisy : bool
        Refit towards :data:`~parambench.methods.pointset.normals.NOISY_TARGET_DEG` on up to
        :data:`~parambench.methods.pointset.normals.NOISY_MAX_K` neighbours (noisy samplings
        with close pairs).

    Returns
    -------
    oriented : (N, 3) numpy.ndarray of float64
        Consistently oriented unit normals (the given ones when given).
    frame_normals : (N, 3) numpy.ndarray of float64
        ``oriented`` smoothed, or ``oriented`` itself when ``smooth`` is False.
    normal_fit : dict
        Facts of :func:`~parambench.methods.pointset.normals.noise_adaptive_normals` (how
        many points were refitted on larger neighbourhoods, the predicted fit error).

    Raises
    ------
    InconsistentNormalsError
        Given normals are inconsistently oriented or not normal to the points.
    """
    # PCA on the kNN, refitted on more points where the fit residual says noise.
    refit = {"target_deg": NOISY_TARGET_DEG, "max_k": NOISY_MAX_K} if noisy else {}
    fitted, normal_fit, fit_error = noise_adaptive_normals(points, graph.indices, return_error=True, **refit)
    if given is not None:
        oriented = given
        check_user_normals(points, oriented, fitted, graph.indices)
    else:
        oriented = orient_normals(points, fitted, graph.indices, fit_error)
    frame_normals = (neighbourhood_smoothed(points, oriented, graph.indices, graph.distances, spacing,
                                            method=smoothing)
                     if smooth else oriented)
    return oriented, frame_normals, normal_fit


def resolved_dem(params: FrontEndParams, normal_fit: dict | None, close_pairs: float | None = None) -> str:
    """The DEM kind ``params.dem`` stands for: itself, or for "auto" the choice by noise and sampling.

    "auto" gives "projected" when the normals were fitted here, the median predicted
    error of their kNN plane fits is at least :data:`AUTO_PROJECTED_ERROR_DEG` (noisy
    points) and at least :data:`AUTO_CLOSE_PAIR_SHARE` of the points are close pairs
    (``close_pairs``, :func:`close_pair_share`); "upwind" otherwise: on clean points,
    regular samplings, with given normals, and always for ``dem_variant="paper"`` (the
    paper's DEM to the letter).

    Parameters
    ----------
    params : FrontEndParams
    normal_fit : dict or None
        The normals stage's facts
        (:func:`~parambench.methods.pointset.normals.noise_adaptive_normals`).
    close_pairs : float, optional
        Share of close pairs; not known (None): the upwind DEM.

    Returns
    -------
    str
        One of :data:`~parambench.methods.pointset.dem.DEM_KINDS`.
    """
    if params.dem != "auto":
        return params.dem
    projected = (noisy_fits(normal_fit) and close_pairs is not None and close_pairs >= AUTO_CLOSE_PAIR_SHARE
                 and params.dem_variant != "paper")
    return "projected" if projected else "upwind"


def noisy_fits(normal_fit: dict | None) -> bool:
    """Whether the normals stage's fits say noise (median predicted error >= :data:`AUTO_PROJECTED_ERROR_DEG`)."""
    median = fit_error_median(normal_fit)
    return median is not None and median >= AUTO_PROJECTED_ERROR_DEG


def close_pair_share(points: np.ndarray, normals: np.ndarray, knn_indices: np.ndarray, spacing: np.ndarray) -> float:
    """Share of points whose nearest neighbour, measured in their tangent plane, is closer than :data:`CLOSE_PAIR_SPACINGS`.

    Parameters
    ----------
    points, normals : (N, 3) numpy.ndarray of float64
        Unit normals.
    knn_indices : (N, K) numpy.ndarray of int64
    spacing : (N,) numpy.ndarray of float64
        Local spacing per point (same length unit as ``points``).

    Returns
    -------
    float
        In [0, 1]. In the tangent plane, so that normal noise does not hide a pair.
    """
    close = np.empty(points.shape[0], dtype=bool)

    def rows_of(rows: slice) -> None:
        d = points[knn_indices[rows]] - points[rows, None, :]
        along = np.einsum("nki,ni->nk", d, normals[rows])
        in_plane = np.sqrt(np.maximum(np.einsum("nki,nki->nk", d, d) - along**2, 0.0))
        close[rows] = in_plane.min(axis=1) < CLOSE_PAIR_SPACINGS * spacing[rows]

    for_each_chunk(rows_of, points.shape[0], _CLOSE_PAIR_CHUNK)
    return float(close.mean()) if close.size else 0.0


def dem_stage(points: np.ndarray, frame_normals: np.ndarray, adjacency: sp.csr_matrix, spacing: float,
              h_local: np.ndarray, *, ball_k: int, ball_eps_factor: float, dem: str, max_ball: int,
              dem_variant: str = "robust"):
    """Stage ``dem``: geodesic K-eps balls with DEM tangent coordinates.

    Also the wider balls of the boundary stage's retry. Radii are
    ``ball_eps_factor * max(h_local, spacing)``.

    Parameters
    ----------
    points, frame_normals : (N, 3) numpy.ndarray of float64
    adjacency : (N, N) scipy.sparse.csr_matrix
        Symmetrised kNN graph.
    spacing : float
        Mean spacing ``l``.
    h_local : (N,) numpy.ndarray of float64
        Spacing field (see :class:`Neighbourhoods`).
    ball_k, ball_eps_factor, dem, max_ball
        As in :class:`~parambench.methods.pointset.params.FrontEndParams`.
    dem_variant : {"robust", "paper"}
        Selects projection and upwind weighting (:data:`DEM_VARIANTS`).

    Returns
    -------
    parambench.methods.pointset.dem.GeodesicBalls
    """
    variant = DEM_VARIANTS[dem_variant]
    return dem_balls(points, frame_normals, adjacency, spacing, ball_k=int(ball_k),
                     ball_eps_factor=ball_eps_factor, dem=dem, max_ball=max_ball,
                     projection=variant["projection"], front_weight=variant["front_weight"],
                     local_spacing=np.maximum(h_local, spacing))


def weights_stage(points: np.ndarray, balls, weights: str = "tangent",
                  reg_eps: float = DEFAULT_REG_EPS) -> tuple[np.ndarray, np.ndarray]:
    """Stage ``weights`` (first part): reconstruction weights per ball and their errors ``R_x``.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    balls : parambench.methods.pointset.dem.GeodesicBalls
    weights : {"tangent", "lle3d"}
        W^tan on the tangent coordinates (Eq. 13) or 3D LLE weights (Eqs. 10-12).
    reg_eps : float

    Returns
    -------
    w : (N, B) numpy.ndarray of float64
        Row i's weights of ``balls.indices[i]`` (zero at padding); rows sum to 1.
    r_x : (N,) numpy.ndarray of float64
        Reconstruction error per point (tangent plane for W^tan, 3D for LLE).
    """
    mask = balls.mask
    n = points.shape[0]
    if weights == "tangent":
        w = tangent_weights(balls.coords, mask, float(reg_eps))
        r_x = reconstruction_error(balls.coords, w)
    else:
        w = lle3d_weights(points, balls.indices, float(reg_eps))
        r_x = np.empty(n)
        for lo in range(0, n, 65536):  # 3D offsets chunked: (chunk, B, 3) at a time
            sl = slice(lo, min(lo + 65536, n))
            offsets = points[np.where(mask[sl], balls.indices[sl], 0)] - points[sl, None, :]
            r_x[sl] = reconstruction_error(offsets, w[sl])
    return w, r_x


def boundary_stage(nb: Neighbourhoods, frame_normals: np.ndarray, balls, params: FrontEndParams,
                   lattice: bool = False, given: list | None = None, fit_error_deg: float | None = None):
    """Stage ``boundary``: the boundary loops, in kd-tree order.

    With ``boundary_method="angle"``, when at least ``4 * min_loop_size`` points pass the
    angle criterion but no loop closes (a ragged, sparsely sampled boundary), the stage
    is run once more on balls 1.6x wider (W keeps the normal balls); where the loops leave
    boundary candidates that ring a missed hole, it is run again at lower angles
    (:func:`_covering_angle`). On a lattice the
    loops are the rim of its cells rebuilt from the points where those make a clean
    surface (:func:`~parambench.methods.pointset.lattice_loops.lattice_loops`; the angle
    criterion's candidates are kept for the self-check), ``diagnostics["loops_from"]``
    says which.

    Parameters
    ----------
    nb : Neighbourhoods
        From :func:`knn_stage` (adjacency still held).
    frame_normals : (N, 3) numpy.ndarray of float64
    balls : parambench.methods.pointset.dem.GeodesicBalls
        From :func:`dem_stage`.
    params : FrontEndParams
    lattice : bool
        The points are a lattice (:func:`~parambench.methods.pointset.lattice.is_lattice`).
    given : list of (L_i,) numpy.ndarray of int64, optional
        Loops known to the caller, in kd-tree order.
    fit_error_deg : float, optional
        Median predicted error of the normals stage's plane fits on ``k_nn`` neighbours
        (degrees): where it says noise, the NoBoundaryError names it.

    Returns
    -------
    boundary : parambench.methods.pointset.boundary.BoundaryLoops
        Loops as indices into ``nb.points``.
    retried : bool
        The wider balls were tried.

    Raises
    ------
    NoBoundaryError
        No loop closed (with the noise named where ``fit_error_deg`` says so).
    """
    p, spacing = nb.points, nb.spacing
    min_loop_size = int(params.min_loop_size)
    bnd_args = dict(angle_deg=float(params.boundary_angle_deg), decimate=int(params.boundary_decimate),
                    min_loop_size=min_loop_size, require_loop=False, local_spacing=nb.h_around, lips=nb.lips,
                    slot_ends=nb.slot_ends)
    retried = False
    if params.boundary_method == "rings":
        bnd = find_boundary_rings(p, frame_normals, nb.h_around, decimate=int(params.boundary_decimate),
                                  min_loop_size=min_loop_size)
    else:
        bnd = find_boundary(p, frame_normals, balls.indices, balls.coords, **bnd_args)
    if given is not None:
        # Given loops may run either way; the front end's run with the surface on their left.
        given = [surface_on_the_left(p, frame_normals, np.asarray(lp, dtype=np.int64), nb.graph.indices)
                 for lp in given]
        return _with_loops(bnd, given, 1, "given"), False
    if params.boundary_method != "rings":
        cells = lattice_loops(p, frame_normals, nb.graph.indices) if lattice else None
        if cells is not None:
            return _with_loops(bnd, cells, int(params.boundary_decimate), "lattice cells"), False
    if params.boundary_method == "angle" and not bnd.loops and bnd.candidates.sum() >= 4 * params.min_loop_size:
        # Many boundary candidates but no closed loop: a ragged, sparsely sampled
        # boundary. Retry the boundary stage alone on wider balls (W is unaffected).
        wide = dem_stage(p, frame_normals, nb.adjacency, spacing, nb.h_local, ball_k=params.ball_k,
                         ball_eps_factor=_RETRY_BALL_SCALE * float(params.ball_eps_factor),
                         dem=resolved_dem(params, None),  # build_frontend passes its choice
                         max_ball=int(_RETRY_BALL_SCALE**2 * params.max_ball) + 1, dem_variant=params.dem_variant)
        wide_bnd = find_boundary(p, frame_normals, wide.indices, wide.coords, **bnd_args)
        del wide
        retried = True
        if wide_bnd.loops:
            bnd = wide_bnd
    if params.boundary_method == "angle" and bnd.loops:
        bnd = _covering_angle(nb, frame_normals, balls, bnd, bnd_args)
    if not bnd.loops and params.boundary_method == "rings":
        raise NoBoundaryError(
            f"boundary_method='rings' found no boundary loop ({int(bnd.candidates.sum())} points border an "
            "empty triangle): a closed surface (cut it open before flattening), or a noisy sampling; "
            "try boundary_method='angle'.")
    if not bnd.loops:
        from .failure_causes import noisy_points_note  # only on this path: it imports the spectral solvers
        from .handles import handle_note

        raise no_boundary_error(int(bnd.candidates.sum()), float(params.boundary_angle_deg), min_loop_size,
                                p.shape[0], note=noisy_points_note(fit_error_deg, nb.graph.indices.shape[1])
                                or handle_note(p, frame_normals))
    return bnd, retried


def _covering_angle(nb: Neighbourhoods, frame_normals: np.ndarray, balls, bnd, bnd_args: dict):
    """``bnd``, or the loops of a lower angle where ``bnd``'s leave a missed hole and those do not.

    The self-check's coverage test (:func:`~parambench.methods.pointset.selfcheck.loop_coverage`:
    a group of candidates on no loop, or a chain of them round an empty disk, where the
    sampling is regular enough to tell) on the loops; where it fails, the boundary stage
    alone runs again at each of :data:`~parambench.methods.pointset.boundary.LOWER_ANGLES_DEG`
    below the angle used, and the first whose loops pass the same test on its own
    candidates replaces it (``diagnostics["angle_lowered_to"]``). Before, the whole
    method ran again at those angles after a map failed its check for it: on the LiDAR
    tile ``real/lidar-ground`` 10.4 s instead of 2.7 s. The lower angles run on the
    stage's own balls, also where the wider balls' loops were taken.
    """
    from .selfcheck import loop_coverage  # the self-check's own test, so both judge alike

    def covered(b) -> bool:
        return loop_coverage(nb.points, b.loops, b.candidates, nb.graph.indices, nb.spacing)["passed"]

    if covered(bnd):
        return bnd
    for angle in (a for a in LOWER_ANGLES_DEG if a < bnd_args["angle_deg"]):
        low = find_boundary(nb.points, frame_normals, balls.indices, balls.coords, **{**bnd_args, "angle_deg": angle})
        if low.loops and covered(low):
            low.diagnostics["angle_lowered_to"] = angle
            return low
    return bnd


def _with_loops(bnd, loops: list, decimate: int, source: str):
    """``bnd`` (a BoundaryLoops) with ``loops`` (from ``source``) in place of its own, its candidates kept."""
    loops = [loop[::decimate] if decimate > 1 else loop for loop in loops]
    mask = np.zeros(bnd.mask.shape[0], dtype=bool)
    mask[np.concatenate(loops)] = True
    diagnostics = dict(bnd.diagnostics, loops_from=source, angle_loop_sizes=bnd.diagnostics.get("loop_sizes"),
                       loop_sizes=[int(len(loop)) for loop in loops], n_in_loops=int(mask.sum()))
    return replace(bnd, loops=loops, mask=mask, diagnostics=diagnostics)


def stage_diagnostics(nb: Neighbourhoods, balls, w: np.ndarray, r_x: np.ndarray, bnd, retried: bool, *,
                      k_nn: int, normals_given: bool, neighbours: str, normal_fit: dict | None = None) -> dict:
    """The JSON-serialisable ``FrontEnd.diagnostics`` from the stages' outputs (see :func:`build_frontend`).

    Parameters
    ----------
    nb : Neighbourhoods
    balls : parambench.methods.pointset.dem.GeodesicBalls
    w : (N, B) numpy.ndarray of float64
        Ball weights (kd-tree order, as ``balls``).
    r_x : (N,) numpy.ndarray of float64
    bnd : parambench.methods.pointset.boundary.BoundaryLoops
    retried : bool
    k_nn : int
    normals_given : bool
    neighbours : str
    normal_fit : dict, optional
        The normals stage's fit facts (stored as ``normal_fit``).

    Returns
    -------
    dict
    """
    spacing = nb.spacing
    rel = r_x / spacing**2
    return {
        "n_points": int(nb.points.shape[0]),
        "k_nn": k_nn,
        "mean_spacing": float(spacing),
        "normals_source": "given" if normals_given else "pca",
        "normal_fit": normal_fit or {},
        "neighbours": dict(nb.neighbour_diagnostics, mode=neighbours),
        "ball_size": {"min": int(balls.sizes.min()), "mean": float(balls.sizes.mean()),
                      "max": int(balls.sizes.max())},
        "n_truncated_balls": int(balls.n_truncated),
        "negative_weights": negative_weight_stats(w, balls.mask, bnd.candidates),
        "reconstruction_error": {"mean": float(rel.mean()), "max": float(rel.max()), "unit": "l^2"},
        "boundary": dict(bnd.diagnostics, retried_with_wider_balls=retried),
    }


def build_frontend(points: Any, normals: Any = None, params: FrontEndParams | None = None, *,
                   given_loops: list | None = None, **options: Any) -> FrontEnd:
    """Run the point-set front end of Schmidt & Singh on a point set.

    Stages, each a function of this module: checks (:func:`validate_inputs`); Euclidean
    kNN graph and mean spacing ``l`` (``knn``, :func:`knn_stage`); PCA normals oriented
    along a minimum spanning tree, or the given ones checked (``normals``,
    :func:`normals_stage`); DEM geodesic balls with tangent coordinates (``dem``,
    :func:`dem_stage`); W^tan or 3D LLE weights (``weights``, :func:`weights_stage`);
    boundary loops by the angle criterion (``boundary``, :func:`boundary_stage`); then
    ``L = I - W`` (``weights`` again). All stages run on the points in kd-tree order
    (cache locality) and results come back in input order. When many points pass the
    angle criterion but no loop closes (a ragged, sparsely sampled boundary), the
    boundary stage alone is retried once on balls 1.6x wider
    (``diagnostics["boundary"]["retried_with_wider_balls"]``); when the loops leave
    candidates that ring a missed hole, at 100 and then 90 degrees
    (``diagnostics["boundary"]["angle_lowered_to"]``, where one covers them).

    Parameters
    ----------
    points : (N, 3) array_like of float
    normals : (N, 3) array_like of float, optional
        Consistently oriented normals; estimated when omitted.
    params : FrontEndParams, optional
        The options (see its fields); the defaults when omitted.
    given_loops : list of (L_i,) array_like of int, optional
        Boundary loops known to the caller (indices of ``points``, walking order): used as
        the loops instead of detected ones (the angle criterion still gives the
        candidates; ``diagnostics["boundary"]["loops_from"]`` is "given"), so no
        NoBoundaryError.
    **options
        Fields of :class:`FrontEndParams` to change in ``params``, e.g. ``k_nn=12``.

    Returns
    -------
    FrontEnd
        ``diagnostics`` holds: ``n_points``, ``k_nn``, ``mean_spacing``, ``normals_source``
        ("given"/"pca"), ``normal_fit`` (:func:`~parambench.methods.pointset.normals.noise_adaptive_normals`
        facts), ``ball_size`` {min, mean, max}, ``n_truncated_balls``,
        ``negative_weights`` (:func:`~parambench.methods.pointset.tangent_weights.negative_weight_stats`,
        interior vs. angle-criterion boundary points), ``reconstruction_error`` {mean,
        max, unit: "l^2"} (R_x divided by l^2), ``boundary`` (loop extraction facts),
        ``dem`` (the DEM used), ``lattice`` (whether the points are a lattice: a raster, a
        range image, a grid sampling; :func:`~parambench.methods.pointset.lattice.is_lattice`).

    Raises
    ------
    TypeError
        A keyword in ``options`` that is not a field of :class:`FrontEndParams`.
    InvalidInputError
        Bad arrays (shape, NaN/inf) or option values.
    TooFewPointsError
        Fewer than ``k_nn + 1`` points.
    DuplicatePointsError
        Coincident points.
    DisconnectedError
        The kNN graph has several components.
    InconsistentNormalsError
        Given normals are inconsistently oriented or not normal to the points.
    NoBoundaryError
        No boundary loop: a closed surface, or (worded differently) a boundary too
        ragged to close even on the wider balls.
    """
    params = replace(FrontEndParams() if params is None else params, **options)
    pts, given = validate_inputs(points, normals, params)
    variant = DEM_VARIANTS[params.dem_variant]
    k_nn = int(params.k_nn)
    timer = StageTimer()

    # "auto" starts from the Euclidean graph; a screen with the normals fitted on it
    # decides whether the gap-aware graph (about 10x the kNN search) is worth building.
    screened = params.neighbours == "auto"
    with timer("knn"):
        nb = knn_stage(pts, k_nn, "euclidean" if screened else params.neighbours, params.spacing)
    order, inv = nb.order, nb.inv

    def fit_normals(nb: Neighbourhoods, noisy: bool = False):
        with timer("normals"):
            return normals_stage(nb.points, None if given is None else given[order], nb.graph, nb.spacing,
                                 smooth=params.smooth_normals, smoothing=variant["smoothing"], noisy=noisy)

    oriented, frame_normals, normal_fit = fit_normals(nb)
    if screened:
        with timer("knn"):
            suspects = gap_suspected(nb.points, nb.graph, oriented)
            nb = (knn_stage(pts, k_nn, "auto", params.spacing, unique_checked=True) if suspects
                  else nb._replace(neighbour_diagnostics={"pruned": False, "n_gap_edges": 0}))
            nb = nb._replace(neighbour_diagnostics=dict(nb.neighbour_diagnostics, screen_suspects=suspects))
        if nb.neighbour_diagnostics["pruned"]:
            oriented, frame_normals, normal_fit = fit_normals(nb)

    def dem_to_boundary(nb: Neighbourhoods, normals: tuple):
        oriented, frame_normals, normal_fit = normals
        close_pairs = (close_pair_share(nb.points, frame_normals, nb.graph.indices, nb.h_local)
                       if params.dem == "auto" and noisy_fits(normal_fit) else None)
        chosen = replace(params, dem=resolved_dem(params, normal_fit, close_pairs))
        if chosen.dem == "projected" and params.dem == "auto" and given is None:
            normals = fit_normals(nb, noisy=True)  # see normals.NOISY_TARGET_DEG
            oriented, frame_normals, normal_fit = normals
        with timer("dem"):
            balls = dem_stage(nb.points, frame_normals, nb.adjacency, nb.spacing, nb.h_local, ball_k=chosen.ball_k,
                              ball_eps_factor=float(chosen.ball_eps_factor), dem=chosen.dem,
                              max_ball=int(chosen.max_ball), dem_variant=chosen.dem_variant)
        with timer("weights"):
            w, r_x = weights_stage(nb.points, balls, chosen.weights, chosen.reg_eps)
        with timer("boundary"):
            lattice = is_lattice(nb.points, nb.graph, frame_normals)
            known = None if given_loops is None else [inv[np.asarray(lp, dtype=np.int64)] for lp in given_loops]
            bnd, retried = boundary_stage(nb, frame_normals, balls, chosen, lattice, known,
                                          fit_error_median(normal_fit))
        return balls, w, r_x, bnd, retried, chosen.dem, normals, lattice

    uncut = None
    if params.neighbours == "auto" and params.slot_cuts:
        with timer("knn"):
            cut_nb = slot_stage(nb, oriented, k_nn, params.spacing)
        if cut_nb.neighbour_diagnostics["slots"]["n_slot_edges"]:
            uncut = (nb, oriented, frame_normals, normal_fit)
            oriented, frame_normals, normal_fit = fit_normals(cut_nb)
        nb = cut_nb
    try:
        balls, w, r_x, bnd, retried, dem_used, normals, lattice = dem_to_boundary(nb, (oriented, frame_normals,
                                                                                       normal_fit))
        oriented, frame_normals, normal_fit = normals
        confirmed = uncut is None or slots_on_loops(nb.slot_ends, nb.graph, bnd.mask)
    except NoBoundaryError:
        if uncut is None:
            raise
        confirmed = False
    if not confirmed:
        # The cut lips are on no loop: the walk did not close around the slot, and a
        # graph cut open without a boundary there gives a worse map than the uncut one.
        # The cut graph's balls and weights go first: held through the second pass they
        # doubled the front end's peak (uniform random points at 1M, whose chance strips
        # are cut and then reverted).
        balls = w = r_x = bnd = normals = cut_nb = None
        slots = dict(nb.neighbour_diagnostics["slots"], reverted=True)
        nb, oriented, frame_normals, normal_fit = uncut
        nb = nb._replace(neighbour_diagnostics=dict(nb.neighbour_diagnostics, slots=slots))
        balls, w, r_x, bnd, retried, dem_used, normals, lattice = dem_to_boundary(nb, (oriented, frame_normals,
                                                                                       normal_fit))
        oriented, frame_normals, normal_fit = normals
    del uncut

    with timer("boundary"):
        nb = nb._replace(adjacency=None)  # not needed any more; large at 1M points
        loops = [_from_sorted(loop, order) for loop in bnd.loops]
        loops = [np.roll(loop, -int(np.argmin(loop))) for loop in loops]  # deterministic start

    diagnostics = stage_diagnostics(nb, balls, w, r_x, bnd, retried, k_nn=k_nn, normals_given=given is not None,
                                    neighbours=params.neighbours, normal_fit=normal_fit)
    diagnostics["dem"] = dem_used
    diagnostics["lattice"] = lattice

    # Kept inline (not a stage function) so each big array is released as soon as its
    # input-order copy exists: at 1M points the balls and weights are ~1 GB.
    with timer("weights"):  # back to the input order, then the sparse matrices
        # The largest array first, its sorted copy dropped before the next copy is made:
        # at 1M points this stage set ocp's peak memory (3.27 GB with the harness).
        indices, sorted_coords = balls.indices, balls.coords
        del balls  # its graph distances too
        coords = take_rows(sorted_coords, inv)
        del sorted_coords
        ball_indices = renumbered_rows(indices, inv, order)
        del indices
        # Row i of W takes the weights of sorted row inv[i]: no reordered copy of w.
        w_mat = weight_matrix(ball_indices, w, weight_rows=inv)
        del w

    recorded = {"k_nn": k_nn, "ball_k": int(params.ball_k), "ball_eps_factor": float(params.ball_eps_factor),
                "dem": params.dem, "smooth_normals": bool(params.smooth_normals), "reg_eps": float(params.reg_eps),
                "boundary_angle_deg": float(params.boundary_angle_deg),
                "boundary_decimate": int(params.boundary_decimate), "weights": params.weights,
                "max_ball": int(params.max_ball), "min_loop_size": int(params.min_loop_size),
                "dem_variant": params.dem_variant, "spacing": params.spacing, "neighbours": params.neighbours,
                "boundary_method": params.boundary_method, "slot_cuts": bool(params.slot_cuts)}
    return FrontEnd(points=pts, normals=oriented[inv], knn_indices=renumbered_rows(nb.graph.indices, inv, order),
                    mean_spacing=float(nb.spacing),
                    local_spacing=_interior_spacing(nb.h_local, nb.graph.indices, bnd.mask)[inv],
                    ball_indices=ball_indices, tangent_coords=coords, W=w_mat,
                    boundary_mask=bnd.mask[inv], boundary_loops=loops, reconstruction_error=r_x[inv],
                    diagnostics=diagnostics, timings=dict(timer.timings), params=recorded)


def _interior_spacing(h: np.ndarray, knn: np.ndarray, boundary: np.ndarray) -> np.ndarray:
    """The spacing field with boundary points' values taken from their interior neighbours.

    A boundary point's kNN fill a half disc, so its own kNN distances (and, through the
    averages, its neighbours') overstate the spacing; its area term would then be too
    large. Points on a loop and their kNN neighbours take the mean over their kNN that
    are neither (unchanged where a point has none).
    """
    near = boundary | boundary[knn].any(axis=1)
    src = ~near[knn]
    count = src.sum(axis=1)
    fill = np.where(src, h[knn], 0.0).sum(axis=1) / np.maximum(count, 1)
    return np.where(near & (count > 0), fill, h)


def _from_sorted(indices: np.ndarray, order: np.ndarray) -> np.ndarray:
    """Map point indices of the reordered set back to input indices, keeping -1 padding."""
    return np.where(indices >= 0, order[np.maximum(indices, 0)], -1)
