"""kNN graph, PCA normals, orientation, smoothing and tangent frames."""

from __future__ import annotations

import numpy as np
import pytest

from parambench.datasets_gen.errors import DisconnectedError, InconsistentNormalsError, TooFewPointsError
from parambench.methods.pointset.neighbourhoods import (
    KnnGraph,
    _symmetric_adjacency_scipy,
    knn_graph,
    require_connected,
    symmetric_adjacency,
)
from parambench.methods.pointset.normals import (
    check_user_normals,
    consistent_signs,
    orient_normals,
    pca_normals,
    smooth_normals,
    tangent_frames,
)


def _square_grid(n, h=1.0):
    g = np.arange(n) * h
    xy = np.stack(np.meshgrid(g, g), axis=-1).reshape(-1, 2)
    return np.c_[xy, np.zeros(len(xy))]


def test_knn_on_a_square_grid_by_hand():
    pts = _square_grid(5, h=0.5)
    graph = knn_graph(pts, 4)
    centre = 12  # (1.0, 1.0): its 4 nearest are the axis neighbours at 0.5
    assert set(graph.indices[centre].tolist()) == {7, 11, 13, 17}
    np.testing.assert_allclose(graph.distances[centre], 0.5)
    assert not np.any(graph.indices == np.arange(25)[:, None])
    assert np.all(np.diff(graph.distances, axis=1) >= 0)
    # Interior points: 4 x 0.5; edge points: 3 x 0.5 + 0.5 sqrt(2)... mean by brute force.
    d = np.linalg.norm(pts[:, None] - pts[None], axis=-1)
    np.testing.assert_allclose(graph.mean_spacing, np.sort(d, axis=1)[:, 1:5].mean())


def test_symmetric_adjacency_is_the_union_of_knn_edges():
    pts = np.random.default_rng(0).normal(size=(60, 3))
    graph = knn_graph(pts, 5)
    adj = symmetric_adjacency(graph)
    assert abs(adj - adj.T).max() == 0
    for i in range(60):
        for j, d in zip(graph.indices[i], graph.distances[i]):
            assert adj[i, j] == pytest.approx(d) and adj[j, i] == pytest.approx(d)
    assert adj.nnz <= 2 * 60 * 5 and adj.diagonal().max() == 0


def _same_csr(a, b):
    return all(np.array_equal(x, y) and x.dtype == y.dtype
               for x, y in ((a.data, b.data), (a.indices, b.indices), (a.indptr, b.indptr)))


@pytest.mark.parametrize("seed", range(4))
def test_symmetric_adjacency_kernel_equals_sparse_maximum(seed):
    rng = np.random.default_rng(seed)
    n, k = int(rng.integers(12, 300)), int(rng.integers(1, 10))
    # Arbitrary distinct neighbours and lengths that differ by direction: the merge must
    # take the larger, as scipy's maximum does.
    idx = np.stack([rng.choice(np.delete(np.arange(n), i), size=k, replace=False) for i in range(n)])
    graph = KnnGraph(indices=idx, distances=rng.uniform(0.1, 2.0, size=(n, k)), mean_spacing=1.0)
    adj = symmetric_adjacency(graph)
    assert _same_csr(adj, _symmetric_adjacency_scipy(graph)) and adj.has_sorted_indices
    real = knn_graph(rng.normal(size=(n, 3)), min(k, n - 1))
    assert _same_csr(symmetric_adjacency(real), _symmetric_adjacency_scipy(real))


def test_symmetric_adjacency_of_odd_rows_takes_the_sparse_path():
    # A repeated neighbour (summed by the COO conversion), a self loop, a zero length.
    idx = np.array([[1, 1], [0, 1], [0, 1]])
    dist = np.array([[1.0, 1.0], [1.0, 0.0], [2.0, 3.0]])
    graph = KnnGraph(indices=idx, distances=dist, mean_spacing=1.0)
    assert _same_csr(symmetric_adjacency(graph), _symmetric_adjacency_scipy(graph))


def test_too_few_points_and_disconnected_graph():
    with pytest.raises(TooFewPointsError):
        knn_graph(np.random.default_rng(1).normal(size=(8, 3)), 8)
    a = _square_grid(10)
    b = _square_grid(6) + [100.0, 0.0, 0.0]
    graph = knn_graph(np.vstack([a, b]), 8)
    with pytest.raises(DisconnectedError, match=r"several components: 100, 36 points.*increase k_nn"):
        require_connected(symmetric_adjacency(graph), 8)


