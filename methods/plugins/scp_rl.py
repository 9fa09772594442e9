"""``scp-rl``: SCP on robust-laplacian's point-cloud Laplacian (Sharp & Crane 2020), a peer row.

Same points, same detected boundary as ``ocp``; only the Laplacian differs, so the row
isolates what W^tan contributes.
"""

from __future__ import annotations

import numpy as np

from parambench.datasets_gen.surface import MethodInput

from ..base import Method, MethodOutput, StageTimer
from ..hints import Hint
from ..pointset.plugin_support import (BOUNDARY_HINTS, FRONTEND_DEFAULTS, FRONTEND_PEAK, frontend_diagnostics,
                                       run_frontend, scale_to_spacing)
from ..registry import register
from ..spectral import ConformalProblem
from ..spectral.problem import solve_line_then_direct
from ._robust_laplacian import robust_point_cloud_laplacian


#: Offered last when both k searches fail: the same points with W^tan instead of this Laplacian.
_OCP_HINT = Hint("try --method ocp (the same boundary, the paper's Laplacian)")


@register
class ScpRobustLaplacian(Method):
    """SCP with robust-laplacian's point-cloud (tufted intrinsic Delaunay) Laplacian."""

    name = "scp-rl"
    description = "SCP on robust-laplacian's point-cloud Laplacian, boundary by angle criterion (peer; points only)"
    peak_memory = FRONTEND_PEAK  # at least the front end's; the solve's own not measured
    defaults = {**FRONTEND_DEFAULTS, "rl_neighbors": 30, "k_search": "line"}
    param_grid = {"k_search": ["none", "line"]}

    def solve(self, surface: MethodInput, params: dict, timer: StageTimer) -> MethodOutput:
        front = run_frontend(surface, params, timer)
        lap = robust_point_cloud_laplacian(surface.points, int(params["rl_neighbors"]), timer)
        with timer("solve"):
            problem = ConformalProblem(lap, front.boundary_loops, b_matrix="boundary", points=surface.points)
            if params["k_search"] == "line":
                # Line, then direct where it fails, as ocp: each alone failing named the other
                # (a 3000-point bumped square: "use k_search='direct'", then "use k_search='line'").
                sol = solve_line_then_direct(problem, "scp", hints=(*BOUNDARY_HINTS, _OCP_HINT))
            else:
                sol = problem.solve("scp", params["k_search"])
            uv = scale_to_spacing(sol.uv, front)
        diag = {**frontend_diagnostics(front), **sol.diagnostics,
                "k_opt": float(sol.k), "turning": np.asarray(sol.turning).tolist()}
        return MethodOutput(uv, diag)
