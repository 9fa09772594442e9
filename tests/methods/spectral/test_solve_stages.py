"""The stages of ConformalProblem.solve, each on its own: name checks, pins, the three k paths, finish."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from parambench.datasets_gen.errors import InvalidInputError, SolverError, UnknownNameError
from parambench.methods.spectral import ConformalProblem
from parambench.methods.spectral.problem import ConformalSolution, _checked_names


@pytest.fixture(scope="module")
def pins(saddle):
    return np.array([saddle.loops[0][0], saddle.loops[0][40]]), np.array([0.0, 1.0], dtype=complex)


def test_checked_names_checks_mode_first():
    assert _checked_names("dncp", "direct") == ("dncp", "direct")
    with pytest.raises(UnknownNameError, match="mode 'lscm'"):
        _checked_names("lscm", "golden")
    with pytest.raises(UnknownNameError, match="k_search 'golden'"):
        _checked_names("scp", "golden")


def test_dncp_pins_only_for_dncp(saddle):
    prob = ConformalProblem(saddle.lap, saddle.loops)
    assert prob._dncp_pins("scp", (3, 3), (0.0, 0.0)) == (None, None)  # SCP ignores pins, even bad ones
    with pytest.raises(InvalidInputError, match="two pinned"):
        prob._dncp_pins("dncp", None, (0.0, 1.0))
    p, v = prob._dncp_pins("dncp", [5, 9], [0.0, 1j])
    assert p.dtype == np.int64 and p.tolist() == [5, 9] and v.tolist() == [0.0, 1j]


@pytest.mark.parametrize("b_kind", ["boundary", "mass"])
@pytest.mark.parametrize("backend", ["auto", "sparse", "boundary"])
@pytest.mark.parametrize("mode", ["scp", "dncp"])
def test_line_evaluator_picks_the_back_end(saddle, pins, mode, backend, b_kind):
    n = saddle.points.shape[0]
    b = "boundary" if b_kind == "boundary" else sp.identity(n, format="csr") / n
    prob = ConformalProblem(saddle.lap, saddle.loops, b, points=saddle.points)
    evaluate, reduced = prob._line_evaluator(mode, backend, *pins)
    # "auto" reduces only with B on the boundary; a forced reduction works for DNCP with
    # any B (it keeps the pins) but not for SCP, whose B must live on the kept vertices.
    use_b = backend == "boundary" or (backend == "auto" and b_kind == "boundary")
    want_reduced = use_b and (mode == "dncp" or b_kind == "boundary")
    assert reduced == want_reduced
    k = 1.1
    if mode == "scp":
        ref = prob._scp_reduced(k) if want_reduced else prob._scp_sparse(k, True)
    else:
        ref = prob._dncp_reduced(k, *pins) if want_reduced else prob._dncp_sparse(k, *pins)
    got = evaluate(k)
    assert got.k == k and got.energy == ref.energy and np.array_equal(got.state[0], ref.state[0])


def test_line_evaluator_rejects_unknown_backend(saddle):
    with pytest.raises(UnknownNameError, match="backend 'dense'"):
        ConformalProblem(saddle.lap, saddle.loops)._line_evaluator("scp", "dense")


def test_solve_fixed_uses_sparse_scp_under_auto(saddle, pins):
    prob = ConformalProblem(saddle.lap, saddle.loops, points=saddle.points)
    sol = prob._solve_fixed("scp", 1.0, None, None, "auto")
    ref = prob.scp(1.0, backend="sparse")
    assert sol.diagnostics["backend"] == "sparse" and sol.k == 1.0 and np.array_equal(sol.z, ref.z)
    dn = prob._solve_fixed("dncp", 1.0, *pins, "auto")
    assert np.array_equal(dn.z[pins[0]], pins[1]) and np.array_equal(dn.z, prob.dncp(1.0, *pins).z)


@pytest.mark.parametrize("mode", ["scp", "dncp"])
def test_solve_direct_is_at_k_direct(saddle, pins, mode):
    prob = ConformalProblem(saddle.lap, saddle.loops, points=saddle.points)
    sol = prob._solve_direct(mode, *pins, "auto")
    assert sol.k == prob.k_direct(pins[0] if mode == "dncp" else ())[0]
    if mode == "scp":
        # the pencil's map has zero energy at k_opt
        assert sol.eigenvalue == 0.0 and abs(sol.energy) < 1e-8
    else:
        assert np.array_equal(sol.z[pins[0]], pins[1]) and sol.eigenvalue is None


@pytest.mark.parametrize("mode", ["scp", "dncp"])
def test_solve_line_finds_the_direct_k(saddle, pins, mode):
    prob = ConformalProblem(saddle.lap, saddle.loops, points=saddle.points)
    sol, diag = prob._solve_line(mode, *pins, "boundary", dict(growth=1.25, r=0.5, bracket=None, xatol=1e-9))
    assert set(diag) == {"landscape", "bracket", "n_k_evaluations"}
    lo, hi = diag["bracket"]
    assert lo <= sol.k <= hi and diag["n_k_evaluations"] == len(diag["landscape"]["k"])
    assert np.isclose(sol.k, prob.k_direct(pins[0] if mode == "dncp" else ())[0], rtol=1e-6)
    assert sol.z.shape == (saddle.points.shape[0],) and sol.diagnostics["backend"] == "boundary"


def _solution(z, turning):
    return ConformalSolution(z=np.asarray(z, dtype=complex), k=1.0, energy=0.0, turning=np.asarray(turning),
                             diagnostics={"backend": "sparse"})


def test_finish_refuses_irregular_searched_maps_only(saddle):
    prob = ConformalProblem(saddle.lap, saddle.loops)
    with pytest.raises(SolverError, match="not a regular flattening"):
        prob._finish(_solution([0, 1], [2]), "scp", "line", {"k_search": "line"})
    sol = prob._finish(_solution([0, 1], [2]), "scp", "none", {"k_search": "none"})
    assert sol.diagnostics["regular_boundary"] is False and sol.diagnostics["turning_numbers"] == [2]
    assert sol.diagnostics["backend"] == "sparse" and sol.diagnostics["k_search"] == "none"
    assert "eigenvalue" not in sol.diagnostics
    with pytest.raises(SolverError, match="non-finite"):
        prob._finish(_solution([0, np.nan], [1]), "dncp", "none", {"k_search": "none"})