@pytest.mark.parametrize("seed", range(4))
def test_component_sizes_equal_scipy_components(seed):
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components

    from parambench.methods.pointset.neighbourhoods import _component_sizes

    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 400))
    m = int(rng.integers(0, 2 * n))
    # Directed, unsymmetric entries: the undirected components join either direction.
    a = sp.csr_matrix((rng.uniform(0.5, 1.0, m), (rng.integers(0, n, m), rng.integers(0, n, m))), shape=(n, n))
    _, labels = connected_components(a, directed=False)
    want = np.sort(np.bincount(labels))[::-1]
    np.testing.assert_array_equal(_component_sizes(a), want)
    np.testing.assert_array_equal(_component_sizes(a.tocoo()), want)  # the scipy path


def test_pca_normals_on_plane_and_sphere(make_sphere):
    rng = np.random.default_rng(2)
    plane = np.c_[rng.uniform(size=(300, 2)), np.zeros(300)]
    n = pca_normals(plane, knn_graph(plane, 8).indices)
    np.testing.assert_allclose(np.abs(n[:, 2]), 1.0, atol=1e-12)
    sphere = make_sphere(4000)
    n = pca_normals(sphere, knn_graph(sphere, 8).indices)
    assert np.abs(np.einsum("ij,ij->i", n, sphere)).min() > 0.999


def test_orientation_repairs_random_flips_and_follows_the_global_rule(make_cap, make_sphere):
    patch = make_cap(1.0, 1.2, 40, "jittered")
    graph = knn_graph(patch.points, 8)
    flips = np.where(np.random.default_rng(3).random(len(patch.points)) < 0.5, -1.0, 1.0)
    oriented = orient_normals(patch.points, patch.normals * flips[:, None], graph.indices)
    np.testing.assert_allclose(oriented, patch.normals)  # consistent, and +z (sum's largest axis)
    sphere = make_sphere(3000)
    out = orient_normals(sphere, -sphere, knn_graph(sphere, 8).indices)
    np.testing.assert_allclose(out, sphere)  # normals cancel: outward from the centroid


def test_consistent_signs_on_a_long_chain():
    # A 2000-point helix strip: the spanning tree is deep, exercising pointer doubling.
    t = np.linspace(0, 40, 2000)
    pts = np.c_[np.cos(t), np.sin(t), 0.05 * t]
    normals = np.c_[np.cos(t), np.sin(t), np.zeros_like(t)]
    flips = np.where(np.arange(2000) % 3 == 0, -1.0, 1.0)
    signs = consistent_signs(pts, normals * flips[:, None], knn_graph(pts, 4).indices)
    fixed = normals * (flips * signs)[:, None]
    assert abs(np.einsum("ij,ij->i", fixed, normals).sum()) == pytest.approx(2000)


@pytest.mark.parametrize("method", ["linear", "average"])
def test_smoothing_reduces_noise(make_cap, method):
    patch = make_cap(1.0, 1.0, 40, "jittered")
    rng = np.random.default_rng(4)
    noisy = patch.normals + 0.1 * rng.normal(size=patch.normals.shape)
    noisy /= np.linalg.norm(noisy, axis=1, keepdims=True)
    graph = knn_graph(patch.points, 8)
    smooth = smooth_normals(patch.points, noisy, graph.indices, graph.distances, graph.mean_spacing, method=method)
    err = lambda n: np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", n, patch.normals), -1, 1))).mean()
    assert err(smooth) < 0.6 * err(noisy)
    np.testing.assert_allclose(np.linalg.norm(smooth, axis=1), 1.0)


def test_linear_smoothing_has_no_boundary_tilt(make_cap):
    """Exact sphere normals, one-sided boundary neighbourhoods: the weighted average tilts
    towards the interior (measured ~1.3 degrees here), the local-linear fit stays exact to
    second order."""
    patch = make_cap(1.0, 1.0, 40, "grid")
    graph = knn_graph(patch.points, 8)
    args = (patch.points, patch.normals, graph.indices, graph.distances, graph.mean_spacing)
    tilt = lambda n: np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", n, patch.normals), -1, 1)))
    b = patch.boundary_mask
    avg = tilt(smooth_normals(*args, method="average"))[b].mean()
    lin = tilt(smooth_normals(*args, method="linear"))[b].mean()
    assert avg > 0.5
    assert lin < 0.1 * avg


