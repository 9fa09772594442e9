"""``scp-tan``: raw SCP on ``L = I - W^tan`` at a fixed k: ``ocp``'s "paper" energy without the k search (Sec. 4.2)."""

from __future__ import annotations

import numpy as np

from parambench.datasets_gen.surface import MethodInput

from ..base import Method, MethodOutput, StageTimer
from ..pointset.plugin_support import (FRONTEND_DEFAULTS, FRONTEND_PEAK, frontend_diagnostics, run_frontend,
                                       scale_to_spacing)
from ..registry import register
from .ocp import conformal_problem


@register
class ScpTan(Method):
    """Raw SCP with W^tan at a fixed k (default 1): kept to show the "spinning" of Sec. 4.2.

    W^tan is row-normalised, so k = 1 is far below k_opt: the boundary image winds more
    than once (turning number > 1). The map is returned as computed, with its turning
    numbers in the diagnostics, so the benchmark shows the failure honestly.
    """

    name = "scp-tan"
    description = "raw SCP on W^tan at fixed k (shows the spinning failure of Sec. 4.2; points only)"
    peak_memory = FRONTEND_PEAK  # at least the front end's; the solve's own not measured
    defaults = {**FRONTEND_DEFAULTS, "k": 1.0}

    def solve(self, surface: MethodInput, params: dict, timer: StageTimer) -> MethodOutput:
        front = run_frontend(surface, params, timer)
        with timer("solve"):
            problem = conformal_problem(front)
            sol = problem.scp(float(params["k"]), backend="auto", allow_negative=True)
            uv = scale_to_spacing(sol.uv, front)
        diag = {**frontend_diagnostics(front), **sol.diagnostics, **problem.counts, "k": float(sol.k),
                "turning": np.asarray(sol.turning).tolist(), "energy": float(sol.energy)}
        return MethodOutput(uv, diag)
