"""W^tan and 3D LLE weights: exactness of the Woodbury solve, planar reproduction, negativity."""

from __future__ import annotations

import igl
import numpy as np
import pytest
from scipy.spatial import Delaunay

from parambench.datasets_gen.errors import InvalidInputError
from parambench.methods.pointset.frontend import build_frontend
from parambench.methods.pointset.laplacian import graph_laplacian
from parambench.methods.pointset.tangent_weights import (
    dense_weights,
    lle3d_weights,
    lle_weights,
    negative_weight_stats,
    reconstruction_error,
    tangent_weights,
    weight_matrix,
)


def _random_balls(rng, n=200, b=12, d=2):
    offsets = rng.normal(size=(n, b, d))
    sizes = rng.integers(4, b + 1, size=n)
    mask = np.arange(b)[None, :] < sizes[:, None]
    return offsets * mask[:, :, None], mask


def test_hand_computed_symmetric_neighbourhood():
    # Four neighbours on the axes: by symmetry every weight is 1/4, and the neighbourhood
    # is reproduced exactly whatever the regularisation.
    x = np.array([[[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]]])
    w = tangent_weights(x, np.ones((1, 4), dtype=bool), reg_eps=0.3)
    np.testing.assert_allclose(w, 0.25, atol=1e-15)
    assert reconstruction_error(x, w)[0] < 1e-30


def test_hand_computed_collinear_pair():
    # Neighbours at +1 and +3 on a line: C = [[1, 3], [3, 9]], tr = 10, eps = 0.1 ->
    # (C + I) w = 1 gives w = (7, -1) / 11, normalised (7/6, -1/6);
    # R_x = (7/6 * 1 - 1/6 * 3)^2 = 4/9.
    x = np.array([[[1.0, 0.0], [3.0, 0.0]]])
    w = tangent_weights(x, np.ones((1, 2), dtype=bool), reg_eps=0.1)
    np.testing.assert_allclose(w[0], [7 / 6, -1 / 6], rtol=1e-13)
    np.testing.assert_allclose(reconstruction_error(x, w), [4 / 9], rtol=1e-12)


@pytest.mark.parametrize("d", [2, 3])
@pytest.mark.parametrize("eps", [1e-1, 1e-2, 1e-3, 1e-6])
def test_woodbury_equals_padded_dense_solve(d, eps):
    rng = np.random.default_rng(d)
    offsets, mask = _random_balls(rng, d=d)
    fast = lle_weights(offsets, mask, eps)
    ref = dense_weights(offsets, mask, eps)
    np.testing.assert_allclose(fast, ref, atol=1e-9 * np.abs(ref).max())
    assert np.all(fast[~mask] == 0)
    np.testing.assert_allclose(fast.sum(axis=1), 1.0, atol=1e-12)


def test_nonpositive_eps_and_degenerate_ball_raise():
    x = np.zeros((1, 3, 2))
    with pytest.raises(InvalidInputError, match="reg_eps"):
        tangent_weights(np.ones((1, 3, 2)), np.ones((1, 3), dtype=bool), reg_eps=0.0)
    with pytest.raises(InvalidInputError, match="degenerate"):
        tangent_weights(x, np.ones((1, 3), dtype=bool))


def test_plane_grid_interior_is_reproduced_exactly(make_height_patch):
    # Interior balls of a regular grid are symmetric, so sum_j w_j T x_j = 0 exactly,
    # even with the default regularisation.
    patch = make_height_patch("plane", 40, "grid")
    fe = build_frontend(patch.points)
    xy = patch.points[:, :2]
    deep = np.all(np.abs(xy) < 1 - 4 * 2 / 39, axis=1)
    w = fe.W[deep]
    residual = w @ fe.points - fe.points[deep]
    assert np.abs(residual).max() < 1e-10 * fe.mean_spacing
    np.testing.assert_allclose(np.asarray(fe.W.sum(axis=1)).ravel(), 1.0, atol=1e-12)