def test_user_normals_checks(make_cap):
    patch = make_cap(1.0, 1.0, 30, "jittered")
    graph = knn_graph(patch.points, 8)
    fitted = pca_normals(patch.points, graph.indices)
    check_user_normals(patch.points, patch.normals, fitted, graph.indices)  # consistent: no error
    check_user_normals(patch.points, -patch.normals, fitted, graph.indices)  # all flipped is still consistent
    flipped = patch.normals.copy()
    flipped[::7] *= -1
    with pytest.raises(InconsistentNormalsError, match="other side.*omit normals"):
        check_user_normals(patch.points, flipped, fitted, graph.indices)
    sideways = np.tile([1.0, 0.0, 0.0], (len(patch.points), 1))  # consistent but in the tangent plane
    with pytest.raises(InconsistentNormalsError, match="perpendicular"):
        check_user_normals(patch.points, sideways, fitted, graph.indices)


def test_tangent_frames_are_right_handed_orthonormal():
    rng = np.random.default_rng(5)
    n = rng.normal(size=(500, 3))
    n = np.vstack([n, [[0, 0, 1], [0, 0, -1], [1e-17, 0, -1], [1, 0, 0]]])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    e1, e2 = tangent_frames(n)
    for a, b in ((e1, e1), (e2, e2)):
        np.testing.assert_allclose(np.einsum("ij,ij->i", a, b), 1.0, atol=1e-12)
    for a, b in ((e1, e2), (e1, n), (e2, n)):
        np.testing.assert_allclose(np.einsum("ij,ij->i", a, b), 0.0, atol=1e-12)
    np.testing.assert_allclose(np.cross(e1, e2), n, atol=1e-12)


def test_thin_fold_does_not_fool_the_orientation_tree():
    """Two sheets 1.2 spacings apart joined by a half cylinder (a U): kNN edges cross the
    gap between anti-parallel normals (|n_i . n_j| = 1). The exact, consistent normals
    must pass the check, which needs the off-tangent-plane term of the tree weights."""
    h, gap = 0.05, 0.06
    x, y = np.meshgrid(np.arange(0, 2 + 1e-9, h), np.arange(0, 1 + 1e-9, h))
    bottom = np.c_[x.ravel(), y.ravel(), np.zeros(x.size)]
    top = bottom + [0.0, 0.0, gap]
    t, yc = np.meshgrid(np.linspace(-np.pi / 2, np.pi / 2, 5)[1:-1], np.arange(0, 1 + 1e-9, h))
    r = gap / 2
    bend = np.c_[2 + r * np.cos(t.ravel()), yc.ravel(), r + r * np.sin(t.ravel())]
    points = np.vstack([bottom, top, bend])
    normals = np.vstack([np.tile([0, 0, -1.0], (x.size, 1)), np.tile([0, 0, 1.0], (x.size, 1)),
                         np.c_[np.cos(t.ravel()), np.zeros(t.size), np.sin(t.ravel())]])
    graph = knn_graph(points, 8)
    crossing = np.einsum("ij,ikj->ik", normals, normals[graph.indices]) < 0
    assert crossing.sum() > 1000
    signs = consistent_signs(points, normals, graph.indices)
    assert np.all(signs == signs[0])


@pytest.mark.parametrize("steps,height,seed", [(6, 0.5, 5), (7, 0.3, 1)])
def test_orientation_tree_goes_around_poorly_fitted_normals(steps, height, seed):
    """pymeshlab's ridged fractal terrain (a height field, so the mesh's normals all face up)
    has knife-edge ridges under the sampling scale, where the kNN plane fits lie almost in the
    surface. Passing signs through them misoriented 306 of 4225 and 1755 of 16641 points;
    with the fits' predicted errors on the tree's edges they stay leaves."""
    from parambench.bench.frontend_isolation import vertex_normals
    from parambench.datasets_gen.real import pymeshlab_terrain
    from parambench.methods.pointset.normals import noise_adaptive_normals

    terrain = pymeshlab_terrain(steps, height, seed)
    points = terrain.points
    truth = vertex_normals(points, terrain.faces)
    assert np.all(truth[:, 2] > 0)  # a height field: one side is up
    graph = knn_graph(points, 8)
    fitted, _, fit_error = noise_adaptive_normals(points, graph.indices, return_error=True)
    oriented = orient_normals(points, fitted, graph.indices, fit_error)
    against = np.einsum("ij,ij->i", oriented, truth) < 0
    assert against.sum() <= 0.005 * len(points)


