"""The order of ``ocp``'s fallbacks after a failed Neumann k search on a point set.

The cheap ones come first (the paper energy's search, then cotangent SCP on the mesh a
first map needing no k triangulates: the unrolled boundary's map, an sdp map); the exact searches on the dense boundary reduction, which cost
most of ``ocp``'s time on points scattered over real meshes and rarely found a map
there, come last and still run when everything else failed.
"""

from __future__ import annotations

import numpy as np
import pytest

import parambench.methods.plugins.ocp as ocp_module
from parambench.bench.metrics import evaluate
from parambench.datasets_gen.errors import ConvergenceError
from parambench.datasets_gen.registry import make_surface
from parambench.methods.registry import get_method
from parambench.methods.spectral import problem as problem_module


@pytest.fixture(scope="module")
def plane():
    return make_surface("plane", 600, seed=0)


def _line_search_fails(monkeypatch, calls: list):
    """Every line search fails; the direct search is recorded and runs as it would."""
    real_solve = problem_module.ConformalProblem.solve

    def solve(self, mode, k_search="none", **kwargs):
        calls.append((k_search, self.exact_fallbacks))
        if k_search == "line":
            raise ConvergenceError("no t = 1 crossing found (stand-in)")
        return real_solve(self, mode, k_search, **kwargs)

    monkeypatch.setattr(problem_module.ConformalProblem, "solve", solve)


def test_the_exact_searches_run_last_after_the_cheap_fallbacks_failed(plane, monkeypatch):
    calls, order = [], []
    _line_search_fails(monkeypatch, calls)

    def paper(front, w_tan, solver, params, timer, exc, **options):
        order.append("paper")
        raise exc

    def mesh(front, w_tan, timer, exc, params, solver):
        order.append("mesh")
        raise exc

    monkeypatch.setattr(ocp_module, "_paper_energy_fallback", paper)
    monkeypatch.setattr(ocp_module, "_mesh_fallback", mesh)
    result = get_method("ocp")(plane.method_input(False))
    assert order == ["paper", "mesh"]
    # Neumann's search without its exact searches, then again with them, last: its
    # direct k gives the plane's map.
    assert calls == [("line", False), ("line", True), ("direct", True)]
    assert result.diagnostics["k_search_fallback"] == "direct"
    assert result.diagnostics["selfcheck"]["passed"]
    quality = evaluate(plane.points, plane.faces, result.uv)
    assert quality["foldovers"] == 0 and quality["qc_mean"] < 1.01


def test_a_paper_energy_map_spares_the_exact_searches(plane, monkeypatch):
    calls = []
    real_solve = problem_module.ConformalProblem.solve

    def neumann_line_fails(self, mode, k_search="none", **kwargs):
        calls.append((k_search, self.exact_fallbacks))
        if k_search == "line" and not self.exact_fallbacks:  # only the Neumann attempt runs without them
            raise ConvergenceError("no t = 1 crossing found (stand-in)")
        return real_solve(self, mode, k_search, **kwargs)

    monkeypatch.setattr(problem_module.ConformalProblem, "solve", neumann_line_fails)
    result = get_method("ocp")(plane.method_input(False))
    # Neumann's line search alone, then the paper energy's, which maps; no direct k.
    assert calls[:2] == [("line", False), ("line", True)] and ("direct", True) not in calls
    diag = result.diagnostics
    assert diag["energy_used"] == "paper" and "the exact searches were left for" in diag["energy_error"]
    assert diag["selfcheck"]["passed"]
    quality = evaluate(plane.points, plane.faces, result.uv)
    assert quality["foldovers"] == 0 and quality["qc_mean"] < 1.01
    assert np.isfinite(result.uv).all()


