"""JSON diagnostics of the point-set front end on a surface (``parambench inspect``)."""

from __future__ import annotations

from typing import Any

from parambench.datasets_gen.surface import Surface

from ..memory_budget import check_memory
from .coincident import coincident_groups, warn_merged
from .frontend import build_frontend
from .params import FRONTEND_PEAK
from .handles import handle_cause
from .plugin_support import frontend_candidates
from .ring_orientation import unresolved_points
from .selfcheck import loop_coverage
from .stray_points import isolated_mask

__all__ = ["inspect_surface"]


def inspect_surface(surface: Surface, **frontend_params: Any) -> dict:
    """Run :func:`~parambench.methods.pointset.frontend.build_frontend` on a surface's points and report.

    Faces, if any, are ignored; the surface's normals are passed on when it has them.

    Parameters
    ----------
    surface : Surface
    **frontend_params
        Keyword parameters of ``build_frontend`` (``k_nn``, ``ball_k``, ...).

    Returns
    -------
    dict
        JSON-serialisable: ``name``, ``n_points`` (input points), ``n_coincident_merged``
        (copies of an earlier point, merged first as ``flatten`` does, with a
        CoincidentPointsWarning), ``mean_spacing``, ``boundary_loops`` (lists of input point
        indices in order, outer first), ``n_boundary_points``,
        ``negative_weight_fraction`` {"interior", "boundary"},
        ``reconstruction_error`` {"mean", "max", "unit"} (R_x / l^2), ``ball_size``,
        ``timings`` (seconds per stage), ``params``, the full ``diagnostics`` and
        ``selfcheck``: the parts of a map's self-check that need no map, ``{"coverage":
        loop_coverage(...) or None, "n_unresolved": int, "n_isolated": int}`` (points far
        from all others, :func:`~parambench.methods.pointset.stray_points.isolated_mask`:
        a scan's ``0 0 0`` rows, which also inflate ``mean_spacing``; ``"handle"``:
        :func:`~parambench.methods.pointset.handles.handle_cause`, ``{"genus", "share"}``
        where the points sample a surface with handles, which no map lays flat, else None)
        (:func:`parambench.methods.pointset.selfcheck.loop_coverage`: do the loops cover the
        angle-criterion candidates?; :func:`parambench.methods.pointset.ring_orientation.unresolved_points`:
        points where the sampling does not resolve the surface, and a map's fold would go unseen).

    Raises
    ------
    ParambenchError
        Whatever ``build_frontend`` raises (e.g. NoBoundaryError on a closed surface);
        ResourceLimitError where the front end would need more memory than is available.
    """
    # As flatten does: coincident copies are one sample, the front end runs on one
    # representative per group and indices are reported in the input's numbering.
    groups = coincident_groups(surface.points)
    reps = groups.representatives
    check_memory("inspect", reps.size, FRONTEND_PEAK)
    warn_merged(surface.name, groups, "the front end ran on the {} distinct points")
    normals = None if surface.normals is None else surface.normals[reps]
    fe = build_frontend(surface.points[reps], normals, **frontend_params)
    diag = fe.diagnostics
    candidates = frontend_candidates(fe)
    coverage = (None if candidates is None else
                loop_coverage(fe.points, fe.boundary_loops, candidates, fe.knn_indices, fe.mean_spacing))
    return {
        "name": surface.name,
        "n_points": int(surface.points.shape[0]),
        "n_coincident_merged": groups.n_merged,
        "mean_spacing": fe.mean_spacing,
        "boundary_loops": [reps[loop].tolist() for loop in fe.boundary_loops],
        "n_boundary_points": int(fe.boundary_mask.sum()),
        "negative_weight_fraction": dict(diag["negative_weights"]["negative_fraction"]),
        "reconstruction_error": dict(diag["reconstruction_error"]),
        "ball_size": dict(diag["ball_size"]),
        "timings": {k: float(v) for k, v in fe.timings.items()},
        "params": dict(fe.params),
        "diagnostics": diag,
        "selfcheck": {"coverage": coverage,
                      "n_unresolved": int(unresolved_points(fe.normals, fe.knn_indices).sum()),
                      "n_isolated": int(isolated_mask(fe.points, fe.knn_indices).sum()),
                      "handle": handle_cause(fe.points, fe.normals)},
    }
