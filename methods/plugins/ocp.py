"""``ocp`` and ``scp-tan``: the conformal energy on W^tan, with and without the k search (Sec. 4.2)."""

from __future__ import annotations

import numpy as np

from datasets_gen.surface import Surface

from ..base import Method, Parameterization, StageTimer
from ..pointset.plugin_support import FRONTEND_DEFAULTS, frontend_diagnostics, run_frontend, scale_to_spacing
from ..registry import register
from ..spectral import ConformalProblem


def _conformal_problem(front) -> ConformalProblem:
    return ConformalProblem(front.L, front.boundary_loops, b_matrix="boundary", points=front.points)


@register
class Ocp(Method):
    """Optimized conformal parameterization: SCP on ``k L - A`` with k from Eq. 16.

    ``k_search="line"``: search forward from k = 1 until the boundary turning number is
    1, then minimise within that step (the paper's procedure; the landscape is kept).
    ``"direct"``: k_opt as the largest generalised eigenvalue with a regular map.
    """

    name = "ocp"
    description = "optimized conformal parameterization on W^tan, k line search (points only; Sec. 4.2)"
    defaults = {**FRONTEND_DEFAULTS, "k_search": "line"}
    param_grid = {"k_search": ["line", "direct"]}

    def run(self, surface: Surface, **params) -> Parameterization:
        timer = StageTimer()
        front = run_frontend(surface, params, timer)
        with timer("solve"):
            problem = _conformal_problem(front)
            sol = problem.solve("scp", params["k_search"])
            uv = scale_to_spacing(sol.uv, front)
        diag = {**frontend_diagnostics(front), **sol.diagnostics, **problem.counts,
                "k_opt": float(sol.k), "turning": np.asarray(sol.turning).tolist()}
        return Parameterization(uv=uv, method=self.name, timings=timer.timings, diagnostics=diag)


@register
class ScpTan(Method):
    """Raw SCP with W^tan at a fixed k (default 1): kept to show the "spinning" of Sec. 4.2.

    W^tan is row-normalised, so k = 1 is far below k_opt: the boundary image winds more
    than once (turning number > 1). The map is returned as computed, with its turning
    numbers in the diagnostics, so the benchmark shows the failure honestly.
    """

    name = "scp-tan"
    description = "raw SCP on W^tan at fixed k (shows the spinning failure of Sec. 4.2; points only)"
    defaults = {**FRONTEND_DEFAULTS, "k": 1.0}

    def run(self, surface: Surface, **params) -> Parameterization:
        timer = StageTimer()
        front = run_frontend(surface, params, timer)
        with timer("solve"):
            problem = _conformal_problem(front)
            sol = problem.scp(float(params["k"]), backend="auto", allow_negative=True)
            uv = scale_to_spacing(sol.uv, front)
        diag = {**frontend_diagnostics(front), **sol.diagnostics, **problem.counts, "k": float(sol.k),
                "turning": np.asarray(sol.turning).tolist(), "energy": float(sol.energy)}
        return Parameterization(uv=uv, method=self.name, timings=timer.timings, diagnostics=diag)