def test_local_spacing_of_a_square_grid_by_hand():
    """Interior points of a square grid of step a: 4 neighbours at a and 4 at a*sqrt(2),
    so the mean 8-NN distance (and its neighbourhood averages) is a (1 + sqrt 2) / 2; the
    edge's larger distances (one-sided neighbourhoods) reach one ring inwards per pass."""
    from parambench.methods.pointset.neighbourhoods import knn_graph, local_spacing

    a = 0.3
    g = np.stack(np.meshgrid(np.arange(30), np.arange(30)), -1).reshape(-1, 2) * a
    pts = np.column_stack([g, np.zeros(len(g))])
    graph = knn_graph(pts, 8)
    exact = a * (1 + np.sqrt(2)) / 2
    for passes, margin in ((1, 2.5), (3, 4.5)):
        h = local_spacing(graph, passes)
        deep = np.all((g > margin * a) & (g < (29 - margin) * a), axis=1)
        np.testing.assert_allclose(h[deep], exact, rtol=1e-9)
        assert h.max() > 1.1 * exact  # the corners


def test_balls_follow_local_density():
    """A plane sampled 4x denser (2x finer) on one half. With one global radius the
    sparse half's balls hold barely more than ball_k members (measured median 8, dense
    half 38); with radii from the local spacing (never below the global one) the sparse
    half's balls are full (median 26) and the area terms see the 2x spacing step."""
    from parambench.methods.pointset.frontend import build_frontend

    rng = np.random.default_rng(3)
    coarse = np.stack(np.meshgrid(np.arange(0, 40), np.arange(0, 40)), -1).reshape(-1, 2) * 0.1
    fine = np.stack(np.meshgrid(np.arange(0, 80), np.arange(0, 80)), -1).reshape(-1, 2) * 0.05 + [4.0, 0.0]
    xy = np.vstack([coarse, fine]) + rng.normal(scale=0.004, size=(len(coarse) + len(fine), 2))
    pts = np.column_stack([xy, 0.05 * np.sin(xy[:, 0])])
    sparse = np.all((xy > [0.8, 0.8]) & (xy < [3.0, 3.1]), axis=1)
    dense = np.all((xy > [5.0, 0.8]) & (xy < [7.2, 3.1]), axis=1)

    def facts(mode):
        fe = build_frontend(pts, spacing=mode)
        size = (fe.ball_indices >= 0).sum(axis=1)
        return np.median(size[sparse]), np.median(fe.local_spacing[sparse]) / np.median(fe.local_spacing[dense])

    sparse_global, step_global = facts("global")
    sparse_local, step_local = facts("local")
    assert sparse_global <= 10 and step_global == 1.0
    assert sparse_local >= 20
    assert 1.8 < step_local < 2.2


@pytest.mark.parametrize("workers", [1, 2])
def test_normals_do_not_depend_on_the_batching(monkeypatch, workers):
    # The batches run on worker threads: every row's numbers must be those of one batch
    # of all rows (bit for bit), whatever the batch size and the number of threads.
    import parambench.methods.pointset.normals as nm
    import numba

    rng = np.random.default_rng(5)
    pts = rng.normal(size=(503, 3)) * [1.0, 1.0, 0.1]
    graph = knn_graph(pts, 8)
    valid = rng.random(graph.indices.shape) < 0.8
    valid[:, :3] = True
    normals = orient_normals(pts, pca_normals(pts, graph.indices), graph.indices)

    def run():
        return (pca_normals(pts, graph.indices), *nm.pca_fit(pts, graph.indices, valid),
                *(smooth_normals(pts, normals, graph.indices, graph.distances, graph.mean_spacing, method=m)
                  for m in ("linear", "average")))

    monkeypatch.setattr(nm, "_PCA_CHUNK", 10**6)
    whole = run()
    monkeypatch.setattr(numba.config, "NUMBA_NUM_THREADS", workers)
    monkeypatch.setattr(nm, "_PCA_CHUNK", 37)
    for a, b in zip(whole, run()):
        assert np.array_equal(a, b)