@pytest.mark.parametrize("sampling", ["jittered", "random"])
def test_plane_reproduction_up_to_regularisation(make_height_patch, sampling):
    """sum_j w_j T x_j = lambda (lambda I + X^T X)^-1 X^T 1 / sum(w): O(eps), zero as eps -> 0."""
    patch = make_height_patch("plane", 40, sampling)
    residuals = {}
    for eps in (1e-2, 1e-4, 1e-10):
        fe = build_frontend(patch.points, reg_eps=eps)
        res = fe.W @ fe.points - fe.points
        residuals[eps] = np.abs(res).max() / fe.mean_spacing
        # R_x of W^tan is measured in the tangent plane = the plane itself here.
        np.testing.assert_allclose(fe.reconstruction_error, np.sum(res**2, axis=1), atol=1e-20, rtol=1e-8)
    assert residuals[1e-10] < 1e-8
    assert residuals[1e-4] < residuals[1e-2] < 0.2


def test_lle3d_equals_tangent_weights_on_a_plane(make_height_patch):
    # On a plane the tangent coordinates are an isometric copy of the 3D offsets, so the
    # Gram matrices, and hence the weights, coincide.
    patch = make_height_patch("plane", 30, "jittered")
    tan = build_frontend(patch.points, weights="tangent")
    lle = build_frontend(patch.points, weights="lle3d")
    assert abs(tan.W - lle.W).max() < 1e-10
    direct = lle3d_weights(tan.points, tan.ball_indices)
    assert abs(weight_matrix(tan.ball_indices, direct) - tan.W).max() < 1e-10


def test_weight_matrix_and_laplacian_layout():
    idx = np.array([[1, 2, -1], [0, -1, -1], [1, 0, 3], [2, -1, -1]])
    w = np.array([[0.5, 0.5, 0.0], [1.0, 0.0, 0.0], [0.2, 0.3, 0.5], [1.0, 0.0, 0.0]])
    mat = weight_matrix(idx, w)
    expected = np.array([[0, 0.5, 0.5, 0], [1, 0, 0, 0], [0.3, 0.2, 0, 0.5], [0, 0, 1, 0]])
    np.testing.assert_array_equal(mat.toarray(), expected)
    assert mat.has_sorted_indices
    lap = graph_laplacian(mat)
    np.testing.assert_array_equal(lap.toarray(), np.eye(4) - expected)
    np.testing.assert_allclose(lap @ np.ones(4), 0.0)


def test_negative_weight_stats_by_hand():
    w = np.array([[0.6, 0.6, -0.2], [0.5, 0.5, 0.0], [1.5, -0.5, 0.0]])
    mask = np.array([[1, 1, 1], [1, 1, 0], [1, 1, 0]], dtype=bool)
    stats = negative_weight_stats(w, mask, np.array([False, False, True]), bins=4)
    assert stats["negative_fraction"] == {"interior": 0.2, "boundary": 0.5}
    assert stats["points_with_negative"] == {"interior": 0.5, "boundary": 1.0}
    assert stats["min_weight"] == {"interior": -0.2, "boundary": -0.5}
    assert sum(stats["histogram"]["interior"]) == 5 and sum(stats["histogram"]["boundary"]) == 2
    assert stats["histogram"]["edges"][0] == -0.5 and stats["histogram"]["edges"][-1] == 1.5


@pytest.mark.parametrize("case", ["random", "no boundary", "all boundary", "constant", "no weights"])
def test_negative_weight_stats_in_batches_equal_the_whole_arrays(monkeypatch, case):
    import parambench.methods.pointset.tangent_weights as tw

    rng = np.random.default_rng(7)
    n, b = 500, 13
    w = rng.normal(0.1, 0.2, size=(n, b))
    mask = rng.random((n, b)) < 0.7
    bnd = rng.random(n) < 0.1
    if case == "no boundary":
        bnd[:] = False
    elif case == "all boundary":
        bnd[:] = True
    elif case == "constant":
        w[:] = 0.25
    elif case == "no weights":
        mask[:] = False
    monkeypatch.setattr(tw, "_CHUNK", 37)  # batches with and without boundary rows
    assert tw.negative_weight_stats(w, mask, bnd) == tw._negative_weight_stats_whole(w, mask, bnd)