def test_a_retry_that_changes_only_refine_reuses_the_solved_map(monkeypatch):
    """The self-check's retry ``refine="mesh"`` refines the map the first attempt solved
    (kept for the checked run, :func:`parambench.methods.base.retry_memo`) instead of
    solving it again, and gives the map a fresh run with ``refine="mesh"`` gives."""
    import parambench.methods.pointset.plugin_support as support
    from parambench.methods.plugins.ocp import Ocp

    surface = make_surface("bump", 800, sampling="random", seed=1)
    real_check, solved = support.selfcheck_result, []

    def fails_unless_refined(surf, result, **kwargs):
        facts = real_check(surf, result, **kwargs)
        if result.params["refine"] != "mesh":  # stand-in: the unrefined maps "fold"
            facts.update(passed=False, failed=["flipped"], reason="1 flipped triangle(s) (stand-in)")
        return facts

    real_unrefined = Ocp._unrefined

    def counting(self, *args):
        solved.append(args[1]["k_nn"])
        return real_unrefined(self, *args)

    monkeypatch.setattr(support, "selfcheck_result", fails_unless_refined)
    monkeypatch.setattr(Ocp, "_unrefined", counting)
    retried = get_method("ocp")(surface.method_input(False))
    # first (k_nn 8), k_nn=12 (fails too), then refine="mesh" on the first map: no third solve
    assert solved == [8, 12]
    assert retried.diagnostics["selfcheck"]["retry"]["params"] == {"refine": "mesh"}
    assert retried.diagnostics["refined"]["first_map"].startswith("ocp")
    monkeypatch.setattr(support, "selfcheck_result", real_check)
    fresh = get_method("ocp")(surface.method_input(False), refine="mesh")
    assert solved == [8, 12, 8]  # a new checked run keeps nothing from the last one
    assert np.allclose(retried.uv, fresh.uv, rtol=0, atol=1e-9 * np.ptp(fresh.uv))


def _folded(z: np.ndarray) -> np.ndarray:
    """``z`` with the part beyond 60 % of its u range folded back over the rest."""
    cut = z.real.min() + 0.6 * np.ptp(z.real)
    return np.where(z.real > cut, 2 * cut - z.real, z.real) + 1j * z.imag


def test_a_paper_energy_map_whose_boundary_folds_goes_on_to_the_mesh_fallback(plane, monkeypatch):
    """A paper-energy map that gives no mesh of the surface (its triangulation holds a
    fraction of the points) is not refined into a map of a few triangles: the mesh the
    map of the unrolled boundary triangulates is used instead."""
    from dataclasses import replace

    _line_search_fails(monkeypatch, [])
    real_front, attempts = ocp_module._solve_front, []

    def paper_map_folds(front, box, solver, params, timer, exact_fallbacks=True):
        attempts.append(exact_fallbacks)
        sol, counts, extra = real_front(front, box, solver, params, timer, exact_fallbacks)
        return replace(sol, z=_folded(sol.z)), counts, extra

    monkeypatch.setattr(ocp_module, "_solve_front", paper_map_folds)
    result = get_method("ocp")(plane.method_input(False))
    diag = result.diagnostics
    # Neumann's search failed (stand-in); the paper energy's, by the direct k, mapped and folded.
    assert attempts == [False, True]
    assert diag["energy_used"] == "mesh" and diag["refined"]["first_map"] == "unrolled boundary"
    assert diag["refined"]["n_unplaced"] <= 0.01 * plane.n_points
    quality = evaluate(plane.points, plane.faces, result.uv)
    assert quality["foldovers"] == 0 and quality["qc_mean"] < 1.01 and diag["selfcheck"]["passed"]


def _neumann_search_fails(monkeypatch, attempts: list):
    """The first k search (the Neumann energy's) fails; the later ones run as they would."""
    real_front = ocp_module._solve_front

    def first_fails(front, box, solver, params, timer, exact_fallbacks=True):
        attempts.append(exact_fallbacks)
        if len(attempts) == 1:
            raise ConvergenceError("no t = 1 crossing found (stand-in)")
        return real_front(front, box, solver, params, timer, exact_fallbacks)

    monkeypatch.setattr(ocp_module, "_solve_front", first_fails)


def _counting_front_ends(monkeypatch) -> list:
    runs, real_run = [], ocp_module.run_frontend

    def counting(*args, **kwargs):
        runs.append(1)
        return real_run(*args, **kwargs)

    monkeypatch.setattr(ocp_module, "run_frontend", counting)
    return runs


