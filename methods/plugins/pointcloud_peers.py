"""Peer rows on robust-laplacian's point-cloud Laplacian (Sharp & Crane 2020): SCP and SDP.

Same points, same detected boundary as ``ocp`` and ``sdp``; only the Laplacian differs,
so the rows isolate what W^tan contributes.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from parambench.datasets_gen.surface import Surface

from ..base import Method, Parameterization, StageTimer
from ..pointset.plugin_support import FRONTEND_DEFAULTS, frontend_diagnostics, run_frontend, scale_to_spacing
from ..registry import register
from ..spectral import ConformalProblem
from ..spectral.dirichlet import smallest_nontrivial_pair


def _robust_laplacian(points: np.ndarray, n_neighbors: int, timer: StageTimer) -> sp.csr_matrix:
    import robust_laplacian

    with timer("laplacian"):
        lap, _mass = robust_laplacian.point_cloud_laplacian(points, n_neighbors=n_neighbors)
    return sp.csr_matrix(lap)


@register
class ScpRobustLaplacian(Method):
    """SCP with robust-laplacian's point-cloud (tufted intrinsic Delaunay) Laplacian."""

    name = "scp-rl"
    description = "SCP on robust-laplacian's point-cloud Laplacian, boundary by angle criterion (peer; points only)"
    defaults = {**FRONTEND_DEFAULTS, "rl_neighbors": 30, "k_search": "line"}
    param_grid = {"k_search": ["none", "line"]}

    def run(self, surface: Surface, **params) -> Parameterization:
        timer = StageTimer()
        front = run_frontend(surface, params, timer)
        lap = _robust_laplacian(surface.points, int(params["rl_neighbors"]), timer)
        with timer("solve"):
            problem = ConformalProblem(lap, front.boundary_loops, b_matrix="boundary", points=surface.points)
            sol = problem.solve("scp", params["k_search"])
            uv = scale_to_spacing(sol.uv, front)
        diag = {**frontend_diagnostics(front), **sol.diagnostics,
                "k_opt": float(sol.k), "turning": np.asarray(sol.turning).tolist()}
        return Parameterization(uv=uv, method=self.name, timings=timer.timings, diagnostics=diag)


@register
class SdpRobustLaplacian(Method):
    """SDP (``L f = lambda B f``) with robust-laplacian's point-cloud Laplacian."""

    name = "sdp-rl"
    description = "SDP on robust-laplacian's point-cloud Laplacian (peer; points only)"
    defaults = {**FRONTEND_DEFAULTS, "rl_neighbors": 30}

    def run(self, surface: Surface, **params) -> Parameterization:
        timer = StageTimer()
        front = run_frontend(surface, params, timer)
        lap = _robust_laplacian(surface.points, int(params["rl_neighbors"]), timer)
        with timer("solve"):
            b = sp.diags(front.boundary_mask.astype(np.float64))
            vals, pair = smallest_nontrivial_pair(lap.tocsc(), b.tocsc())
            uv = scale_to_spacing(pair, front)
        diag = dict(frontend_diagnostics(front), eigenvalues=vals.tolist())
        return Parameterization(uv=uv, method=self.name, timings=timer.timings, diagnostics=diag)
