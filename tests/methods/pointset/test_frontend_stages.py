"""Each stage of build_frontend on its own, on surfaces whose answer is known."""

from __future__ import annotations

import json

import numpy as np
import pytest

from parambench.datasets_gen.errors import InconsistentNormalsError, InvalidInputError, NoBoundaryError
from parambench.datasets_gen.registry import make_surface
from parambench.methods.pointset.frontend import (
    boundary_stage,
    build_frontend,
    dem_stage,
    knn_stage,
    normals_stage,
    stage_diagnostics,
    validate_inputs,
    weights_stage,
)
from parambench.methods.pointset.params import FrontEndParams

N_SIDE = 30
H = 1.0 / (N_SIDE - 1)


@pytest.fixture(scope="module")
def tilted_grid():
    """A regular N_SIDE x N_SIDE grid of step H on a tilted plane, shuffled.

    Returns (points, e1, e2, normal): the grid's in-plane axes and the plane's unit normal.
    """
    e1 = np.array([1.0, 0.0, 0.5]) / np.sqrt(1.25)
    e2 = np.array([0.0, 1.0, -0.3])
    e2 -= e1 * (e1 @ e2)
    e2 /= np.linalg.norm(e2)
    u, v = (a.ravel() for a in np.meshgrid(np.linspace(0, 1, N_SIDE), np.linspace(0, 1, N_SIDE)))
    pts = u[:, None] * e1 + v[:, None] * e2
    pts = pts[np.random.default_rng(0).permutation(len(pts))]
    return pts, e1, e2, np.cross(e1, e2)


@pytest.fixture(scope="module")
def grid_stages(tilted_grid):
    """knn, normals and dem stages run on the tilted grid."""
    pts = tilted_grid[0]
    nb = knn_stage(pts, 8)
    oriented, frame, _ = normals_stage(nb.points, None, nb.graph, nb.spacing)
    balls = dem_stage(nb.points, frame, nb.adjacency, nb.spacing, nb.h_local, ball_k=6, ball_eps_factor=2.5,
                      dem="upwind", max_ball=64)
    return nb, oriented, frame, balls


def test_validate_inputs_refuses_each_option_by_name():
    pts = np.random.default_rng(0).random((50, 3))
    for field, bad in [("dem_variant", "new"), ("weights", "cot"), ("dem", "fast"), ("spacing", "x"),
                       ("boundary_method", "alpha"), ("neighbours", "geodesic")]:
        with pytest.raises(InvalidInputError, match=field):
            validate_inputs(pts, None, FrontEndParams(**{field: bad}))
    with pytest.raises(InvalidInputError, match="k_nn must be an integer"):
        validate_inputs(pts, None, FrontEndParams(k_nn=2.5))
    out, normals = validate_inputs(pts.tolist(), None, FrontEndParams())
    assert out.dtype == np.float64 and out.shape == (50, 3) and normals is None


def test_knn_stage_orders_and_measures_the_grid(tilted_grid, grid_stages):
    pts = tilted_grid[0]
    nb = grid_stages[0]
    n = len(pts)
    np.testing.assert_array_equal(np.sort(nb.order), np.arange(n))
    np.testing.assert_array_equal(nb.points, pts[nb.order])
    np.testing.assert_array_equal(nb.points[nb.inv], pts)
    assert nb.graph.indices.shape == (n, 8)
    # every grid point's nearest neighbour is one grid step away
    np.testing.assert_allclose(nb.graph.distances[:, 0], H, rtol=1e-9)
    # interior points: 4 neighbours at H, 4 at H*sqrt(2); the boundary makes l a little larger
    assert (4 + 4 * np.sqrt(2)) / 8 * H < nb.spacing < 1.1 * (4 + 4 * np.sqrt(2)) / 8 * H
    assert nb.adjacency.shape == (n, n) and (nb.adjacency != nb.adjacency.T).nnz == 0
    # a uniform grid has (nearly) one spacing everywhere
    assert np.all(np.abs(nb.h_local / nb.spacing - 1) < 0.1)
    glob = knn_stage(pts, 8, spacing_mode="global")
    np.testing.assert_array_equal(glob.h_local, np.full(n, glob.spacing))


def test_normals_stage_returns_the_plane_normal(tilted_grid, grid_stages):
    normal = tilted_grid[3]
    oriented, frame = grid_stages[1], grid_stages[2]
    np.testing.assert_allclose(np.linalg.norm(oriented, axis=1), 1.0, atol=1e-12)
    dots = oriented @ normal
    # consistently oriented: all on one side, and the normal of the plane
    assert np.all(np.sign(dots) == np.sign(dots[0]))
    np.testing.assert_allclose(np.abs(dots), 1.0, atol=1e-9)
    np.testing.assert_allclose(np.abs(frame @ normal), 1.0, atol=1e-9)


