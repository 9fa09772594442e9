"""One entry point for the point-set front end: kNN graph, normals, DEM balls, weights, boundary.

The point-set methods (LEM, LLE, SDP, OCP) call :func:`build_frontend` and use ``W``,
``L`` and the boundary loops of the returned :class:`FrontEnd`.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import scipy.sparse as sp

from parambench.datasets_gen.errors import InvalidInputError, NoBoundaryError
from parambench.datasets_gen.surface import MIN_POINTS, require_unique_points, validate_normals, validate_points

from ..base import StageTimer
from .boundary import DEFAULT_MIN_LOOP_SIZE, find_boundary, no_boundary_error
from .boundary_rings import find_boundary_rings
from .dem import DEFAULT_MAX_BALL, DEM_KINDS, dem_balls
from .laplacian import graph_laplacian
from .neighbourhoods import knn_graph, local_spacing, require_connected, spatial_order, symmetric_adjacency
# Aliased: build_frontend has a boolean parameter of the same name.
from .surface_neighbours import surface_knn_graph
from .normals import check_user_normals, orient_normals, pca_normals
from .normals import smooth_normals as neighbourhood_smoothed
from .tangent_weights import (
    DEFAULT_REG_EPS,
    lle3d_weights,
    negative_weight_stats,
    reconstruction_error,
    tangent_weights,
    weight_matrix,
)

__all__ = ["FrontEnd", "build_frontend", "WEIGHT_KINDS", "DEM_VARIANTS", "STAGES"]

WEIGHT_KINDS = ("tangent", "lle3d")

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
NEIGHBOUR_MODES = ("surface", "euclidean")

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
        ``I - W``.
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
    L: sp.csr_matrix
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

    def without_balls(self) -> "FrontEnd":
        """A copy without the per-ball data (balls, tangent coordinates, W, L): set to None.

        Solvers that have built their operator call this before factorising, so that at
        1M points the ~1.3 GB of ball data is not held through the factorisation.
        """
        return replace(self, ball_indices=None, tangent_coords=None, W=None, L=None)


def _validate(points: Any, normals: Any, k_nn: int, weights: str, dem: str,
              dem_variant: str) -> tuple[np.ndarray, np.ndarray | None]:
    if dem_variant not in DEM_VARIANTS:
        raise InvalidInputError(f"dem_variant must be one of {', '.join(DEM_VARIANTS)}, got {dem_variant!r}.")
    if weights not in WEIGHT_KINDS:
        raise InvalidInputError(f"weights must be one of {', '.join(WEIGHT_KINDS)}, got {weights!r}.")
    if dem not in DEM_KINDS:
        raise InvalidInputError(f"dem must be one of {', '.join(DEM_KINDS)}, got {dem!r}.")
    if int(k_nn) != k_nn or k_nn < 2:
        raise InvalidInputError(f"k_nn must be an integer >= 2, got {k_nn}.")
    pts = validate_points(points, min_points=max(MIN_POINTS, int(k_nn) + 1))
    require_unique_points(pts)
    nrm = None if normals is None else validate_normals(normals, pts.shape[0])
    return pts, nrm


def build_frontend(points: Any, normals: Any = None, *, k_nn: int = 8, ball_k: int = 6,
                   ball_eps_factor: float = 2.5, dem: str = "upwind", smooth_normals: bool = True,
                   reg_eps: float = DEFAULT_REG_EPS, boundary_angle_deg: float = 120.0,
                   boundary_decimate: int = 1, weights: str = "tangent", max_ball: int = DEFAULT_MAX_BALL,
                   min_loop_size: int = DEFAULT_MIN_LOOP_SIZE, dem_variant: str = "robust",
                   spacing: str = "local", neighbours: str = "euclidean",
                   boundary_method: str = "angle") -> FrontEnd:
    """Run the point-set front end of Schmidt & Singh on a point set.

    Stages: Euclidean kNN graph and mean spacing ``l`` (``knn``); PCA normals oriented
    along a minimum spanning tree, or the given ones checked (``normals``); DEM geodesic
    balls with tangent coordinates (``dem``); W^tan or 3D LLE weights and ``L = I - W``
    (``weights``); boundary loops by the angle criterion (``boundary``). All stages run
    on the points in kd-tree order (cache locality) and results come back in input order.
    When many points pass the angle criterion but no loop closes (a ragged, sparsely
    sampled boundary), the boundary stage alone is retried once on balls 1.6x wider
    (``diagnostics["boundary"]["retried_with_wider_balls"]``).

    Parameters
    ----------
    points : (N, 3) array_like of float
    normals : (N, 3) array_like of float, optional
        Consistently oriented normals; estimated when omitted.
    k_nn : int
        K of the Euclidean neighbourhood graph (paper: 8).
    ball_k : int
        Minimum members of a geodesic ball (paper: 6).
    ball_eps_factor : float
        Geodesic ball radius in units of ``l`` (paper: 2.5).
    dem : {"upwind", "plain"}
        Upwind-average DEM (Eq. 9) or plain DEM (Eq. 8).
    smooth_normals : bool
        Use distance-weighted neighbourhood-averaged normals in the DEM (Sec. 3.1).
    reg_eps : float
        Regularisation eps of Eq. 12 (default 1e-2).
    boundary_angle_deg : float
        Angle-criterion threshold (degrees).
    boundary_decimate : int
        Keep every m-th point of each boundary loop.
    weights : {"tangent", "lle3d"}
        W^tan (Eq. 13) or 3D LLE weights (Eqs. 10-12) on the same balls.
    max_ball : int
        Cap on geodesic ball size.
    min_loop_size : int
        Boundary cycles with fewer points are dropped as sampling gaps.
    spacing : {"local", "global"}
        "local" (default): ocp's area terms follow the spacing around each point, and
        ball radii grow with it where the sampling is sparser than average (never below
        the paper's ``ball_eps_factor * l``: radii smaller than that made ocp fail on a
        400-point random cap), so sparse regions of adaptively sampled surfaces get full
        balls; "global": the paper's single ``eps = ball_eps_factor * l`` everywhere and
        one area per point.
    neighbours : {"euclidean", "surface"}
        "euclidean" (default): the paper's plain K nearest; "surface": K neighbours kept
        along the surface, not across narrow gaps
        (:func:`parambench.methods.pointset.surface_neighbours.surface_knn_graph`). Experimental: it
        does not separate the touching sheets of the camelhead scan and with noise of 0.5
        spacings it loses the outer loop of "holes" at 2k points, so it is not the default.
    boundary_method : {"angle", "rings"}
        "angle" (default): the paper's angle criterion on the geodesic balls, candidates
        chained into loops (:mod:`parambench.methods.pointset.boundary`); "rings": loops of the
        boundary edges of the points' tangent-plane Delaunay one-rings with an alpha-shape
        test (:mod:`parambench.methods.pointset.boundary_rings`): finds slits of regular samplings
        narrower than the balls; otherwise measured on par with "angle".
    dem_variant : {"robust", "paper"}
        "paper": T_q p by length-preserving projection, upwind weights
        ``(|p-q|^2 + eps)^-1``, normals smoothed by weighted averaging, all as in the
        paper. "robust" (default): midpoint projection, front-aligned upwind weights,
        local-linear normal smoothing; at least as accurate on clean samplings and
        2-4x more accurate under noise (see :mod:`parambench.methods.pointset.dem`).

    Returns
    -------
    FrontEnd
        ``diagnostics`` holds: ``n_points``, ``k_nn``, ``mean_spacing``, ``normals_source``
        ("given"/"pca"), ``ball_size`` {min, mean, max}, ``n_truncated_balls``,
        ``negative_weights`` (:func:`~parambench.methods.pointset.tangent_weights.negative_weight_stats`,
        interior vs. angle-criterion boundary points), ``reconstruction_error`` {mean,
        max, unit: "l^2"} (R_x divided by l^2), ``boundary`` (loop extraction facts).

    Raises
    ------
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
    pts, given = _validate(points, normals, k_nn, weights, dem, dem_variant)
    if spacing not in SPACING_MODES:
        raise InvalidInputError(f"spacing must be one of {', '.join(SPACING_MODES)}, got {spacing!r}.")
    spacing_mode = spacing
    if boundary_method not in BOUNDARY_METHODS:
        raise InvalidInputError(f"boundary_method must be one of {', '.join(BOUNDARY_METHODS)}, "
                                f"got {boundary_method!r}.")
    if neighbours not in NEIGHBOUR_MODES:
        raise InvalidInputError(f"neighbours must be one of {', '.join(NEIGHBOUR_MODES)}, got {neighbours!r}.")
    variant = DEM_VARIANTS[dem_variant]
    k_nn = int(k_nn)
    n = pts.shape[0]
    timer = StageTimer()

    # Every stage runs on the points in kd-tree order (memory locality of the graph
    # searches; see spatial_order) and the results are mapped back to the input order.
    with timer("knn"):
        order = spatial_order(pts)
        inv = np.empty_like(order)
        inv[order] = np.arange(n, dtype=np.int64)
        p = pts[order]
        if neighbours == "surface":
            graph, nbr_diag = surface_knn_graph(p, k_nn)
        else:
            graph, nbr_diag = knn_graph(p, k_nn), {}
        adjacency = symmetric_adjacency(graph)
        require_connected(adjacency, k_nn)
        spacing = graph.mean_spacing
        # The loop-spacing rule of the boundary needs the spacing right at the loop (one
        # average); balls and area terms need a smooth field (ten: noise-free on uniform
        # random samples, still following a graded sampling's density).
        h_around = local_spacing(graph, passes=1)
        h_local = local_spacing(graph, passes=SMOOTH_SPACING_PASSES) if spacing_mode == "local" else np.full(n, spacing)

    with timer("normals"):
        fitted = pca_normals(p, graph.indices)
        if given is not None:
            oriented = given[order]
            check_user_normals(p, oriented, fitted, graph.indices)
        else:
            oriented = orient_normals(p, fitted, graph.indices)
        frame_normals = (neighbourhood_smoothed(p, oriented, graph.indices, graph.distances, spacing,
                                                method=variant["smoothing"])
                         if smooth_normals else oriented)
        del fitted

    with timer("dem"):
        balls = dem_balls(p, frame_normals, adjacency, spacing, ball_k=int(ball_k),
                          ball_eps_factor=float(ball_eps_factor), dem=dem, max_ball=int(max_ball),
                          projection=variant["projection"], front_weight=variant["front_weight"],
                          local_spacing=np.maximum(h_local, spacing))
    mask = balls.mask

    with timer("weights"):
        if weights == "tangent":
            w = tangent_weights(balls.coords, mask, float(reg_eps))
            r_x = reconstruction_error(balls.coords, w)
        else:
            w = lle3d_weights(p, balls.indices, float(reg_eps))
            r_x = np.empty(n)
            for lo in range(0, n, 65536):  # 3D offsets chunked: (chunk, B, 3) at a time
                sl = slice(lo, min(lo + 65536, n))
                offsets = p[np.where(mask[sl], balls.indices[sl], 0)] - p[sl, None, :]
                r_x[sl] = reconstruction_error(offsets, w[sl])

    with timer("boundary"):
        bnd_args = dict(angle_deg=float(boundary_angle_deg), decimate=int(boundary_decimate),
                        min_loop_size=int(min_loop_size), require_loop=False, local_spacing=h_around)
        retried = False
        if boundary_method == "rings":
            bnd = find_boundary_rings(p, frame_normals, h_around, decimate=int(boundary_decimate),
                                      min_loop_size=int(min_loop_size))
        else:
            bnd = find_boundary(p, frame_normals, balls.indices, balls.coords, **bnd_args)
        if boundary_method == "angle" and not bnd.loops and bnd.candidates.sum() >= 4 * min_loop_size:
            # Many boundary candidates but no closed loop: a ragged, sparsely sampled
            # boundary. Retry the boundary stage alone on wider balls (W is unaffected).
            wide = dem_balls(p, frame_normals, adjacency, spacing, ball_k=int(ball_k),
                             ball_eps_factor=_RETRY_BALL_SCALE * float(ball_eps_factor), dem=dem,
                             max_ball=int(_RETRY_BALL_SCALE**2 * max_ball) + 1,
                             projection=variant["projection"], front_weight=variant["front_weight"],
                             local_spacing=np.maximum(h_local, spacing))
            wide_bnd = find_boundary(p, frame_normals, wide.indices, wide.coords, **bnd_args)
            del wide
            retried = True
            if wide_bnd.loops:
                bnd = wide_bnd
        if not bnd.loops and boundary_method == "rings":
            raise NoBoundaryError(
                f"boundary_method='rings' found no boundary loop ({int(bnd.candidates.sum())} points border an "
                "empty triangle): a closed surface (cut it open before flattening), or a noisy sampling; "
                "try boundary_method='angle'.")
        if not bnd.loops:
            raise no_boundary_error(int(bnd.candidates.sum()), float(boundary_angle_deg), int(min_loop_size))
        del adjacency
        loops = [_from_sorted(loop, order) for loop in bnd.loops]
        loops = [np.roll(loop, -int(np.argmin(loop))) for loop in loops]  # deterministic start

    rel = r_x / spacing**2
    diagnostics = {
        "n_points": int(n),
        "k_nn": k_nn,
        "mean_spacing": float(spacing),
        "normals_source": "given" if given is not None else "pca",
        "neighbours": dict(nbr_diag, mode=neighbours),
        "ball_size": {"min": int(balls.sizes.min()), "mean": float(balls.sizes.mean()),
                      "max": int(balls.sizes.max())},
        "n_truncated_balls": int(balls.n_truncated),
        "negative_weights": negative_weight_stats(w, mask, bnd.candidates),
        "reconstruction_error": {"mean": float(rel.mean()), "max": float(rel.max()), "unit": "l^2"},
        "boundary": dict(bnd.diagnostics, retried_with_wider_balls=retried),
    }
    del mask

    with timer("weights"):  # back to the input order, then the sparse matrices
        ball_indices = _from_sorted(balls.indices[inv], order)
        coords = balls.coords[inv]
        del balls
        w = w[inv]
        w_mat = weight_matrix(ball_indices, w)
        del w
        lap = graph_laplacian(w_mat)

    params = {"k_nn": k_nn, "ball_k": int(ball_k), "ball_eps_factor": float(ball_eps_factor), "dem": dem,
              "smooth_normals": bool(smooth_normals), "reg_eps": float(reg_eps),
              "boundary_angle_deg": float(boundary_angle_deg), "boundary_decimate": int(boundary_decimate),
              "weights": weights, "max_ball": int(max_ball), "min_loop_size": int(min_loop_size),
              "dem_variant": dem_variant, "spacing": spacing_mode, "neighbours": neighbours,
              "boundary_method": boundary_method}
    return FrontEnd(points=pts, normals=oriented[inv], knn_indices=_from_sorted(graph.indices[inv], order),
                    mean_spacing=float(spacing), local_spacing=_interior_spacing(h_local, graph.indices, bnd.mask)[inv], ball_indices=ball_indices, tangent_coords=coords, W=w_mat, L=lap,
                    boundary_mask=bnd.mask[inv], boundary_loops=loops, reconstruction_error=r_x[inv],
                    diagnostics=diagnostics, timings=dict(timer.timings), params=params)


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