@pytest.mark.parametrize("kind", ["bump", "saddle"])
def test_fewer_negative_interior_weights_than_cotangent(make_height_patch, kind):
    """Paper Sec. 3.2 / Fig. 5 on an irregular mesh: the Delaunay triangulation of random
    samples, lifted onto the curved surface. Measured: cotangent 3.7% (bump) and 7.5%
    (saddle) negative interior weights, W^tan about 1%."""
    patch = make_height_patch(kind, 50, "random")
    faces = Delaunay(patch.points[:, :2]).simplices.astype(np.int64)
    cot = igl.cotmatrix(patch.points, faces).tocoo()
    interior = ~patch.boundary_mask
    off = (cot.row != cot.col) & interior[cot.row]
    cot_negative = float((cot.data[off] < 0).mean())

    # The paper's setting (one ball radius 2.5 l): with radii from the local spacing the
    # balls of a random patch are smaller where it is denser (measured 2.0 % against 3.7 %).
    fe = build_frontend(patch.points, spacing="global")
    w = fe.W.tocoo()
    tan_negative = float((w.data[interior[w.row]] < 0).mean())
    assert cot_negative > 0.02
    assert tan_negative < 0.5 * cot_negative
    # More negative weights on the boundary than inside (W^tan still minimises R_x there).
    frac = fe.diagnostics["negative_weights"]["negative_fraction"]
    assert frac["boundary"] > frac["interior"]


@pytest.mark.parametrize("workers", [1, 2])
def test_weights_do_not_depend_on_the_batching(monkeypatch, workers):
    # Batches run on worker threads: each row's numbers must be those of one batch of
    # all rows, bit for bit.
    import numba

    import parambench.methods.pointset.tangent_weights as tw

    rng = np.random.default_rng(3)
    n, b = 301, 17
    coords = rng.normal(size=(n, b, 2))
    mask = rng.random((n, b)) < 0.8
    mask[:, :3] = True
    coords[~mask] = 0.0
    monkeypatch.setattr(tw, "_CHUNK", 10**6)
    w0 = tw.tangent_weights(coords, mask)
    r0 = tw.reconstruction_error(coords, w0)
    monkeypatch.setattr(numba.config, "NUMBA_NUM_THREADS", workers)
    monkeypatch.setattr(tw, "_CHUNK", 23)
    w1 = tw.tangent_weights(coords, mask)
    assert np.array_equal(w0, w1)
    assert np.array_equal(r0, tw.reconstruction_error(coords, w1))
    bad = coords.copy()
    bad[[40, 200]] = 0.0
    with pytest.raises(InvalidInputError, match="point 40 is degenerate"):
        tw.tangent_weights(bad, mask)


@pytest.mark.parametrize("seed", range(3))
def test_weight_matrix_kernel_equals_the_scipy_build(seed):
    from parambench.methods.pointset.tangent_weights import _weight_matrix_scipy

    rng = np.random.default_rng(seed)
    n, b = int(rng.integers(5, 200)), int(rng.integers(1, 30))
    idx = np.full((n, b), -1, dtype=np.int64)
    for i in range(n):  # distinct members in arbitrary order, padding anywhere
        m = int(rng.integers(0, min(b, n) + 1))
        cols = rng.choice(n, size=m, replace=False)
        idx[i, np.sort(rng.choice(b, size=m, replace=False))] = cols
    w = rng.normal(size=(n, b))
    w[rng.random((n, b)) < 0.1] = 0.0  # explicit zeros stay entries
    ref = _weight_matrix_scipy(idx, w)
    perm = rng.permutation(n)
    for got in (weight_matrix(idx, w), weight_matrix(idx, w[perm], weight_rows=np.argsort(perm))):
        assert got.has_sorted_indices
        for x, y in ((got.data, ref.data), (got.indices, ref.indices), (got.indptr, ref.indptr)):
            assert x.dtype == y.dtype and np.array_equal(x, y)