def test_normals_stage_on_a_spherical_cap():
    cap = make_surface("cap", 1500, seed=0)
    nb = knn_stage(cap.points, 8)
    exact = cap.normals[nb.order]
    oriented, frame, _ = normals_stage(nb.points, None, nb.graph, nb.spacing)
    dots = np.einsum("ij,ij->i", oriented, exact)
    assert np.all(np.sign(dots) == np.sign(dots[0])) and np.abs(dots).min() > 0.995
    assert np.abs(np.einsum("ij,ij->i", frame, exact)).min() > 0.995
    # given normals are kept as they are; without smoothing the frames are those normals
    kept, unsmoothed, _ = normals_stage(nb.points, exact, nb.graph, nb.spacing, smooth=False)
    np.testing.assert_array_equal(kept, exact)
    assert unsmoothed is kept
    flipped = exact.copy()
    flipped[: len(flipped) // 2] *= -1
    with pytest.raises(InconsistentNormalsError):
        normals_stage(nb.points, flipped, nb.graph, nb.spacing)


def test_dem_stage_keeps_distances_on_a_plane(grid_stages):
    nb, _, _, balls = grid_stages
    mask = balls.mask
    assert balls.sizes.min() >= 6 and balls.sizes.max() <= 64
    assert np.all(mask.sum(axis=1) == balls.sizes)
    # on a plane the geodesic is the straight segment: tangent coordinates keep 3D distances
    offsets = nb.points[np.maximum(balls.indices, 0)] - nb.points[:, None, :]
    d3 = np.linalg.norm(offsets, axis=-1)
    d2 = np.linalg.norm(balls.coords, axis=-1)
    np.testing.assert_allclose(d2[mask], d3[mask], atol=1e-12)
    # a ball of radius 2.5 l around an interior point holds every grid point that close
    centre = int(np.argmin(np.linalg.norm(nb.points - nb.points.mean(axis=0), axis=1)))
    members = set(balls.indices[centre][mask[centre]].tolist())
    close = set(np.flatnonzero(np.linalg.norm(nb.points - nb.points[centre], axis=1) < 2.0 * nb.spacing).tolist())
    assert (close - {centre}) <= members


@pytest.mark.parametrize("weights", ["tangent", "lle3d"])
def test_weights_stage_reproduces_interior_points_of_a_plane(grid_stages, weights):
    nb, _, _, balls = grid_stages
    w, r_x = weights_stage(nb.points, balls, weights, 1e-2)
    assert w.shape == balls.indices.shape and r_x.shape == (len(nb.points),)
    np.testing.assert_allclose(w.sum(axis=1), 1.0, atol=1e-12)
    assert np.all(w[~balls.mask] == 0)
    # away from the border the weighted mean of the neighbours is the point itself (up to reg_eps)
    interior = np.linalg.norm(nb.points - nb.points.mean(axis=0), axis=1) < 0.25
    assert interior.sum() > 50
    offsets = nb.points[np.maximum(balls.indices, 0)] - nb.points[:, None, :]
    residual = np.linalg.norm((w[..., None] * offsets).sum(axis=1), axis=1)
    assert residual[interior].max() < 0.01 * nb.spacing
    assert r_x.max() < 0.05 * nb.spacing**2


def test_boundary_stage_finds_the_square(tilted_grid, grid_stages):
    _, e1, e2, _ = tilted_grid
    nb, _, frame, balls = grid_stages
    bnd, retried = boundary_stage(nb, frame, balls, FrontEndParams())
    u, v = nb.points @ e1, nb.points @ e2
    border = np.isclose(u, 0) | np.isclose(u, 1) | np.isclose(v, 0) | np.isclose(v, 1)
    assert not retried and len(bnd.loops) == 1
    np.testing.assert_array_equal(bnd.mask, border)
    loop = bnd.loops[0]
    assert sorted(loop.tolist()) == sorted(np.flatnonzero(border).tolist())
    # walked in order: consecutive loop points are one grid step apart
    steps = np.linalg.norm(nb.points[loop] - nb.points[np.roll(loop, -1)], axis=1)
    np.testing.assert_allclose(steps, H, rtol=1e-9)


def test_boundary_stage_refuses_a_closed_surface():
    rng = np.random.default_rng(0)
    x = rng.normal(size=(1500, 3))
    sphere = x / np.linalg.norm(x, axis=1, keepdims=True)
    nb = knn_stage(sphere, 8)
    _, frame, _ = normals_stage(nb.points, None, nb.graph, nb.spacing)
    balls = dem_stage(nb.points, frame, nb.adjacency, nb.spacing, nb.h_local, ball_k=6, ball_eps_factor=2.5,
                      dem="upwind", max_ball=64)
    for method in ("angle", "rings"):
        with pytest.raises(NoBoundaryError):
            boundary_stage(nb, frame, balls, FrontEndParams(boundary_method=method))


def test_stage_diagnostics_are_json_and_match_the_stages(grid_stages):
    nb, _, frame, balls = grid_stages
    w, r_x = weights_stage(nb.points, balls)
    bnd, retried = boundary_stage(nb, frame, balls, FrontEndParams())
    diag = stage_diagnostics(nb, balls, w, r_x, bnd, retried, k_nn=8, normals_given=False, neighbours="euclidean")
    json.dumps(diag)
    assert diag["n_points"] == N_SIDE**2 and diag["k_nn"] == 8 and diag["normals_source"] == "pca"
    assert diag["ball_size"]["min"] == balls.sizes.min() and diag["ball_size"]["max"] == balls.sizes.max()
    assert diag["reconstruction_error"]["max"] == pytest.approx(r_x.max() / nb.spacing**2)
    assert diag["boundary"]["retried_with_wider_balls"] is False
    # knn_stage's default ("auto") found no gap on the grid: its facts, under the mode given
    assert diag["neighbours"] == dict(nb.neighbour_diagnostics, mode="euclidean")
    assert nb.neighbour_diagnostics["pruned"] is False


def test_build_frontend_is_the_stages_chained(tilted_grid, grid_stages):
    """build_frontend gives what the stages give, mapped back to the input order."""
    pts = tilted_grid[0]
    nb, oriented, _, balls = grid_stages
    fe = build_frontend(pts)
    np.testing.assert_array_equal(fe.normals, oriented[nb.inv])
    np.testing.assert_array_equal(fe.knn_indices, nb.order[nb.graph.indices[nb.inv]])
    w, r_x = weights_stage(nb.points, balls)
    np.testing.assert_array_equal(fe.reconstruction_error, r_x[nb.inv])
    assert fe.mean_spacing == nb.spacing
