"""``lle``: locally linear embedding, minimising ``f^T L^T L f`` (Roweis & Saul; the paper's Sec. 2, Fig. 4)."""

from __future__ import annotations

import scipy.sparse as sp

from parambench.datasets_gen.surface import MethodInput

from ..base import Method, MethodOutput, StageTimer
from ..pointset.plugin_support import (FRONTEND_DEFAULTS, FRONTEND_PEAK, frontend_diagnostics, run_frontend,
                                       scale_to_spacing)
from ..registry import register
from ..spectral.dirichlet import smallest_nontrivial_pair


@register
class Lle(Method):
    """LLE: the two smallest non-constant eigenvectors of ``(I - W)^T (I - W)``.

    ``weights="tangent"`` uses W^tan (Eq. 13, Fig. 4b), ``"lle3d"`` the classic 3D weights
    (Fig. 4a). Positive semi-definite even though W is not symmetric.
    """

    name = "lle"
    description = "locally linear embedding on W^tan or 3D LLE weights (points only; Sec. 2, Fig. 4)"
    peak_memory = FRONTEND_PEAK  # at least the front end's; the solve's own not measured
    defaults = {**FRONTEND_DEFAULTS, "weights": "tangent"}
    param_grid = {"weights": ["tangent", "lle3d"]}

    def solve(self, surface: MethodInput, params: dict, timer: StageTimer) -> MethodOutput:
        front = run_frontend(surface, params, timer, weights=params["weights"])
        with timer("solve"):
            lap = front.L
            vals, pair = smallest_nontrivial_pair((lap.T @ lap).tocsc(), sp.identity(lap.shape[0], format="csc"))
            uv = scale_to_spacing(pair, front)
        diag = dict(frontend_diagnostics(front), eigenvalues=vals.tolist())
        return MethodOutput(uv, diag)
