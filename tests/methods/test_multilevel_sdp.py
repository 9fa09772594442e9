"""SDP on two levels (``sdp``'s ``solver="multilevel"``) against the direct shift-invert solve."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

import parambench.methods.plugins.ocp as ocp_plugin
import parambench.methods.plugins.sdp as sdp_plugin
from parambench.bench.metrics import evaluate, similarity_align
from parambench.datasets_gen.errors import ConvergenceError, InvalidInputError, UnknownNameError
from parambench.datasets_gen.registry import make_surface
from parambench.methods import get_method
from parambench.methods.pointset.frontend import build_frontend
from parambench.methods.spectral import ConformalProblem
from parambench.methods.spectral.dirichlet import smallest_nontrivial_pair
from parambench.methods.spectral.multilevel_dirichlet import boundary_dirichlet_pair, multilevel_sdp


def _principal_sines(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Sines of the principal angles between the column spaces of a and b (mean removed)."""
    qa, _ = np.linalg.qr(a - a.mean(axis=0))
    qb, _ = np.linalg.qr(b - b.mean(axis=0))
    cos = np.clip(np.linalg.svd(qa.T @ qb, compute_uv=False), 0.0, 1.0)
    return np.sqrt(1.0 - cos**2)


@pytest.fixture(scope="module")
def bump_front():
    surf = make_surface("bump", 3000, sampling="jittered", seed=0)
    return build_frontend(surf.points_only().points)


def test_boundary_eigenproblem_is_the_full_one(bump_front):
    # With exact interior solves the subspace refinement must reach the pencil's own pair:
    # the same two eigenvalues and the same plane of eigenvectors on every point.
    front = bump_front
    lap = front.L
    b = sp.diags(front.boundary_mask.astype(np.float64))
    values, pair = smallest_nontrivial_pair(lap.tocsc(), b.tocsc())
    red = ConformalProblem(lap, front.boundary_loops, points=front.points).reduction()
    sub_values, sub_pair, boundary_pair, info = boundary_dirichlet_pair(red, front.boundary_loops, front.points)
    assert np.allclose(np.sort(sub_values), np.sort(values), rtol=1e-7)
    assert _principal_sines(sub_pair, pair).max() < 1e-5
    assert info["boundary_residual"] < 1e-8
    # Interior rows of L f = lambda B f: the pair is harmonic there (B vanishes).
    interior = ~front.boundary_mask
    assert np.abs((lap @ sub_pair)[interior]).max() < 1e-10 * np.abs(sub_pair).max()
    assert np.abs(boundary_pair.mean(axis=0)).max() < 1e-12  # constants removed


def test_multilevel_refuses_a_coarse_level_without_the_boundary(bump_front):
    front = bump_front
    coarse = np.arange(0, front.n_points, 5)
    with pytest.raises(InvalidInputError, match="every boundary-loop point"):
        multilevel_sdp(front.L, front.boundary_loops, front.points, coarse)


def test_unknown_fine_solver_is_refused_with_the_choices():
    surf = make_surface("bump", 600, sampling="jittered", seed=0)
    with pytest.raises(UnknownNameError, match="twogrid"):
        get_method("sdp")(surf.points_only(), solver="multilevel", fine_solver="amg")


@pytest.fixture(scope="module")
def sdp_20k():
    surf = make_surface("bump", 20_000, sampling="jittered", seed=0)
    method = get_method("sdp")
    return surf, method(surf.points_only(), solver="direct"), method(surf.points_only(), solver="multilevel")


def test_multilevel_sdp_matches_the_direct_solve_at_20k(sdp_20k):
    surf, direct, multi = sdp_20k
    kw = dict(boundary_loops=surf.boundary_loops, diameter=surf.diameter)
    ev_d = evaluate(surf.points, surf.faces, direct.uv, **kw)
    ev_m = evaluate(surf.points, surf.faces, multi.uv, **kw)
    assert ev_m["foldovers"] == ev_d["foldovers"] == 0
    assert abs(ev_m["qc_mean"] - ev_d["qc_mean"]) <= 0.002 * ev_d["qc_mean"]
    aligned = similarity_align(multi.uv, direct.uv)
    assert np.sqrt(np.mean(np.sum((aligned - direct.uv) ** 2, axis=1))) <= 1e-3 * surf.diameter
    assert np.allclose(multi.diagnostics["eigenvalues"], direct.diagnostics["eigenvalues"], rtol=1e-4)


def test_multilevel_sdp_really_is_two_level(sdp_20k):
    surf, direct, multi = sdp_20k
    d = multi.diagnostics
    assert d["solver"] == "multilevel" and direct.diagnostics["solver"] == "direct"
    assert 0 < d["coarse_points"] < surf.n_points / 4
    assert d["twogrid_cycles"] > 0 and not d["twogrid_fell_back"]
    assert {"subsample", "coarse", "solve"} <= set(multi.timings)


def test_auto_takes_two_levels_from_the_threshold_and_falls_back_where_they_fail(monkeypatch):
    surf = make_surface("bump", 3000, sampling="jittered", seed=0)
    sdp = get_method("sdp")
    assert sdp(surf.points_only()).diagnostics["solver"] == "direct"  # below the threshold
    monkeypatch.setattr(ocp_plugin, "MULTILEVEL_FROM", 1000)
    assert sdp(surf.points_only()).diagnostics["solver"] == "multilevel"

    def fails(*args, **kwargs):
        raise ConvergenceError("the boundary eigenproblem's refinement did not converge (stand-in)")

    monkeypatch.setattr(sdp_plugin, "two_level_sdp_pair", fails)
    with pytest.raises(ConvergenceError, match="use solver='direct'"):
        sdp(surf.points_only(), solver="multilevel")
    auto = sdp(surf.points_only())
    assert auto.diagnostics["solver"] == "direct" and auto.diagnostics["multilevel_error"].startswith("Convergence")
    assert np.array_equal(auto.uv, sdp(surf.points_only(), solver="direct").uv)