def test_large_point_sets_rebuild_w_tan_for_the_paper_energy_fallback(plane, monkeypatch):
    """From MULTILEVEL_FROM points on W^tan is not held through the Neumann solve; a
    failed search runs the front end again for it, and the fallback maps as it does
    where W^tan was held (same matrix, same map)."""
    attempts = []
    _neumann_search_fails(monkeypatch, attempts)
    runs = _counting_front_ends(monkeypatch)
    held = get_method("ocp")(plane.method_input(False), solver="direct")
    assert len(runs) == 1 and attempts == [False, True]  # exact searches left for last
    monkeypatch.setattr(ocp_module, "MULTILEVEL_FROM", plane.n_points)  # the plane counts as large
    runs.clear(), attempts.clear()
    rebuilt = get_method("ocp")(plane.method_input(False), solver="direct")
    # Cheap fallback first as before; the front end ran a second time, for W^tan; the
    # paper energy's search keeps to its path (no exact searches, no direct solve).
    assert len(runs) == 2 and attempts == [False, False]
    for result in (held, rebuilt):
        assert result.diagnostics["energy_used"] == "paper" and result.diagnostics["selfcheck"]["passed"]
    assert np.array_equal(held.uv, rebuilt.uv)
    quality = evaluate(plane.points, plane.faces, rebuilt.uv)
    assert quality["foldovers"] == 0 and quality["qc_mean"] < 1.01


def test_large_point_sets_run_the_front_end_once_when_the_neumann_search_maps(plane, monkeypatch):
    runs = _counting_front_ends(monkeypatch)
    monkeypatch.setattr(ocp_module, "MULTILEVEL_FROM", plane.n_points)
    result = get_method("ocp")(plane.method_input(False), solver="direct")
    assert len(runs) == 1 and result.diagnostics["energy_used"] == "neumann"


def test_tangent_weights_are_built_once_and_only_when_asked():
    built = []
    lazy = ocp_module.TangentWeights(rebuild=lambda: built.append(1) or "W")
    assert built == []
    assert lazy.matrix() == "W" and lazy.matrix() == "W" and built == [1]
    with pytest.raises(ValueError):
        ocp_module.TangentWeights()


def test_a_failed_two_level_neumann_search_goes_to_the_paper_energy_before_any_direct_solve(plane, monkeypatch):
    """With the paper-energy fallback at hand, the two-level path's safety net (the
    direct solve of the same energy, 274 s to fail on a 511k-point helmet) is not run."""
    order = []
    real_multilevel, real_problem = ocp_module._multilevel_solve, ocp_module.conformal_problem

    def multilevel(*args, **kwargs):
        order.append("multilevel")
        if len(order) == 1:
            raise ConvergenceError("no t = 1 crossing found (stand-in)")
        return real_multilevel(*args, **kwargs)

    def direct(*args, **kwargs):
        order.append("direct")
        return real_problem(*args, **kwargs)

    monkeypatch.setattr(ocp_module, "_multilevel_solve", multilevel)
    monkeypatch.setattr(ocp_module, "conformal_problem", direct)
    monkeypatch.setattr(ocp_module, "MULTILEVEL_FROM", plane.n_points)
    result = get_method("ocp")(plane.method_input(False))
    assert order[:2] == ["multilevel", "multilevel"]  # Neumann's, then the paper energy's
    diag = result.diagnostics
    assert diag["energy_used"] == "paper" and diag["selfcheck"]["passed"]
    quality = evaluate(plane.points, plane.faces, result.uv)
    assert quality["foldovers"] == 0 and quality["qc_mean"] < 1.01


def test_the_fallback_runs_without_the_failed_solves_arrays(plane, monkeypatch):
    """The error of the failed Neumann search is held through the paper-energy fallback;
    the arrays of the failed solve's frames are not (at 300k points they were gigabytes)."""
    import weakref

    class Big:
        pass

    refs, alive_in_fallback = [], []
    real_front, real_paper = ocp_module._solve_front, ocp_module._paper_energy_fallback

    def fails_holding_big(front, box, solver, params, timer, exact_fallbacks=True):
        if not refs:
            big = Big()
            refs.append(weakref.ref(big))
            raise ConvergenceError("no t = 1 crossing found (stand-in)")
        return real_front(front, box, solver, params, timer, exact_fallbacks)

    def paper(*args, **kwargs):
        alive_in_fallback.append(refs[0]() is not None)
        return real_paper(*args, **kwargs)

    monkeypatch.setattr(ocp_module, "_solve_front", fails_holding_big)
    monkeypatch.setattr(ocp_module, "_paper_energy_fallback", paper)
    result = get_method("ocp")(plane.method_input(False))
    assert alive_in_fallback == [False]
    assert result.diagnostics["energy_used"] == "paper"
