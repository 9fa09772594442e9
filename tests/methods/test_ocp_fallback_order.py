"""The order of ``ocp``'s fallbacks after a failed Neumann k search on a point set.

The cheap ones come first (the paper energy's search, then cotangent SCP on the mesh an
sdp map triangulates); the exact searches on the dense boundary reduction, which cost
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

    def paper(front, w_tan, solver, params, timer, exc):
        order.append("paper")
        raise exc

    def mesh(front, w_tan, timer, exc):
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
