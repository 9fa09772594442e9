"""``dem="auto"``: the upwind DEM, except projected offsets on noisy points with close pairs."""

from __future__ import annotations

import numpy as np
import pytest

from parambench.bench.metrics import evaluate
from parambench.datasets_gen.errors import InvalidInputError
from parambench.datasets_gen.registry import make_surface
from parambench.methods.pointset.frontend import (
    AUTO_CLOSE_PAIR_SHARE,
    AUTO_PROJECTED_ERROR_DEG,
    FrontEndParams,
    build_frontend,
    close_pair_share,
    resolved_dem,
)
from parambench.methods.pointset.neighbourhoods import knn_graph
from parambench.methods.registry import get_method


def _fit(median_deg: float) -> dict:
    return {"predicted_error_deg": {"median": median_deg, "p95": 2 * median_deg}}


@pytest.mark.parametrize("median, expected", [(0.0, "upwind"), (AUTO_PROJECTED_ERROR_DEG - 0.1, "upwind"),
                                              (AUTO_PROJECTED_ERROR_DEG, "projected"), (25.0, "projected")])
def test_auto_follows_the_normal_fits_error(median, expected):
    assert resolved_dem(FrontEndParams(), _fit(median), close_pairs=0.1) == expected


@pytest.mark.parametrize("share, expected", [(None, "upwind"), (0.0, "upwind"), (AUTO_CLOSE_PAIR_SHARE - 1e-3, "upwind"),
                                             (AUTO_CLOSE_PAIR_SHARE, "projected")])
def test_auto_projects_only_samplings_with_close_pairs(share, expected):
    assert resolved_dem(FrontEndParams(), _fit(25.0), close_pairs=share) == expected


@pytest.mark.parametrize("sampling, low, high", [("jittered", 0.0, 0.001), ("random", 0.08, 0.2)])
def test_close_pairs_tell_random_from_jittered_sampling_under_noise(sampling, low, high):
    """In the tangent plane: normal noise of 0.5 spacings does not hide a random sampling's pairs.
    (A Poisson sampling has a neighbour within r of a point with probability 1 - exp(-rho pi r^2).)"""
    surface = make_surface("plane", 5000, sampling=sampling, seed=0, noise=0.5)
    graph = knn_graph(surface.points, 8)
    normals = surface.normals  # the exact plane normal: only the sampling is tested here
    share = close_pair_share(surface.points, normals, graph.indices, graph.distances.mean(axis=1))
    assert low <= share <= high


def test_auto_without_fits_and_the_paper_variant_keep_the_upwind_dem():
    assert resolved_dem(FrontEndParams(), None, 0.1) == "upwind"  # given normals: no fit to judge by
    assert resolved_dem(FrontEndParams(), {}, 0.1) == "upwind"
    assert resolved_dem(FrontEndParams(dem_variant="paper"), _fit(25.0), 0.1) == "upwind"


@pytest.mark.parametrize("kind", ["upwind", "plain", "projected"])
def test_an_explicit_kind_is_kept(kind):
    assert resolved_dem(FrontEndParams(dem=kind), _fit(25.0), 0.1) == kind
    assert resolved_dem(FrontEndParams(dem=kind), _fit(0.0), 0.0) == kind


def test_unknown_kind_is_refused():
    points = make_surface("plane", 300, sampling="jittered", seed=0).points
    with pytest.raises(InvalidInputError, match="dem must be one of"):
        build_frontend(points, dem="exponential")


@pytest.mark.parametrize("sampling, noise, expected", [("random", 0.0, "upwind"), ("jittered", 0.5, "upwind"),
                                                      ("random", 0.5, "projected")])
def test_front_end_records_its_choice(sampling, noise, expected):
    points = make_surface("bump", 2000, sampling=sampling, seed=0, noise=noise).points
    front = build_frontend(points)
    assert front.diagnostics["dem"] == expected
    assert front.params["dem"] == "auto"


def test_noisy_random_sampling_folds_less_with_the_projection():
    """Random sampling, normal noise of 0.5 spacings: the DEM's fronts run through
    near-coincident points whose offsets are mostly noise. Measured (seed 0, 2k points):
    foldovers on the true mesh 22 -> 11 (bump), 22 -> 4 (cap)."""
    for name, most in (("bump", 12), ("cap", 6)):
        surface = make_surface(name, 2000, sampling="random", seed=0, noise=0.5)
        given = surface.method_input(False)
        folds = {dem: evaluate(surface.points, surface.faces, get_method("ocp")(given, dem=dem).uv)["foldovers"]
                 for dem in ("upwind", "auto")}
        assert folds["auto"] <= most < folds["upwind"], (name, folds)


def test_noisy_close_paired_samplings_refit_their_normals_harder():
    """Where the balls are projected, the normals aim at 2 degrees on up to 160 neighbours
    (normals.NOISY_TARGET_DEG): the order of close pairs along the surface depends on it."""
    plane = make_surface("plane", 3000, sampling="random", seed=0, noise=0.5)
    front = build_frontend(plane.points)
    assert front.diagnostics["dem"] == "projected"
    tilt = np.degrees(np.arccos(np.clip(np.abs(front.normals[:, 2]), 0.0, 1.0)))
    assert np.median(tilt) < 3.0 and front.diagnostics["normal_fit"]["refit_k"]["max"] > 64  # 4.3 with the usual refit
    # Clean or jittered samplings keep the usual refit (their upwind DEM): the same normals
    # as a front end asked for the upwind DEM outright.
    for sampling, noise in (("random", 0.0), ("jittered", 0.5)):
        points = make_surface("bump", 2000, sampling=sampling, seed=0, noise=noise).points
        assert np.array_equal(build_frontend(points).normals, build_frontend(points, dem="upwind").normals)


def test_noisy_random_holes_fold_nothing():
    """holes, 2k random points at noise 0.5: 10 foldovers on the true mesh with the usual refit, 0 now."""
    surface = make_surface("holes", 2000, sampling="random", seed=0, noise=0.5)
    result = get_method("ocp")(surface.method_input(False))
    assert evaluate(surface.points, surface.faces, result.uv)["foldovers"] == 0
    assert result.diagnostics["selfcheck"]["passed"]
