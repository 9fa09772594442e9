"""``scp``: spectral conformal parameterization with our own solver and any weights."""

from __future__ import annotations

from parambench.datasets_gen.surface import Surface

from ..base import Method, MethodOutput, StageTimer
from ..mesh.conformal_setup import build_mesh_problem, scale_to_surface_area, solve_with_k_rule
from ..mesh.holes import HOLES_MODES, surface_for_solve
from ..mesh.hybrid import fold_driven_hybrid
from ..mesh.weights import WEIGHT_KINDS
from ..registry import register


@register
class Scp(Method):
    """SCP (Mullen et al. 2008), Sec. 2: the smallest eigenvector of ``L_C z = lambda B z``.

    Complex V x V form, translations deflated, one sparse factorisation reused by the
    shift-invert iterations. With ``weights="cotangent"`` and ``b_matrix="mass"`` it
    solves the same problem as ``scp-igl``. Other weights need k (Eq. 15): ``k_search``
    ``"line"`` (Eq. 16) or ``"direct"`` (generalised eigenvalue); ``"auto"`` uses k = 1
    for cotangent, uniform and hybrid weights (the line search where k = 1 is
    indefinite) and the line search otherwise. ``weights="hybrid"`` with
    ``uniform_at="auto"`` (the default) is uniform only around the folds of the cotangent
    map (:mod:`parambench.methods.mesh.hybrid`, Fig. 12); ``uniform_at="negative"`` or a vertex list
    fixes the uniform vertices instead.

    The output is scaled so that its boundary encloses the 3D surface area.
    """

    name = "scp"
    description = "spectral conformal parameterization, any weights, optional k search (Mullen et al. 2008; Sec. 5)"
    needs_faces = True
    defaults = {"weights": "cotangent", "normalized": False, "b_matrix": "boundary", "k_search": "auto",
                "uniform_at": None, "holes": "auto"}
    choices = {"holes": HOLES_MODES}
    param_grid = {"weights": list(WEIGHT_KINDS), "normalized": [False, True], "b_matrix": ["boundary", "mass"]}

    def solve(self, surface: Surface, params: dict, timer: StageTimer) -> MethodOutput:
        weights, normalized, b_matrix = params["weights"], bool(params["normalized"]), params["b_matrix"]

        def solve(problem):
            with timer("solve"):
                return solve_with_k_rule(problem, "scp", params["k_search"], weights=weights, normalized=normalized)

        n_points = surface.n_points
        surface, n_filled = surface_for_solve(surface, params["holes"], weights, normalized)
        if weights == "hybrid" and params["uniform_at"] in (None, "auto"):
            problem, sol, loops, info = fold_driven_hybrid(surface, timer, solve, normalized=normalized,
                                                           b_matrix=b_matrix)
        else:
            problem, loops, info = build_mesh_problem(surface, timer, weights=weights, normalized=normalized,
                                                      uniform_at=params["uniform_at"], b_matrix=b_matrix)
            sol = solve(problem)
        with timer("solve"):
            uv = scale_to_surface_area(sol.z, problem, surface.points, surface.faces)[:n_points]
        diagnostics = dict(sol.diagnostics, holes_filled=n_filled, **info)
        return MethodOutput(uv, diagnostics)
