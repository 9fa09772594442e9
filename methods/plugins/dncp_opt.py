"""``dncp-opt``: DNCP with two pinned vertices inside the k search (Sec. 5, optimized DNCP)."""

from __future__ import annotations

from parambench.datasets_gen.surface import MethodInput

from ..base import Method, MethodOutput, StageTimer
from ..mesh.conformal_setup import build_mesh_problem, resolve_pins, scale_to_surface_area, solve_with_k_rule
from ..mesh.fallbacks import first_regular, mesh_attempts
from ..mesh.holes import HOLES_MODES, solve_with_holes
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
    ``holes``: ``"auto"`` (default) solves with the holes free and, where that fails or
    turns a hole inside out, again with each hole closed by a refined patch
    (:mod:`parambench.methods.mesh.holes`); ``"free"`` or ``"filled"`` forces one.
    Where the line search finds no bracket, k_opt is computed directly
    (``diagnostics["k_search_fallback"] = "direct"``).

    Where no regular map exists at any k, two fallbacks follow, in this order
    (:mod:`parambench.methods.mesh.fallbacks`, which has the measurements): with
    ``weights="authalic"`` (no ``uniform_at``), uniform authalic rows at every vertex with
    a negative authalic weight (``diagnostics["authalic_fallback"]``, as in ``scp``); with
    ``pins="farthest"``, up to six other pairs half the outer boundary apart
    (:func:`parambench.methods.mesh.pins.opposite_pairs`), first with the weights as asked,
    then (authalic) with the uniform rows. The map returned records
    ``diagnostics["pins_fallback"]`` (the pair's rank), ``pins_farthest`` (the pair that
    failed), ``pins`` (the pair used) and ``fallback_reason``. Pins given as ``"i,j"`` are
    never changed.
    """

    name = "dncp-opt"
    description = "optimized DNCP: two pins, k line search (Eq. 16), any weights (Sec. 5)"
    needs_faces = True
    defaults = {"weights": "cotangent", "normalized": False, "pins": "farthest", "k_search": "line",
                "uniform_at": None, "holes": "auto"}
    choices = {"holes": HOLES_MODES}
    param_grid = {"weights": list(WEIGHT_KINDS), "normalized": [False, True], "k_search": ["line", "direct"]}

    def solve(self, surface: MethodInput, params: dict, timer: StageTimer) -> MethodOutput:
        weights, normalized = params["weights"], bool(params["normalized"])

        def attempt(surf, uniform_at, pair):
            # pins are chosen once per surface (the hybrid rounds share them); with the holes
            # filled, "farthest" picks them on the outer loop
            pins = pair

            def solve(problem):
                nonlocal pins
                pins = resolve_pins(params["pins"], surf.points, problem.loops) if pins is None else pins
                with timer("solve"):
                    return solve_with_k_rule(problem, "dncp", params["k_search"], weights=weights,
                                             normalized=normalized, pins=pins)

            if weights == "hybrid" and uniform_at in (None, "auto"):
                problem, sol, loops, info = fold_driven_hybrid(surf, timer, solve, normalized=normalized,
                                                               b_matrix="boundary")
            else:
                problem, loops, info = build_mesh_problem(surf, timer, weights=weights, normalized=normalized,
                                                          uniform_at=uniform_at, b_matrix="boundary")
                sol = solve(problem)
            return problem, sol, loops, dict(info, pins=[int(pins[0]), int(pins[1])])

        def with_holes(uniform_at, pair):
            return solve_with_holes(surface, params["holes"], lambda surf: attempt(surf, uniform_at, pair))

        attempts = mesh_attempts(with_holes, surface, weights=weights, uniform_at=params["uniform_at"],
                                 pins=params["pins"])
        ((problem, sol, loops, info), work, n_filled), fallback = first_regular(attempts)
        with timer("solve"):
            uv = scale_to_surface_area(sol.z, problem, work.points, work.faces)[: surface.n_points]
        diagnostics = dict(sol.diagnostics, holes_filled=n_filled, **info, **fallback)
        return MethodOutput(uv, diagnostics)
