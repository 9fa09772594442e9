"""``scp``: spectral conformal parameterization with our own solver and any weights."""

from __future__ import annotations

from datasets_gen.surface import Surface

from ..base import Method, Parameterization, StageTimer
from ..mesh.conformal_setup import build_mesh_problem, default_k_search, scale_to_surface_area
from ..mesh.weights import WEIGHT_KINDS
from ..registry import register


@register
class Scp(Method):
    """SCP (Mullen et al. 2008), Sec. 2: the smallest eigenvector of ``L_C z = lambda B z``.

    Complex V x V form, translations deflated, one sparse factorisation reused by the
    shift-invert iterations. With ``weights="cotangent"`` and ``b_matrix="mass"`` it
    solves the same problem as ``scp-igl``. Other weights need k (Eq. 15): ``k_search``
    ``"line"`` (Eq. 16) or ``"direct"`` (generalised eigenvalue); ``"auto"`` uses k = 1
    for cotangent and uniform weights and the line search otherwise.

    The output is scaled so that its boundary encloses the 3D surface area.
    """

    name = "scp"
    description = "spectral conformal parameterization, any weights, optional k search (Mullen et al. 2008; Sec. 5)"
    needs_faces = True
    defaults = {"weights": "cotangent", "normalized": False, "b_matrix": "boundary", "k_search": "auto",
                "uniform_at": None}
    param_grid = {"weights": list(WEIGHT_KINDS), "normalized": [False, True], "b_matrix": ["boundary", "mass"]}

    def run(self, surface: Surface, **params) -> Parameterization:
        timer = StageTimer()
        problem, loops, info = build_mesh_problem(surface, timer, weights=params["weights"],
                                                  normalized=params["normalized"], uniform_at=params["uniform_at"],
                                                  b_matrix=params["b_matrix"])
        k_search = params["k_search"]
        if k_search == "auto":
            k_search = default_k_search(params["weights"], params["normalized"])
        with timer("solve"):
            sol = problem.solve("scp", k_search)
            uv = scale_to_surface_area(sol.z, problem, surface.points, surface.faces)
        diagnostics = dict(sol.diagnostics, **info)
        return Parameterization(uv=uv, method=self.name, timings=timer.timings, diagnostics=diagnostics)
