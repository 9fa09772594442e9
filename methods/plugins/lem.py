"""``lem``: Laplacian eigenmaps, ``L f = lambda D f`` (Belkin & Niyogi; the paper's Sec. 2, Fig. 6b)."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from parambench.datasets_gen.errors import SolverError
from parambench.datasets_gen.surface import MethodInput

from ..base import Method, MethodOutput, StageTimer
from ..pointset.plugin_support import (FRONTEND_DEFAULTS, FRONTEND_PEAK, frontend_diagnostics, run_frontend,
                                       scale_to_spacing)
from ..registry import register
from ..spectral.dirichlet import smallest_nontrivial_pair


@register
class Lem(Method):
    """LEM on the point set: W symmetrised, ``D = diag(row sums)``, ``(D - W) f = lambda D f``.

    ``weights="tangent"`` uses W^tan (Eq. 13), ``"lle3d"`` the 3D LLE weights (Eqs. 10-12).
    No boundary constraint: the Rayleigh quotient prefers its own point distribution, which
    is why LEM fails on strongly curved patches (Sec. 4.1) — shown here, not hidden.
    """

    name = "lem"
    description = "Laplacian eigenmaps on W^tan or 3D LLE weights (points only; Sec. 2, Fig. 6b)"
    peak_memory = FRONTEND_PEAK  # at least the front end's; the solve's own not measured
    defaults = {**FRONTEND_DEFAULTS, "weights": "tangent"}
    param_grid = {"weights": ["tangent", "lle3d"]}

    def solve(self, surface: MethodInput, params: dict, timer: StageTimer) -> MethodOutput:
        front = run_frontend(surface, params, timer, weights=params["weights"])
        with timer("solve"):
            w = 0.5 * (front.W + front.W.T)
            degree = np.asarray(w.sum(axis=1)).ravel()
            if np.any(degree <= 0):
                raise SolverError(f"{int((degree <= 0).sum())} point(s) have non-positive total weight after "
                                  "symmetrisation; LEM needs positive degrees. Use a larger reg_eps.")
            d = sp.diags(degree)
            vals, pair = smallest_nontrivial_pair((d - w).tocsc(), d.tocsc())
            uv = scale_to_spacing(pair, front)
        diag = dict(frontend_diagnostics(front), eigenvalues=vals.tolist())
        return MethodOutput(uv, diag)
