"""``dncp-opt``: DNCP with two pinned vertices inside the k search (Sec. 5, optimized DNCP)."""

from __future__ import annotations

from parambench.datasets_gen.surface import Surface

from ..base import Method, MethodOutput, StageTimer
from ..mesh.conformal_setup import build_mesh_problem, resolve_pins, scale_to_surface_area, solve_with_k_rule
from ..mesh.holes import HOLES_MODES, surface_for_solve
from ..mesh.hybrid import fold_driven_hybrid
from ..mesh.weights import WEIGHT_KINDS
from ..registry import register


@register
class DncpOpt(Method):
    """Optimized DNCP, Sec. 5: pinned conformal energy ``z^H (k L/2 - M) z`` with k from Eq. 16.

    Two vertices are pinned to 0 and 1; at k_opt the map is, up to a similarity, the
    zero-energy map, so the result no longer depends on the pins (Fig. 10). ``pins`` is
    ``"farthest"`` (the two boundary vertices farthest apart) or ``"i,j"``. ``k_search``
    is ``"line"`` (Eq. 16), ``"direct"`` (generalised eigenvalue) or ``"none"`` (plain
    DNCP at k = 1). The output is scaled so that its boundary encloses the 3D area.
    ``weights="hybrid"`` with ``uniform_at="auto"`` (the default) is uniform only around
    the folds of the cotangent map (:mod:`parambench.methods.mesh.hybrid`, Fig. 12).
    """

    name = "dncp-opt"
    description = "optimized DNCP: two pins, k line search (Eq. 16), any weights (Sec. 5)"
    needs_faces = True
    defaults = {"weights": "cotangent", "normalized": False, "pins": "farthest", "k_search": "line",
                "uniform_at": None, "holes": "auto"}
    choices = {"holes": HOLES_MODES}
    param_grid = {"weights": list(WEIGHT_KINDS), "normalized": [False, True], "k_search": ["line", "direct"]}

    def solve(self, surface: Surface, params: dict, timer: StageTimer) -> MethodOutput:
        weights, normalized = params["weights"], bool(params["normalized"])
        pins = None

        def solve(problem):
            nonlocal pins
            pins = resolve_pins(params["pins"], surface.points, problem.loops) if pins is None else pins
            with timer("solve"):
                return solve_with_k_rule(problem, "dncp", params["k_search"], weights=weights, normalized=normalized,
                                         pins=pins)

        n_points = surface.n_points
        surface, n_filled = surface_for_solve(surface, params["holes"], weights, normalized)
        if weights == "hybrid" and params["uniform_at"] in (None, "auto"):
            problem, sol, loops, info = fold_driven_hybrid(surface, timer, solve, normalized=normalized,
                                                           b_matrix="boundary")
        else:
            problem, loops, info = build_mesh_problem(surface, timer, weights=weights, normalized=normalized,
                                                      uniform_at=params["uniform_at"], b_matrix="boundary")
            sol = solve(problem)
        with timer("solve"):
            uv = scale_to_surface_area(sol.z, problem, surface.points, surface.faces)[:n_points]
        diagnostics = dict(sol.diagnostics, holes_filled=n_filled, pins=[int(pins[0]), int(pins[1])], **info)
        return MethodOutput(uv, diagnostics)
