"""``scp``: spectral conformal parameterization with our own solver and any weights."""

from __future__ import annotations

from parambench.datasets_gen.surface import MethodInput

from ..base import Method, MethodOutput, StageTimer
from ..mesh.conformal_setup import build_mesh_problem, scale_to_surface_area, solve_with_k_rule
from ..mesh.fallbacks import first_regular, mesh_attempts
from ..mesh.holes import HOLES_MODES, solve_with_holes
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
    fixes the uniform vertices instead. ``holes``: ``"auto"`` (default) solves with the
    holes free and, where that fails or turns a hole inside out, again with each hole
    closed by a refined patch (:mod:`parambench.methods.mesh.holes`); ``"free"`` or ``"filled"``
    forces one.

    ``weights="authalic"`` (without ``uniform_at``): where the plain authalic weights give
    no regular map at any k, every vertex with a negative authalic weight gets the uniform
    authalic weights in its row (``uniform_at="negative"``) and the map is solved again;
    the result then says so in ``diagnostics["authalic_fallback"]`` (with
    ``n_uniform_rows``, ``uniform_share`` and ``fallback_reason``). Measured cause and
    alternatives: :mod:`parambench.methods.mesh.fallbacks`. ``uniform_at`` given with
    authalic weights sets those rows directly.

    The output is scaled so that its boundary encloses the 3D surface area.
    """

    name = "scp"
    description = "spectral conformal parameterization, any weights, optional k search (Mullen et al. 2008; Sec. 5)"
    needs_faces = True
    defaults = {"weights": "cotangent", "normalized": False, "b_matrix": "boundary", "k_search": "auto",
                "uniform_at": None, "holes": "auto"}
    choices = {"holes": HOLES_MODES}
    param_grid = {"weights": list(WEIGHT_KINDS), "normalized": [False, True], "b_matrix": ["boundary", "mass"]}

    def solve(self, surface: MethodInput, params: dict, timer: StageTimer) -> MethodOutput:
        weights, normalized, b_matrix = params["weights"], bool(params["normalized"]), params["b_matrix"]

        def solve(problem):
            with timer("solve"):
                return solve_with_k_rule(problem, "scp", params["k_search"], weights=weights, normalized=normalized)

        def attempt(surf, uniform_at):
            if weights == "hybrid" and uniform_at in (None, "auto"):
                return fold_driven_hybrid(surf, timer, solve, normalized=normalized, b_matrix=b_matrix)
            problem, loops, info = build_mesh_problem(surf, timer, weights=weights, normalized=normalized,
                                                      uniform_at=uniform_at, b_matrix=b_matrix)
            return problem, solve(problem), loops, info

        def with_holes(uniform_at, _pins):
            return solve_with_holes(surface, params["holes"], lambda surf: attempt(surf, uniform_at))

        attempts = mesh_attempts(with_holes, surface, weights=weights, uniform_at=params["uniform_at"])
        ((problem, sol, loops, info), work, n_filled), fallback = first_regular(attempts)
        with timer("solve"):
            uv = scale_to_surface_area(sol.z, problem, work.points, work.faces)[: surface.n_points]
        diagnostics = dict(sol.diagnostics, holes_filled=n_filled, **info, **fallback)
        return MethodOutput(uv, diagnostics)
