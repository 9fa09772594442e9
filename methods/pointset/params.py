"""The parameters of the point-set front end, in one dataclass whose defaults are the front end's.

:func:`parambench.methods.pointset.frontend.build_frontend` takes a :class:`FrontEndParams`; the
point-set method plugins accept the fields marked as method parameters (see
:data:`METHOD_FIELDS`) and :data:`parambench.methods.pointset.plugin_support.FRONTEND_DEFAULTS` is
derived from it, so a default is written once.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Any, Mapping

from ..memory_budget import PeakMemory
from .boundary import DEFAULT_MIN_LOOP_SIZE
from .dem import DEFAULT_MAX_BALL
from .tangent_weights import DEFAULT_REG_EPS

__all__ = ["FrontEndParams", "METHOD_FIELDS", "method_defaults", "frontend_params", "FRONTEND_PEAK"]

#: The front end's peak resident memory (``build_frontend`` alone, uniform random points on
#: ``bump``: 3.30 GiB at 1M points, 9.52 GiB at 3M, so taken as linear): every point-set
#: method with a front end needs at least this (:func:`parambench.methods.memory_budget.check_memory`).
FRONTEND_PEAK = PeakMemory(3_000_000, 9.52 * 2**30, 1.0, "the point-set front end")

#: ``metadata`` of a field that every point-set method accepts as its own parameter.
_METHOD = {"method_param": True}


@dataclass(frozen=True)
class FrontEndParams:
    """Options of :func:`~parambench.methods.pointset.frontend.build_frontend`; the defaults are the front end's.

    Fields marked as method parameters (:data:`METHOD_FIELDS`) are parameters of every
    point-set method (``ocp``, ``sdp``, ...). The others are set by the front end's
    callers only: ``weights`` by the method (``lem``'s and ``lle``'s own ``weights``,
    W^tan otherwise), the rest from Python or ``parambench inspect``. Values are checked
    (and cast) by ``build_frontend``, not here.

    Attributes
    ----------
    k_nn : int
        K of the Euclidean neighbourhood graph (paper: 8).
    ball_k : int
        Minimum members of a geodesic ball (paper: 6).
    ball_eps_factor : float
        Geodesic ball radius in units of ``l`` (paper: 2.5).
    dem : {"auto", "upwind", "plain", "projected"}
        Upwind-average DEM (Eq. 9), plain DEM (Eq. 8), or the members' offsets projected
        onto the centre's tangent plane; "auto" (default): "projected" on noisy points of
        a sampling with close pairs, the upwind DEM otherwise
        (:func:`~parambench.methods.pointset.frontend.resolved_dem`).
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
    dem_variant : {"robust", "paper"}
        "paper": T_q p by length-preserving projection, upwind weights
        ``(|p-q|^2 + eps)^-1``, normals smoothed by weighted averaging, all as in the
        paper. "robust" (default): midpoint projection, front-aligned upwind weights,
        local-linear normal smoothing; at least as accurate on clean samplings and
        2-4x more accurate under noise (see :mod:`parambench.methods.pointset.dem`).
    spacing : {"local", "global"}
        "local" (default): ocp's area terms follow the spacing around each point, and
        ball radii grow with it where the sampling is sparser than average (never below
        the paper's ``ball_eps_factor * l``: radii smaller than that made ocp fail on a
        400-point random cap), so sparse regions of adaptively sampled surfaces get full
        balls; "global": the paper's single ``eps = ball_eps_factor * l`` everywhere and
        one area per point.
    neighbours : {"auto", "euclidean", "surface", "pruned"}
        "auto" (default): the paper's plain K nearest, except where the points have a
        gap (some edge "pruned" drops joins points more than 4 hops apart along the
        pruned graph); there the pruning is redone with poorly fitted normals borrowed
        from the best-fitted neighbour and its dropped edges without a 4-hop detour are
        cut (:func:`parambench.methods.pointset.surface_neighbours.gap_aware_knn_graph`).
        On the 56 cases of the real-data benchmark a gap is found on camelhead,
        cortex-lh, bunny10k and "fold" with random and graded sampling (the four folds
        then 0 foldovers, QC within 1.2 % of scp-igl); every other case gets the
        Euclidean graph bit for bit. The gap-aware graph (~10x the kNN search) is only
        built where a screen with the normals fitted on the Euclidean graph finds a
        suspect edge without a detour
        (:func:`parambench.methods.pointset.surface_neighbours.gap_suspected`): on the 56
        cases and the 22 generated ones at 100k it flags exactly the cases with a gap;
        elsewhere it costs about half the kNN search (0.13 s at 100k points).
        "euclidean": the paper's plain K nearest. "surface": K neighbours kept
        along the surface, not across narrow gaps
        (:func:`parambench.methods.pointset.surface_neighbours.surface_knn_graph`). Experimental: it
        does not separate the touching sheets of the camelhead scan and with noise of 0.5
        spacings it loses the outer loop of "holes" at 2k points.
        "pruned": the K nearest without edges whose ends lie on opposite sides of each
        other's tangent planes or have opposed normals
        (:func:`parambench.methods.pointset.surface_neighbours.pruned_knn_graph`); normals, DEM
        balls and boundary then stay on one sheet. It fixes the "fold" surface (jittered
        2k/20k, graded 2k: 0 foldovers, QC within 2 % of scp-igl), but on its own it also
        drops edges at sharp tips where no gap is (protrusions, random 2k: 34 foldovers
        instead of 17) and keeps a few edges between the fold's free edges (random 2k
        and 20k, graded 20k: ConvergenceError), hence "auto".
    boundary_method : {"angle", "rings"}
        "angle" (default): the paper's angle criterion on the geodesic balls, candidates
        chained into loops (:mod:`parambench.methods.pointset.boundary`); "rings": loops of the
        boundary edges of the points' tangent-plane Delaunay one-rings with an alpha-shape
        test (:mod:`parambench.methods.pointset.boundary_rings`): finds slits of regular samplings
        narrower than the balls; otherwise measured on par with "angle".
    slot_cuts : bool
        With ``neighbours="auto"``, also cut the edges that cross a slot: an empty strip
        of the tangent plane at least 1.4 local spacings wide and 8 long
        (:mod:`parambench.methods.pointset.slot_cuts`), so the lips of a cut or a narrow
        hole become boundary.
    """

    # Field order is the order of the methods' ``defaults`` (and of build_frontend's old
    # keyword list); results record parameters in that order.
    k_nn: int = field(default=8, metadata=_METHOD)
    ball_k: int = field(default=6, metadata=_METHOD)
    ball_eps_factor: float = field(default=2.5, metadata=_METHOD)
    dem: str = field(default="auto", metadata=_METHOD)
    smooth_normals: bool = True
    reg_eps: float = field(default=DEFAULT_REG_EPS, metadata=_METHOD)
    boundary_angle_deg: float = field(default=120.0, metadata=_METHOD)
    boundary_decimate: int = field(default=1, metadata=_METHOD)
    weights: str = "tangent"
    max_ball: int = DEFAULT_MAX_BALL
    min_loop_size: int = DEFAULT_MIN_LOOP_SIZE
    dem_variant: str = "robust"
    spacing: str = field(default="local", metadata=_METHOD)
    neighbours: str = field(default="auto", metadata=_METHOD)
    boundary_method: str = field(default="angle", metadata=_METHOD)
    slot_cuts: bool = True


#: Names of the fields every point-set method accepts, in field order. The other fields
#: are not method parameters: adding them would change every point-set method's
#: ``defaults`` and so the parameters recorded with every stored result.
METHOD_FIELDS: tuple[str, ...] = tuple(f.name for f in fields(FrontEndParams) if f.metadata.get("method_param"))


def method_defaults() -> dict[str, Any]:
    """The method-parameter fields of :class:`FrontEndParams` with their defaults, in field order.

    Returns
    -------
    dict
        A new dict (callers may change it).
    """
    return {f.name: f.default for f in fields(FrontEndParams) if f.name in METHOD_FIELDS}


def frontend_params(params: Mapping[str, Any], **fixed: Any) -> FrontEndParams:
    """The :class:`FrontEndParams` of a point-set method's parameters.

    Parameters
    ----------
    params : mapping
        The method's parameters; the keys in :data:`METHOD_FIELDS` are used, the others
        ignored, missing ones take the default.
    **fixed
        Fields the method sets itself (e.g. ``weights``).

    Returns
    -------
    FrontEndParams
    """
    return FrontEndParams(**{k: params[k] for k in METHOD_FIELDS if k in params}, **fixed)
