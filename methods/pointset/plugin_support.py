"""Glue shared by the point-set method plugins: front-end parameters, stage timings, output scale."""

from __future__ import annotations

from typing import Any

import numpy as np

from datasets_gen.errors import SolverError, TooFewPointsError
from datasets_gen.surface import Surface

from ..base import StageTimer
from .frontend import STAGES, FrontEnd, build_frontend

__all__ = ["FRONTEND_DEFAULTS", "run_frontend", "require_neighbours", "scale_to_spacing", "frontend_diagnostics"]

#: Front-end parameters every point-set method accepts (paper Sec. 6 defaults).
FRONTEND_DEFAULTS: dict[str, Any] = {
    "k_nn": 8,
    "ball_k": 6,
    "ball_eps_factor": 2.5,
    "dem": "upwind",
    "reg_eps": 1e-2,
    "boundary_angle_deg": 120.0,
    "boundary_decimate": 1,
}


def run_frontend(surface: Surface, params: dict, timer: StageTimer, *, weights: str = "tangent") -> FrontEnd:
    """Run the front end with the front-end keys of ``params``; its stage timings go to ``timer``.

    Raises
    ------
    TooFewPointsError
        ``k_nn`` is not below the number of points (each point needs ``k_nn`` others).
    ParambenchError
        Whatever :func:`~methods.pointset.frontend.build_frontend` raises.
    """
    kwargs = {k: params[k] for k in FRONTEND_DEFAULTS if k in params}
    require_neighbours(surface.n_points, kwargs.get("k_nn", FRONTEND_DEFAULTS["k_nn"]), "k_nn")
    front = build_frontend(surface.points, surface.normals, weights=weights, **kwargs)
    for stage in STAGES:
        timer.timings[stage] = timer.timings.get(stage, 0.0) + front.timings.get(stage, 0.0)
    return front


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
    edge = np.linalg.norm(centred[nbr] - centred[:, None, :], axis=-1).mean()
    if not edge > 0 or not np.isfinite(edge):
        raise SolverError("the map collapses every neighbourhood to a point; the solve failed.")
    return centred * (front.mean_spacing / edge)


def frontend_diagnostics(front: FrontEnd) -> dict:
    """The facts of the front end worth keeping with a result (JSON-serialisable)."""
    diag = front.diagnostics
    return {
        "mean_spacing": front.mean_spacing,
        "n_boundary_points": int(front.boundary_mask.sum()),
        "n_detected_loops": len(front.boundary_loops),
        "negative_weight_fraction": diag["negative_weights"]["negative_fraction"],
        "reconstruction_error": diag["reconstruction_error"],
        "boundary_loops": [loop.tolist() for loop in front.boundary_loops],
    }
