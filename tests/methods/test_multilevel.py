"""The multilevel path of ocp: the Poisson-disk subsample, the prolongation, and the
two-level solve against the direct one.

Accuracy targets of issue #14 (checked here at 20k points, bump): QC mean within 0.2 % of
the direct solve, 0 foldovers, k_opt equal to 1e-3, uv RMS difference after similarity
alignment at most 1e-3 of the diameter, and the same self-check passed.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.spatial.distance import pdist, squareform
from scipy.spatial import cKDTree

from parambench.bench.metrics import evaluate
from parambench.bench.metrics.alignment import similarity_align
from parambench.datasets_gen.errors import InvalidInputError, UnknownNameError
from parambench.datasets_gen.registry import make_surface
from parambench.methods import get_method
from parambench.methods.pointset.subsample import poisson_disk_subsample
from parambench.methods.spectral import ConformalProblem
from parambench.methods.spectral.multilevel import MultilevelSettings, interpolation_matrix, multilevel_scp
from parambench.methods.spectral.subspace import BoundarySubspace


def _grid(n: int = 20) -> np.ndarray:
    u, v = np.meshgrid(np.arange(n, dtype=float), np.arange(n, dtype=float))
    return np.column_stack([u.ravel(), v.ravel(), np.zeros(n * n)])


# ---------------------------------------------------------------- subsample
def test_subsample_is_spread_maximal_and_keeps_the_given_points():
    pts = _grid(20)
    keep = np.flatnonzero((pts[:, 0] == 0) | (pts[:, 0] == 19))  # two dense rows
    radius = 2.5
    sample = poisson_disk_subsample(pts, radius, keep, seed=3)
    assert np.all(np.isin(keep, sample))
    d = squareform(pdist(pts))
    free = np.setdiff1d(sample, keep)
    # Spread: no two sampled points closer than the radius unless both are kept.
    close = d[np.ix_(free, sample)]
    close[close == 0] = np.inf  # a point against itself
    assert close.min() >= radius
    # Maximal: every point lies within the radius of a sampled point.
    assert d[:, sample].min(axis=1).max() < radius
    # Much smaller than the input in the interior.
    assert free.size < 0.25 * (pts.shape[0] - keep.size)


def test_subsample_is_deterministic_per_seed():
    pts = np.random.default_rng(1).random((2000, 3)) * [10, 10, 0.1]
    a = poisson_disk_subsample(pts, 0.5, seed=7)
    b = poisson_disk_subsample(pts, 0.5, seed=7)
    c = poisson_disk_subsample(pts, 0.5, seed=8)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)


def _luby_reference(nbr: np.ndarray, state: np.ndarray, priority: np.ndarray) -> None:
    """Whole-array Luby rounds (the form the compiled kernel replaced), in place."""
    n = nbr.shape[0]
    while True:
        undecided = np.flatnonzero(state[:n] == 0)
        near_sampled = (state[nbr[undecided]] == 1).any(axis=1)
        state[undecided[near_sampled]] = -1
        undecided = undecided[~near_sampled]
        if undecided.size == 0:
            return
        rival = np.where(state[nbr[undecided]] == 0, priority[nbr[undecided]], -1.0).max(axis=1)
        state[undecided[priority[undecided] > rival]] = 1


@pytest.mark.parametrize("seed", range(4))
def test_compiled_luby_rounds_equal_the_whole_array_rounds(seed):
    from parambench.methods.pointset.subsample import _luby_rounds

    rng = np.random.default_rng(seed)
    n, k = 3000, 7
    # Asymmetric lists with misses (index n), as a bounded kNN query gives them.
    nbr = rng.integers(0, n + 1, size=(n, k))
    nbr[nbr == np.arange(n)[:, None]] = n  # a query never lists the point itself
    state = np.zeros(n + 1, dtype=np.int8)
    state[rng.choice(n, 40, replace=False)] = 1
    priority = np.append(rng.random(n), -1.0)
    expected = state.copy()
    _luby_reference(nbr, expected, priority)
    _luby_rounds(nbr, state, priority)
    np.testing.assert_array_equal(state, expected)
    assert not np.any(state[:n] == 0)


def test_subsample_in_leaf_order_is_the_sample_of_the_input_order():
    # The kd-tree query runs on the points in leaf order for speed; each point keeps its
    # own priority, so the sample is the one the input order gives (no order-dependent choice).
    rng = np.random.default_rng(5)
    pts = rng.random((4000, 3)) * [20, 20, 0.2]  # scrambled order, as a scanner writes it
    keep = rng.choice(4000, 60, replace=False)
    radius, seed = 0.9, 11
    dist, nbr = cKDTree(pts).query(pts, k=25, distance_upper_bound=radius)
    nbr = np.where(np.isfinite(dist[:, 1:]), nbr[:, 1:], pts.shape[0])
    state = np.zeros(pts.shape[0] + 1, dtype=np.int8)
    state[keep] = 1
    _luby_reference(nbr, state, np.append(np.random.default_rng(seed).random(pts.shape[0]), -1.0))
    np.testing.assert_array_equal(poisson_disk_subsample(pts, radius, keep, seed=seed),
                                  np.flatnonzero(state[:-1] == 1))


@pytest.mark.parametrize("kwargs", [dict(radius=0.0), dict(radius=1.0, keep=[400])])
def test_subsample_rejects_bad_input(kwargs):
    with pytest.raises(InvalidInputError):
        poisson_disk_subsample(_grid(20), **kwargs)


def test_subsample_rejects_non_finite_points():
    pts = _grid(5)
    pts[3, 1] = np.nan
    with pytest.raises(InvalidInputError, match="finite"):
        poisson_disk_subsample(pts, 1.0)


# ------------------------------------------------------------- prolongation
def test_interpolation_is_identity_on_coarse_points_and_reproduces_constants():
    pts = _grid(10)
    coarse = poisson_disk_subsample(pts, 2.0, seed=0)
    p = interpolation_matrix(pts, coarse)  # no normals: inverse-distance weights
    assert p.shape == (pts.shape[0], coarse.size)
    np.testing.assert_allclose(np.asarray(p.sum(axis=1)).ravel(), 1.0)
    np.testing.assert_array_equal(p[coarse].toarray(), np.eye(coarse.size))
    assert p.min() >= 0
    # Each fine point takes its value from its six nearest coarse points only.
    assert np.diff(p.indptr).max() <= 6


def test_interpolation_with_normals_reproduces_linear_functions():
    # A tilted plane: linear functions of position must be interpolated exactly.
    pts = _grid(12) @ np.array([[1.0, 0.0, 0.3], [0.0, 1.0, -0.2], [0.0, 0.0, 1.0]])
    normal = np.cross([1.0, 0.0, 0.3], [0.0, 1.0, -0.2])
    normals = np.tile(normal / np.linalg.norm(normal), (pts.shape[0], 1))
    coarse = poisson_disk_subsample(pts, 2.0, seed=0)
    p = interpolation_matrix(pts, coarse, normals)
    np.testing.assert_allclose(np.asarray(p.sum(axis=1)).ravel(), 1.0, atol=1e-12)
    np.testing.assert_allclose(p @ pts[coarse], pts, atol=1e-9)
    # Inverse-distance weights would not be exact: the test can tell the two apart.
    idw = interpolation_matrix(pts, coarse)
    assert np.abs(idw @ pts[coarse] - pts).max() > 1e-3


def test_multilevel_refuses_a_coarse_level_without_the_boundary():
    pts = _grid(6)
    lap = sp.csr_matrix(np.eye(36) - np.full((36, 36), 1 / 36))
    loop = np.array([0, 1, 2, 3, 4, 5, 11, 17, 23, 29, 35, 34, 33, 32, 31, 30, 24, 18, 12, 6])
    with pytest.raises(InvalidInputError, match="boundary"):
        multilevel_scp(lap, [loop], pts, np.array([0, 7, 14]))


def test_a_handed_over_laplacian_is_released_and_put_back_on_failure(monkeypatch):
    import parambench.methods.spectral.multilevel as multilevel_module
    from parambench.datasets_gen.errors import ConvergenceError
    from parambench.methods.plugins.ocp import ocp_laplacian
    from parambench.methods.pointset.frontend import build_frontend

    front = build_frontend(make_surface("bump", 3000, sampling="jittered", seed=0).points)
    lap = ocp_laplacian(front)
    coarse = poisson_disk_subsample(front.points, 2.0 * front.mean_spacing, np.concatenate(front.boundary_loops))
    box = [lap.copy()]
    sol, _ = multilevel_scp(box, front.boundary_loops, front.points, coarse, normals=front.normals)
    assert box == []  # released: the solver keeps only its reordered copy
    direct, _ = multilevel_scp(lap, front.boundary_loops, front.points, coarse, normals=front.normals)
    np.testing.assert_array_equal(sol.z, direct.z)

    def fails(*args, **kwargs):
        raise ConvergenceError("two-level stand-in")

    monkeypatch.setattr(multilevel_module, "_two_levels", fails)
    box = [lap.copy()]
    with pytest.raises(ConvergenceError):
        multilevel_scp(box, front.boundary_loops, front.points, coarse, normals=front.normals)
    assert len(box) == 1 and (box[0] != lap).nnz == 0  # back, in the caller's order
    # A refusal before any work leaves the list as it was.
    box = [lap]
    with pytest.raises(InvalidInputError):
        multilevel_scp(box, front.boundary_loops, front.points, coarse[:10], normals=front.normals)
    assert len(box) == 1 and box[0] is lap


def test_unknown_solver_is_refused_with_the_choices():
    surf = make_surface("bump", 600, sampling="jittered", seed=0)
    with pytest.raises(UnknownNameError, match="multilevel"):
        get_method("ocp")(surf.points_only(), solver="amg")


def test_multilevel_refuses_the_direct_k_search():
    surf = make_surface("bump", 600, sampling="jittered", seed=0)
    with pytest.raises(InvalidInputError, match="k_search='line'"):
        get_method("ocp")(surf.points_only(), solver="multilevel", k_search="direct")


# ------------------------------------------------------------ accuracy, 20k
@pytest.fixture(scope="module")
def bump_20k():
    surf = make_surface("bump", 20_000, sampling="jittered", seed=0)
    method = get_method("ocp")
    direct = method(surf.points_only(), solver="direct")
    multi = method(surf.points_only(), solver="multilevel")
    return surf, direct, multi


def test_multilevel_matches_direct_solve_at_20k(bump_20k):
    surf, direct, multi = bump_20k
    kw = dict(boundary_loops=surf.boundary_loops, diameter=surf.diameter)
    ev_d = evaluate(surf.points, surf.faces, direct.uv, **kw)
    ev_m = evaluate(surf.points, surf.faces, multi.uv, **kw)
    assert ev_m["foldovers"] == 0
    assert abs(ev_m["qc_mean"] - ev_d["qc_mean"]) <= 0.002 * ev_d["qc_mean"]
    assert abs(multi.diagnostics["k_opt"] - direct.diagnostics["k_opt"]) <= 1e-3
    aligned = similarity_align(multi.uv, direct.uv)
    rms = np.sqrt(np.mean(np.sum((aligned - direct.uv) ** 2, axis=1)))
    # uv is scaled to the 3D spacing, so the diameter's unit is shared.
    assert rms <= 1e-3 * surf.diameter


def test_multilevel_passes_the_self_check_and_really_is_two_level(bump_20k):
    surf, direct, multi = bump_20k
    assert multi.diagnostics["selfcheck"]["passed"]
    assert multi.diagnostics["solver"] == "multilevel"
    assert direct.diagnostics["solver"] == "direct"
    assert 0 < multi.diagnostics["coarse_points"] < surf.n_points / 4
    assert {"subsample", "coarse", "solve"} <= set(multi.timings)
    assert "coarse" not in direct.timings
    # The fine subspace is the coarse map plus a few modes: far fewer fine solves.
    assert multi.diagnostics["subspace_size"] < direct.diagnostics["subspace_size"] / 2
    # The fine level factorises nothing: its interior solves are two-grid cycles on the
    # coarse level's factorisation, and they converged (no direct fallback).
    assert multi.diagnostics["fine_solver"] == "twogrid" and multi.diagnostics["factorizations"] == 0
    assert multi.diagnostics["twogrid_cycles"] > 0 and not multi.diagnostics["twogrid_fell_back"]
    assert direct.diagnostics["factorizations"] >= 1


def test_multilevel_fine_solvers_give_the_same_map(bump_20k):
    surf, _, multi = bump_20k
    factored = get_method("ocp")(surf.points_only(), solver="multilevel", fine_solver="direct")
    assert factored.diagnostics["factorizations"] == 1 and "twogrid_cycles" not in factored.diagnostics
    # The two-grid path stops refining at SOLVE_FLOOR times its solves' tolerance (a boundary
    # residual of 5e-7, not 1e-9): measured k 1.7e-5 and uv 4.1e-5 of the diameter apart.
    assert multi.diagnostics["boundary_residual"] <= BoundarySubspace.SOLVE_FLOOR * MultilevelSettings().fine_rtol
    assert abs(factored.diagnostics["k_opt"] - multi.diagnostics["k_opt"]) <= 1e-4
    aligned = similarity_align(multi.uv, factored.uv)
    assert np.sqrt(np.mean(np.sum((aligned - factored.uv) ** 2, axis=1))) <= 2e-4 * surf.diameter


def test_auto_solver_takes_the_two_level_path_from_its_threshold(monkeypatch):
    import parambench.methods.plugins.ocp as ocp_plugin

    surf = make_surface("bump", 3000, sampling="jittered", seed=0)
    below = get_method("ocp")(surf.points_only())
    assert below.diagnostics["solver"] == "direct" and below.diagnostics["solver_option"] == "auto"
    monkeypatch.setattr(ocp_plugin, "MULTILEVEL_FROM", 2000)
    above = get_method("ocp")(surf.points_only())
    assert above.diagnostics["solver"] == "multilevel" and above.diagnostics["coarse_points"] > 0
    # the direct k search has no two-level path: auto keeps it direct at any size
    direct_k = get_method("ocp")(surf.points_only(), k_search="direct")
    assert direct_k.diagnostics["solver"] == "direct"
    assert ocp_plugin.resolve_solver("multilevel", 10, "line") == "multilevel"
    assert ocp_plugin.resolve_solver("auto", 10**6, "direct") == "direct"


def test_bump_20k_needs_no_second_fine_search(bump_20k):
    _, _, multi = bump_20k
    assert multi.diagnostics["fine_enlarged"] is False


def test_an_unsettled_fine_search_is_repeated_on_a_larger_subspace(monkeypatch, bump_20k):
    import functools

    import parambench.methods.spectral.multilevel as multilevel

    surf, direct, first = bump_20k
    # A k tolerance of 0 never settles and a residual limit of 0 is always exceeded: the
    # second search on the enlarged subspace must run and still match the direct solve.
    monkeypatch.setattr(multilevel, "MultilevelSettings",
                        functools.partial(MultilevelSettings, fine_ktol=0.0, enlarge_residual=0.0))
    again = get_method("ocp")(surf.points_only(), solver="multilevel")
    diag = again.diagnostics
    assert diag["fine_enlarged"] is True
    assert diag["subspace_size"] >= 2 * MultilevelSettings().enlarged_modes > first.diagnostics["subspace_size"]
    assert diag["triangular_solves"] > first.diagnostics["triangular_solves"]
    assert abs(diag["k_opt"] - direct.diagnostics["k_opt"]) <= 1e-4
    aligned = similarity_align(again.uv, direct.uv)
    assert np.sqrt(np.mean(np.sum((aligned - direct.uv) ** 2, axis=1))) <= 1e-3 * surf.diameter


def test_auto_falls_back_to_the_direct_solve_where_two_levels_fail(monkeypatch):
    import parambench.methods.plugins.ocp as ocp_plugin
    from parambench.datasets_gen.errors import ConvergenceError

    surf = make_surface("bump", 3000, sampling="jittered", seed=0)
    monkeypatch.setattr(ocp_plugin, "MULTILEVEL_FROM", 1000)

    def fails(*args, **kwargs):
        raise ConvergenceError("no t = 1 crossing (two-level stand-in)")

    monkeypatch.setattr(ocp_plugin, "_multilevel_solve", fails)
    ocp = get_method("ocp")
    with pytest.raises(ConvergenceError, match="use solver='direct'"):
        ocp(surf.points_only(), solver="multilevel", refine="none")
    # With the refinement allowed, both energies' two-level searches failing leave the
    # mesh an sdp map triangulates (as on the direct path).
    meshed = ocp(surf.points_only(), solver="multilevel")
    assert meshed.diagnostics["energy_used"] == "mesh" and meshed.diagnostics["selfcheck"]["passed"]
    # An energy without a fallback of its own is solved directly, as solver='direct' does.
    auto = ocp(surf.points_only(), energy="paper")
    assert auto.diagnostics["solver"] == "direct" and auto.diagnostics["solver_option"] == "auto"
    assert auto.diagnostics["multilevel_error"].startswith("ConvergenceError")
    assert np.array_equal(auto.uv, ocp(surf.points_only(), solver="direct", energy="paper").uv)
    # The default energy goes to its fallbacks instead, which keep to two levels at the
    # sizes two levels are for (a direct solve there costs minutes and gigabytes): the
    # paper energy's search (failing here too), then the mesh a two-level sdp map
    # triangulates.
    def no_direct_pair(*args, **kwargs):
        raise AssertionError("the direct sdp pair was solved")

    monkeypatch.setattr(ocp_plugin, "direct_sdp_pair", no_direct_pair)
    default = ocp(surf.points_only())
    diag = default.diagnostics
    assert diag["solver"] == "multilevel" and diag["energy_used"] == "mesh" and diag["selfcheck"]["passed"]
    assert diag["refined"]["first_map"] == "sdp"
    quality = evaluate(surf.points, surf.faces, default.uv)
    assert quality["foldovers"] == 0 and quality["qc_mean"] < 1.01


def test_interpolation_stays_on_its_own_sheet():
    # Two parallel sheets one coarse spacing apart, normals facing away from each other
    # (a fold seen up close): every fine point must interpolate from its own sheet.
    g = _grid(12)
    lower, upper = g.copy(), g.copy()
    upper[:, 2] = 0.8
    pts = np.vstack([lower, upper])
    normals = np.vstack([np.tile([0.0, 0.0, -1.0], (len(g), 1)), np.tile([0.0, 0.0, 1.0], (len(g), 1))])
    coarse = np.flatnonzero((pts[:, 0] % 3 == 0) & (pts[:, 1] % 3 == 0))
    p = interpolation_matrix(pts, coarse, normals).tocoo()
    sheet = pts[:, 2] > 0.4
    assert np.all(sheet[p.row] == sheet[coarse[p.col]])
    # Linear functions on each sheet are still reproduced.
    assert np.allclose(p @ pts[coarse][:, :2], pts[:, :2])


def test_multilevel_maps_the_fold_it_used_to_bridge():
    fold = make_surface("fold", 5000, sampling="jittered", seed=0)
    ocp = get_method("ocp")
    multi = ocp(fold.points_only(), solver="multilevel")
    direct = ocp(fold.points_only(), solver="direct")
    assert abs(multi.diagnostics["k_opt"] - direct.diagnostics["k_opt"]) <= 1e-3
    q = evaluate(fold.points, fold.faces, multi.uv, boundary_loops=fold.boundary_loops, diameter=fold.diameter)
    assert q["foldovers"] == 0


def test_a_failed_coarse_search_leaves_the_fine_level_to_fourier_modes(monkeypatch, bump_20k):
    import parambench.methods.spectral.multilevel as multilevel
    from parambench.datasets_gen.errors import ConvergenceError

    surf, direct, _ = bump_20k

    def fails(self, *args, **kwargs):  # only the coarse level asks for an estimate
        raise ConvergenceError("no t = 1 crossing (coarse stand-in)")

    monkeypatch.setattr(multilevel.ConformalProblem, "scp_subspace_estimate", fails)
    multi = get_method("ocp")(surf.points_only(), solver="multilevel")
    diag = multi.diagnostics
    assert diag["coarse_error"].startswith("ConvergenceError") and diag["coarse_k_opt"] is None
    assert diag["subspace_size"] >= 2 * MultilevelSettings().enlarged_modes - 2
    assert abs(diag["k_opt"] - direct.diagnostics["k_opt"]) <= 1e-4
    aligned = similarity_align(multi.uv, direct.uv)
    assert np.sqrt(np.mean(np.sum((aligned - direct.uv) ** 2, axis=1))) <= 1e-3 * surf.diameter


def test_the_coarse_preconditioner_inverts_the_coarse_boundary_operator(bump_front_small):
    # With the "coarse" level the fine one itself, the preconditioner must be the exact
    # inverse of k/2 S - M_KK + s I on the boundary (S the dense Schur complement), with
    # Olsen's correction: t = C^{-1} r - C^{-1} z (z^H C^{-1} r) / (z^H C^{-1} z).
    from parambench.methods.spectral.multilevel import COARSE_SHIFT, coarse_scp_preconditioner
    from parambench.methods.spectral.operators import area_matrix

    lap, loops, points = bump_front_small
    k = 0.9
    precondition = coarse_scp_preconditioner(lap, loops)
    red = ConformalProblem(lap, loops, points=points).reduction()
    keep = red.keep
    m_kk = area_matrix(loops, lap.shape[0]).toarray()[np.ix_(keep, keep)]
    shift = COARSE_SHIFT * 0.5 * k * np.abs(lap.diagonal()).max()
    c = 0.5 * k * red.schur - m_kk + shift * np.eye(keep.size)
    rng = np.random.default_rng(1)
    r = rng.standard_normal(keep.size) + 1j * rng.standard_normal(keep.size)
    z = rng.standard_normal(keep.size) + 1j * rng.standard_normal(keep.size)
    t_r, t_z = np.linalg.solve(c, r), np.linalg.solve(c, z)
    expected = t_r - t_z * (np.vdot(z, t_r) / np.vdot(z, t_z))
    got = precondition(k, 0.0, r, z)
    assert np.abs(got - expected).max() <= 1e-8 * np.abs(expected).max()
    assert abs(np.vdot(z, got)) <= 1e-10 * np.linalg.norm(z) * np.linalg.norm(got)  # Olsen: z-orthogonal


@pytest.fixture(scope="module")
def bump_front_small():
    from parambench.methods.base import StageTimer
    from parambench.methods.plugins.ocp import ocp_laplacian
    from parambench.methods.pointset.plugin_support import FRONTEND_DEFAULTS, run_frontend

    surf = make_surface("bump", 1500, sampling="jittered", seed=0)
    front = run_frontend(surf.points_only(), dict(FRONTEND_DEFAULTS), StageTimer())
    return sp.csr_matrix(ocp_laplacian(front, "neumann", 1.0)), front.boundary_loops, front.points


def test_an_iterative_solver_that_fell_back_to_a_factorisation_solves_exactly(bump_front_small):
    # The refinement floors its residual at a multiple of the interior solves' tolerance;
    # once the two-grid solver factorises (fold, slit) the solves are exact and the
    # floor must go (fold at 100k points: 6.7e-4 of the diameter off the exact map -> 3.3e-7).
    from parambench.methods.spectral.reduction import BoundaryReduction
    from parambench.methods.spectral.sparse_eigen import SparseFactor

    lap, loops, _ = bump_front_small

    class Iterative(SparseFactor):
        iterative, rtol = True, 1e-8

        def __init__(self, matrix, fell_back):
            super().__init__(matrix)
            self.fell_back = fell_back

    keep = np.concatenate(loops)
    for fell_back, expected in ((False, 1e-8), (True, 0.0)):
        red = BoundaryReduction(lap, keep, interior_solver=lambda l_ii, interior: Iterative(l_ii, fell_back))
        assert red.solves_are_iterative and red.solve_rtol == expected


def _aligned_error(z: np.ndarray, ref: np.ndarray) -> float:
    a = np.column_stack([z.real, z.imag])
    b = np.column_stack([ref.real, ref.imag])
    diameter = float(np.hypot(*np.ptp(b, axis=0)))
    return float(np.sqrt(np.mean(np.sum((similarity_align(a, b) - b) ** 2, axis=1))) / diameter)


def test_a_map_limited_by_its_two_grid_solves_is_polished_to_the_error_asked_for(bump_front_small):
    # Loose two-grid solves floor the boundary residual (SOLVE_FLOOR x fine_rtol) far above
    # what the spectral gap allows for an accurate map: map_error tightens them and
    # settles the search again; without it the map stays where the floor left it.
    from dataclasses import replace

    from scipy.spatial import cKDTree

    lap, loops, points = bump_front_small
    spacing = float(np.mean(cKDTree(points).query(points, k=2)[0][:, 1]))
    coarse = poisson_disk_subsample(points, 2.0 * spacing, np.concatenate(loops), seed=0)
    exact = ConformalProblem(lap, loops, points=points).solve("scp", "line")
    loose = MultilevelSettings(fine_rtol=1e-4, map_error=None)
    plain, plain_info = multilevel_scp(lap, loops, points, coarse, settings=loose)
    polished, info = multilevel_scp(lap, loops, points, coarse, settings=replace(loose, map_error=1e-3))
    assert plain.diagnostics["polish_rtol"] is None
    assert plain.diagnostics["map_error_estimate"] > 1e-3  # the premise: the loose map needs it
    assert polished.diagnostics["polish_rtol"] < 1e-4
    assert polished.diagnostics["map_error_estimate"] < plain.diagnostics["map_error_estimate"]
    assert info["twogrid_cycles"] > plain_info["twogrid_cycles"]
    err_plain, err_polished = _aligned_error(plain.z, exact.z), _aligned_error(polished.z, exact.z)
    # measured (1500 points): 6.1e-4 -> 5.8e-6 of the diameter, k_opt 6.2e-4 -> 6.5e-6 off
    assert err_polished <= 2e-5 and err_polished < err_plain / 10
    assert abs(polished.k - exact.k) <= min(2e-5 * exact.k, abs(plain.k - exact.k) / 10)


def test_ocp_passes_map_error_to_the_two_level_path_and_refuses_a_bad_one():
    surf = make_surface("bump", 3000, sampling="jittered", seed=0)
    method = get_method("ocp")
    for bad in (-1.0, 0, "tight", True):
        with pytest.raises(InvalidInputError, match="map_error"):
            method(surf.points_only(), solver="multilevel", map_error=bad)
    plain = method(surf.points_only(), solver="multilevel")
    assert plain.diagnostics["polish_rtol"] is None  # off by default
    asked = 1e-3 * plain.diagnostics["map_error_estimate"]
    tight = method(surf.points_only(), solver="multilevel", map_error=asked)
    assert tight.diagnostics["polish_rtol"] < MultilevelSettings().fine_rtol
    assert tight.diagnostics["map_error_estimate"] < plain.diagnostics["map_error_estimate"]


def test_an_unsettled_search_at_the_solves_floor_is_polished(bump_front_small):
    # A k tolerance of 0 never settles; with loose two-grid solves the refinement sits at
    # their floor, so the unsettled search is polished (and only then, by default).
    from dataclasses import replace

    from scipy.spatial import cKDTree

    lap, loops, points = bump_front_small
    spacing = float(np.mean(cKDTree(points).query(points, k=2)[0][:, 1]))
    coarse = poisson_disk_subsample(points, 2.0 * spacing, np.concatenate(loops), seed=0)
    exact = ConformalProblem(lap, loops, points=points).solve("scp", "line")
    loose = MultilevelSettings(fine_rtol=1e-4, fine_ktol=0.0, enlarge_residual=1.0)
    off, _ = multilevel_scp(lap, loops, points, coarse, settings=replace(loose, unsettled_map_error=None))
    on, _ = multilevel_scp(lap, loops, points, coarse, settings=replace(loose, unsettled_map_error=1e-3))
    assert not off.diagnostics["subspace_settled"] and off.diagnostics["polish_rtol"] is None
    assert off.diagnostics["boundary_residual"] <= 2 * BoundarySubspace.SOLVE_FLOOR * 1e-4
    assert on.diagnostics["polish_rtol"] < 1e-4
    assert _aligned_error(on.z, exact.z) < _aligned_error(off.z, exact.z) / 10
    settled = MultilevelSettings(fine_rtol=1e-4, unsettled_map_error=1e-3)
    calm, _ = multilevel_scp(lap, loops, points, coarse, settings=settled)
    assert calm.diagnostics["subspace_settled"] and calm.diagnostics["polish_rtol"] is None
