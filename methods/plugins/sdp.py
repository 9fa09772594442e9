"""``sdp``: spectral Dirichlet parameterization, ``L f = lambda B f`` (Sec. 4.1)."""

from __future__ import annotations

import numpy as np

from parambench.datasets_gen.errors import ConvergenceError, SolverError, released
from parambench.datasets_gen.surface import MethodInput

from ..base import Method, MethodOutput, StageTimer
from ..hints import Hint, error_note, hinted
from ..pointset.plugin_support import (FRONTEND_DEFAULTS, FRONTEND_PEAK, frontend_diagnostics, run_frontend,
                                       scale_to_spacing)
from ..pointset.two_level import two_level_sdp_pair
from ..registry import register
from ..spectral.dirichlet import b_orthonormalize, direct_sdp_pair
from ..spectral.multilevel import FINE_SOLVERS
from .ocp import OCP_SOLVERS, resolve_solver


@register
class Sdp(Method):
    """SDP: LEM with B the indicator of the detected boundary points (Fig. 6c).

    ``b_orthonormal=True`` (default) makes the two eigenvectors B-orthonormal (equal
    boundary spread, no correlation), which removes the shear seen on caps and holes.
    ``False`` is the paper's literal SDP. W^tan is not symmetric and the two smallest
    eigenvalues are nearly equal on roughly symmetric patches, so the literal eigenvectors
    can be nearly parallel: measured on the jittered bump, QC mean 1.35 at 5k points but
    3.67 at 10k (B-orthonormal: 1.15 and 1.21).

    ``solver``: ``"direct"`` factorises ``L - sigma B`` on every point (shift-invert);
    ``"multilevel"`` solves the same problem as the eigenproblem of its boundary Schur
    complement in a boundary subspace started from a Poisson-disk subsample's pair, with
    two-grid interior solves (``fine_solver="twogrid"``) or one interior factorisation
    (``"direct"``): :mod:`parambench.methods.spectral.multilevel_dirichlet`. ``"auto"``
    (default) is ``"multilevel"`` from ocp's ``MULTILEVEL_FROM`` points on and falls back
    to ``"direct"`` if the two-level refinement does not converge (``multilevel_error``).
    """

    name = "sdp"
    description = "spectral Dirichlet parameterization, L f = lambda B f on W^tan (points only; Sec. 4.1)"
    peak_memory = FRONTEND_PEAK  # at least the front end's; the solve's own not measured
    defaults = {**FRONTEND_DEFAULTS, "b_orthonormal": True, "solver": "auto", "fine_solver": "twogrid"}
    param_grid = {"b_orthonormal": [False, True]}
    choices = {"solver": OCP_SOLVERS, "fine_solver": FINE_SOLVERS}

    def solve(self, surface: MethodInput, params: dict, timer: StageTimer) -> MethodOutput:
        solver = resolve_solver(params["solver"], surface.n_points, "line")
        front = run_frontend(surface, params, timer)
        lap = front.L
        front = front.without_balls()  # ~1.3 GB at 1M points, not needed by the solve
        b_diag = front.boundary_mask.astype(np.float64)
        extra: dict = {}
        pair = None
        if solver == "multilevel":
            try:
                pair, extra = two_level_sdp_pair(front, lap, params["fine_solver"], timer)
            except (ConvergenceError, SolverError) as exc:
                if params["solver"] != "auto":
                    stem, hints = getattr(exc, "parambench_hints", None) or (str(exc).rstrip("."), ())
                    raise hinted(type(exc), stem, *hints, Hint("use solver='direct'", "solver", "direct")) from exc
                extra = {"multilevel_error": error_note(released(exc), self.defaults, params)}
                solver = "direct"
        with timer("solve"):
            if pair is None:
                vals, pair = direct_sdp_pair(lap, front.boundary_mask, front.points,
                                             b_orthonormal=bool(params["b_orthonormal"]))
                extra["eigenvalues"] = vals.tolist()
            elif params["b_orthonormal"]:
                pair = b_orthonormalize(pair, b_diag)
            uv = scale_to_spacing(pair, front)
        diag = dict(frontend_diagnostics(front), solver=solver, solver_option=params["solver"], **extra)
        return MethodOutput(uv, diag)
