"""ConformalProblem: SCP/DNCP at fixed k, direct and line-searched k_opt, both back ends."""

from __future__ import annotations

import igl
import numpy as np
import pytest

from parambench.datasets_gen.errors import ConvergenceError, InvalidInputError, SolverError, UnknownNameError
from parambench.methods.spectral import ConformalProblem
from parambench.methods.spectral.ksearch import line_search
from parambench.methods.spectral.sparse_eigen import SparseFactor


def identity_uv(case):
    return case.points[:, :2]


def test_flat_disk_gives_identity_despite_double_zero_eigenvalue(plane, uv_rms):
    # Translations and the identity map both have eigenvalue 0 (four zeros in real 2V
    # form); deflating translations must still return the identity, not a constant.
    for b in ("boundary", igl.massmatrix(plane.points, plane.faces, igl.MASSMATRIX_TYPE_VORONOI)):
        prob = ConformalProblem(plane.lap, plane.loops, b_matrix=b, points=plane.points)
        sol = prob.solve("scp")
        assert abs(sol.eigenvalue) < 1e-9
        assert uv_rms(sol.uv, identity_uv(plane)) < 1e-9
        assert sol.diagnostics["n_eigen_solves"] == 1 and sol.diagnostics["n_factorizations"] == 1


def test_holes_multiple_loops(holes, uv_rms):
    prob = ConformalProblem(holes.lap, holes.loops, points=holes.points)
    for k_search in ("none", "line", "direct"):
        sol = prob.solve("scp", k_search)
        assert sorted(sol.turning.tolist()) == [-1, -1, -1, 1]
        assert uv_rms(sol.uv, identity_uv(holes)) < 1e-8
        assert abs(sol.k - 1.0) < 1e-9


def test_backends_agree(saddle, uv_rms):
    prob = ConformalProblem(saddle.lap, saddle.loops, points=saddle.points)
    a = prob.scp(1.0, backend="sparse")
    b = prob.scp(1.0, backend="boundary")
    assert np.isclose(a.eigenvalue.real, b.eigenvalue.real, rtol=1e-6)
    assert uv_rms(a.uv, b.uv) < 1e-8
    pins = (saddle.loops[0][0], saddle.loops[0][40])
    c = prob.dncp(1.0, pins, backend="sparse")
    d = prob.dncp(1.0, pins, backend="boundary")
    assert np.allclose(c.z, d.z, atol=1e-9)
    assert np.isclose(c.z[pins[1]], 1.0) and np.isclose(c.z[pins[0]], 0.0)