@pytest.mark.parametrize("workers", [1, 2])
def test_spacing_and_noise_level_do_not_depend_on_the_batching(monkeypatch, workers):
    import numba

    import parambench.methods.pointset.neighbourhoods as nbm
    import parambench.methods.pointset.surface_neighbours as snm
    from parambench.methods.pointset.neighbourhoods import local_spacing

    rng = np.random.default_rng(11)
    pts = rng.normal(size=(401, 3)) * [1.0, 1.0, 0.05]
    graph = knn_graph(pts, 8)
    normals = pca_normals(pts, graph.indices)
    monkeypatch.setattr(nbm, "_SPACING_CHUNK", 10**6)
    monkeypatch.setattr(snm, "_NOISE_CHUNK", 10**6)
    whole = local_spacing(graph, 10), snm._noise_level(pts, graph.indices, normals)
    # The numpy expressions on all rows at once, as before the batching.
    h = graph.distances.mean(axis=1)
    for _ in range(10):
        h = (h + h[graph.indices].sum(axis=1)) / 9
    d = pts[graph.indices[:, :6]] - pts[:, None, :]
    noise = 3.0 * 1.4826 * float(np.median(np.abs(np.einsum("nki,ni->nk", d, normals))))
    assert np.array_equal(whole[0], h) and whole[1] == noise
    monkeypatch.setattr(numba.config, "NUMBA_NUM_THREADS", workers)
    monkeypatch.setattr(nbm, "_SPACING_CHUNK", 50)  # the last batch has one row
    monkeypatch.setattr(snm, "_NOISE_CHUNK", 50)
    assert np.array_equal(local_spacing(graph, 10), h)
    assert snm._noise_level(pts, graph.indices, normals) == noise


@pytest.mark.parametrize("parts", [1, 2, 3, 5])
def test_stable_order_is_numpys_stable_argsort(monkeypatch, parts):
    from parambench.methods.pointset import normals

    monkeypatch.setattr(normals, "worker_count", lambda: parts)
    keys = np.random.default_rng(parts).integers(0, 7, 1001).astype(np.float64)  # many ties
    np.testing.assert_array_equal(normals._stable_order(keys), np.argsort(keys, kind="stable"))
    keys = np.random.default_rng(parts).random(999)
    np.testing.assert_array_equal(normals._stable_order(keys), np.argsort(keys, kind="stable"))
    # long runs of one key (a flat region's edges all weigh the floor 1e-9)
    keys = np.where(np.random.default_rng(parts).random(5003) < 0.7, 1e-9, np.random.default_rng(9).random(5003))
    np.testing.assert_array_equal(normals._stable_order(keys), np.argsort(keys, kind="stable"))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_spanning_forest_is_scipys_tree(seed):
    """The compiled Kruskal keeps exactly scipy's entries, ties included, on one or several components."""
    from parambench.methods.pointset.normals import _spanning_forest_scipy, spanning_forest

    rng = np.random.default_rng(seed)
    n, k = 3000, 4
    # two blocks of points never joined (a forest), columns distinct and sorted per row
    cols = np.sort(np.stack([rng.choice(n // 2, k, replace=False) for _ in range(n)]), axis=1)
    cols[n // 2:] += n // 2
    weights = rng.integers(1, 5, n * k).astype(np.float64) * 0.25  # heavy ties
    got = spanning_forest(cols.ravel(), weights, k)
    want = _spanning_forest_scipy(cols.ravel(), weights, k)
    for a, b in zip(got, want):
        np.testing.assert_array_equal(a, b)
    bad = weights.copy()
    bad[0] = np.nan  # not positive and finite: scipy's path
    for a, b in zip(spanning_forest(cols.ravel(), bad, k), _spanning_forest_scipy(cols.ravel(), bad, k)):
        np.testing.assert_array_equal(a, b)


def test_spanning_forest_leaves_out_later_twins_as_scipy_rejects_them():
    """A kNN graph with symmetric, heavily tied weights: both directions of mutual edges, scipy's tree."""
    from parambench.methods.pointset.normals import _first_of_twins, _spanning_forest_scipy, spanning_forest

    pts = np.c_[np.random.default_rng(5).uniform(size=(2000, 2)), np.zeros(2000)]
    graph = knn_graph(pts, 6)
    cols = np.sort(graph.indices, axis=1).ravel()
    rows = np.repeat(np.arange(2000), 6)
    weights = np.round(np.linalg.norm(pts[rows] - pts[cols], axis=1) * 40) + 1.0  # the same both ways
    first = np.empty(cols.size, dtype=np.bool_)
    _first_of_twins(cols, weights, 6, first)
    assert 0 < (~first).sum() < cols.size // 2 and (cols[~first] < rows[~first]).all()
    for a, b in zip(spanning_forest(cols, weights, 6), _spanning_forest_scipy(cols, weights, 6)):
        np.testing.assert_array_equal(a, b)
