"""``sdp-rl``: SDP on robust-laplacian's point-cloud Laplacian (Sharp & Crane 2020), a peer row.

Same points, same detected boundary as ``sdp``; only the Laplacian differs, so the row
isolates what W^tan contributes.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from parambench.datasets_gen.surface import MethodInput

from ..base import Method, MethodOutput, StageTimer
from ..pointset.plugin_support import (FRONTEND_DEFAULTS, FRONTEND_PEAK, frontend_diagnostics, run_frontend,
                                       scale_to_spacing)
from ..registry import register
from ..spectral.dirichlet import smallest_nontrivial_pair
from ._robust_laplacian import robust_point_cloud_laplacian


@register
class SdpRobustLaplacian(Method):
    """SDP (``L f = lambda B f``) with robust-laplacian's point-cloud Laplacian."""

    name = "sdp-rl"
    description = "SDP on robust-laplacian's point-cloud Laplacian (peer; points only)"
    peak_memory = FRONTEND_PEAK  # at least the front end's; the solve's own not measured
    defaults = {**FRONTEND_DEFAULTS, "rl_neighbors": 30}

    def solve(self, surface: MethodInput, params: dict, timer: StageTimer) -> MethodOutput:
        front = run_frontend(surface, params, timer)
        lap = robust_point_cloud_laplacian(surface.points, int(params["rl_neighbors"]), timer)
        with timer("solve"):
            b = sp.diags(front.boundary_mask.astype(np.float64))
            vals, pair = smallest_nontrivial_pair(lap.tocsc(), b.tocsc())
            uv = scale_to_spacing(pair, front)
        diag = dict(frontend_diagnostics(front), eigenvalues=vals.tolist())
        return MethodOutput(uv, diag)