def test_line_and_direct_agree_and_dncp_loses_its_pins(saddle, uv_rms):
    prob = ConformalProblem(saddle.lap, saddle.loops, points=saddle.points)
    direct = prob.solve("scp", "direct")
    line = prob.solve("scp", "line")
    assert abs(line.k - direct.k) < 1e-10
    assert 0.999 < direct.k <= 1.0  # cotangent: E_D >= A, so k_opt <= 1, and nearly 1
    assert uv_rms(line.uv, direct.uv) < 1e-8
    landscape = line.diagnostics["landscape"]
    assert len(landscape["k"]) == line.diagnostics["n_k_evaluations"]
    # The search starts from the pencil's k_opt estimate; Eq. 16's full line search from
    # k = 1 (through spinning maps) finds the same k_opt with many more evaluations.
    full = line_search(prob._scp_reduced)
    assert any(max(map(abs, t)) > 1 for t in full.landscape["t"])
    assert abs(full.best.k - line.k) < 1e-10
    assert line.diagnostics["n_k_evaluations"] <= 8 < full.n_evaluations
    loop = saddle.loops[0]
    for pins in [(loop[0], loop[len(loop) // 2]), (loop[3], loop[9]), (loop[10], loop[-20])]:
        d = prob.solve("dncp", "line", pins=pins)
        assert abs(d.k - direct.k) < 1e-10
        assert uv_rms(d.uv, direct.uv) < 1e-8


@pytest.mark.parametrize("k_search", ["line", "direct"])
def test_k_opt_scales_inversely_with_the_laplacian(saddle, k_search):
    base = ConformalProblem(saddle.lap, saddle.loops).solve("scp", k_search).k
    scaled = ConformalProblem(saddle.lap / 3.0, saddle.loops).solve("scp", k_search).k
    assert np.isclose(scaled, 3.0 * base, rtol=1e-9)


@pytest.mark.slow
def test_k_opt_does_not_depend_on_b(saddle):
    mass = igl.massmatrix(saddle.points, saddle.faces, igl.MASSMATRIX_TYPE_VORONOI)
    k_b = ConformalProblem(saddle.lap, saddle.loops).solve("scp", "direct").k
    # mass B: the line search runs on the sparse back end, through indefinite k < k_opt
    prob = ConformalProblem(saddle.lap, saddle.loops, b_matrix=mass, points=saddle.points)
    sol = prob.solve("scp", "line")
    assert sol.diagnostics["backend"] == "sparse"
    assert abs(sol.k - k_b) < 1e-9


def test_normalized_weights_need_and_get_a_larger_k(saddle, uv_rms):
    lap = saddle.weights_laplacian("cotangent", normalized=True)
    prob = ConformalProblem(lap, saddle.loops, points=saddle.points)
    assert not prob.hermitian
    with pytest.raises(SolverError, match="indefinite"):
        prob.solve("scp", "none")
    sol = prob.solve("scp", "line")
    # row sums of cotangent weights are about 2 (1.7 inside a 60-deg lattice, less at the boundary)
    assert 1.3 < sol.k < 4.0 and sol.turning.tolist() == [1]
    # non-Hermitian sparse and dense solves agree at the same k
    dense = prob.scp(sol.k * 1.05, backend="boundary")
    sparse = prob.scp(sol.k * 1.05, backend="sparse")
    assert np.isclose(dense.eigenvalue, sparse.eigenvalue, rtol=1e-6)
    assert uv_rms(sparse.uv, dense.uv) < 1e-7


def test_indefinite_energy_is_refused_not_returned(saddle):
    prob = ConformalProblem(saddle.lap, saddle.loops, points=saddle.points)
    with pytest.raises(SolverError, match="indefinite"):
        prob.scp(0.5, backend="sparse")
    with pytest.raises(SolverError, match="indefinite"):
        prob.scp(0.5, backend="boundary")
    low = prob.scp(0.5, backend="sparse", allow_negative=True)
    dense_low = prob.scp(0.5, backend="boundary", allow_negative=True)
    assert low.eigenvalue.real < 0 and np.isclose(low.eigenvalue.real, dense_low.eigenvalue.real, rtol=1e-6)
    assert abs(low.turning[0]) > 1  # the minimiser spins


def test_search_failures_are_reported(saddle):
    prob = ConformalProblem(saddle.lap, saddle.loops)
    with pytest.raises(ConvergenceError, match="no t = 1 crossing in the k bracket"):
        prob.solve("scp", "line", bracket=(0.2, 0.5))
    with pytest.raises(ConvergenceError, match="no t = 1 crossing in the k bracket"):
        prob.solve("dncp", "line", pins=(saddle.loops[0][0], saddle.loops[0][30]), bracket=(0.2, 0.5))


def test_reversed_loops_give_the_mirror_image(saddle, uv_rms):
    prob = ConformalProblem(saddle.lap, saddle.loops)
    flipped = ConformalProblem(saddle.lap, [loop[::-1] for loop in saddle.loops])
    a, b = prob.solve("scp", "direct"), flipped.solve("scp", "direct")
    assert np.isclose(a.k, b.k, rtol=1e-10)
    assert uv_rms(b.uv, a.uv) < 1e-8
    # same loops in the same order, so the flipped map encloses negative area
    assert np.vdot(b.z, prob.area @ b.z).real < 0 < np.vdot(a.z, prob.area @ a.z).real


def test_bad_arguments(saddle):
    with pytest.raises(UnknownNameError):
        ConformalProblem(saddle.lap, saddle.loops, b_matrix="identity")
    with pytest.raises(InvalidInputError, match="sum to zero"):
        ConformalProblem(saddle.lap + 0.1 * np.eye(1)[0, 0] * igl.massmatrix(saddle.points, saddle.faces), saddle.loops)
    prob = ConformalProblem(saddle.lap, saddle.loops)
    with pytest.raises(UnknownNameError):
        prob.solve("lscm")
    with pytest.raises(UnknownNameError):
        prob.solve("scp", "golden")
    with pytest.raises(InvalidInputError, match="two distinct"):
        prob.solve("dncp", "none", pins=(3, 3))


def test_dncp_direct_with_non_symmetric_weights(saddle):
    # k_direct with pins on a non-symmetric Laplacian once tested the pins array for truth
    # ("truth value of an array ... is ambiguous"); it must take the pencil's own vectors.
    lap = saddle.weights_laplacian("cotangent", normalized=True)
    pins = (saddle.loops[0][0], saddle.loops[0][40])
    prob = ConformalProblem(lap, saddle.loops, points=saddle.points)
    assert not prob.hermitian
    direct = prob.solve("dncp", "direct", pins=pins)
    line = ConformalProblem(lap, saddle.loops, points=saddle.points).solve("dncp", "line", pins=pins)
    assert direct.diagnostics["regular_boundary"]
    assert np.isclose(direct.k, line.k, rtol=1e-9)


def test_a_failed_subspace_search_goes_to_the_exact_search_only_with_direct_solves(saddle, uv_rms, monkeypatch):
    # With iterative interior solves (the two-level path's fine level) the exact search's
    # reduction would take one iterative solve per boundary point: the error goes up to
    # the caller instead (ocp's solver="auto" then takes the direct path). The saddle's
    # 146 boundary points take the subspace search from subspace_from=50 on.
    reference = ConformalProblem(saddle.lap, saddle.loops, points=saddle.points).solve("scp", "line")

    def fails(self, line_kwargs, exact_fallback=False):
        raise SolverError("the subspace map spins (stand-in)")

    monkeypatch.setattr(ConformalProblem, "_scp_subspace_search", fails)
    direct = ConformalProblem(saddle.lap, saddle.loops, points=saddle.points, subspace_from=50).solve("scp", "line")
    assert direct.diagnostics["subspace_fallback"] == "the subspace map spins (stand-in)"
    assert abs(direct.k - reference.k) < 1e-6 and uv_rms(direct.uv, reference.uv) < 1e-6
    iterative = ConformalProblem(saddle.lap, saddle.loops, points=saddle.points, subspace_from=50,
                                 interior_solver=lambda l_ii, interior: SparseFactor(l_ii))
    with pytest.raises(SolverError, match="stand-in"):
        iterative.solve("scp", "line")


def _line_searches_fail(prob: ConformalProblem, monkeypatch) -> list:
    """Make every line search of ``prob`` fail; the list records each k_search asked for."""
    real_solve, asked = prob.solve, []

    def line_fails(mode, k_search="none", **kwargs):
        asked.append(k_search)
        if k_search == "line":
            raise ConvergenceError("no t = 1 crossing found (stand-in)")
        return real_solve(mode, k_search, **kwargs)

    monkeypatch.setattr(prob, "solve", line_fails)
    return asked


@pytest.mark.parametrize("cap_above_boundary", [True, False])
def test_failed_line_search_falls_back_to_the_direct_k_only_on_small_boundaries(plane, monkeypatch,
                                                                               cap_above_boundary):
    """The automatic fallback's dense eigen-solves are cubic in the boundary's size: above
    EXACT_FALLBACK_MAX_BOUNDARY the line search's failure is reported at once, with the
    direct search offered as a hint; below it the direct search runs and gives the map."""
    from parambench.methods.spectral import problem as problem_module

    prob = ConformalProblem(plane.lap, plane.loops, points=plane.points)
    n_boundary = prob.boundary.size
    monkeypatch.setattr(problem_module, "EXACT_FALLBACK_MAX_BOUNDARY",
                        n_boundary if cap_above_boundary else n_boundary - 1)
    asked = _line_searches_fail(prob, monkeypatch)
    if cap_above_boundary:
        sol = problem_module.solve_line_then_direct(prob, "scp")
        assert asked == ["line", "direct"] and sol.diagnostics["k_search_fallback"] == "direct"
        assert abs(sol.k - 1.0) < 1e-9
    else:
        with pytest.raises(ConvergenceError, match=f"not tried on {n_boundary} boundary points.*k_search='direct'"):
            problem_module.solve_line_then_direct(prob, "scp")
        assert asked == ["line"]


def test_without_exact_fallbacks_a_failed_search_is_left_to_the_caller(saddle, plane, monkeypatch):
    """``exact_fallbacks=False`` (the caller has a cheaper fallback: ocp's paper energy):
    a failed subspace search is raised as it is, without the exact search on the dense
    boundary reduction, and a failed line search without the direct k; the message
    says they were left to the caller (who runs them if its fallback fails)."""
    from parambench.methods.spectral import problem as problem_module

    def fails(self, line_kwargs, exact_fallback=False):
        assert exact_fallback is False  # nor inside the subspace search
        raise SolverError("the subspace map spins (stand-in)")

    exact_runs = []
    real_reduced = ConformalProblem._scp_reduced
    monkeypatch.setattr(ConformalProblem, "_scp_reduced",
                        lambda self, k: exact_runs.append(k) or real_reduced(self, k))
    with monkeypatch.context() as patch:
        patch.setattr(ConformalProblem, "_scp_subspace_search", fails)
        prob = ConformalProblem(saddle.lap, saddle.loops, points=saddle.points, subspace_from=50,
                                exact_fallbacks=False)
        assert not prob.exact_fallback_affordable()
        with pytest.raises(SolverError, match="stand-in"):
            prob.solve("scp", "line")
        assert exact_runs == []

    prob = ConformalProblem(plane.lap, plane.loops, points=plane.points, exact_fallbacks=False)
    real_solve = prob.solve
    asked = _line_searches_fail(prob, monkeypatch)
    with pytest.raises(ConvergenceError, match="the exact searches were left for the caller's fallback") as err:
        problem_module.solve_line_then_direct(prob, "scp")
    assert asked == ["line"] and "k_search" not in str(err.value)
    # Asked for, the direct search still runs and maps the plane.
    assert abs(real_solve("scp", "direct").k - 1.0) < 1e-9


@pytest.mark.parametrize("symmetric", [True, False])
def test_the_direct_fallback_examines_few_candidates_only_for_nonsymmetric_weights(plane, monkeypatch, symmetric):
    """With non-symmetric weights each near-real candidate of the direct fallback costs a
    dense eigen-solve and none beyond the largest few has given a map (13 s on scattered
    real/lilium for nothing): the fallback looks at FALLBACK_NONSYMMETRIC_CANDIDATES; with
    symmetric weights a candidate is free and all are looked at."""
    from parambench.methods.spectral import problem as problem_module

    lap = plane.lap.tolil(copy=True)
    if not symmetric:  # one off-diagonal pair made unequal, rows still summing to zero
        i = plane.lap[0].indices[plane.lap[0].indices != 0][0]  # a neighbour of vertex 0
        lap[0, i] += 1e-3
        lap[0, 0] -= 1e-3
    prob = ConformalProblem(lap.tocsr(), plane.loops, points=plane.points)
    assert prob.hermitian is symmetric
    real_direct, seen = prob.k_direct, []

    def direct_spy(extra=(), max_candidates=None, imag_tol=None):
        seen.append(max_candidates)
        return real_direct(extra, max_candidates, imag_tol)

    _line_searches_fail(prob, monkeypatch)
    monkeypatch.setattr(prob, "k_direct", direct_spy)
    sol = problem_module.solve_line_then_direct(prob, "scp")
    assert seen == [None if symmetric else problem_module.FALLBACK_NONSYMMETRIC_CANDIDATES]
    assert abs(sol.k - 1.0) < 1e-2  # a plane: the identity's k, also with the small asymmetry
