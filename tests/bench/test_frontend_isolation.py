"""The ground-truth substitution diagnostic of bench/frontend_isolation.py, on a small clean surface."""

import numpy as np
import pytest

from parambench.bench import frontend_isolation as iso
from parambench.datasets_gen.registry import make_surface
from parambench.methods.pointset import frontend


def _surface():
    return make_surface("bump", 600, sampling="jittered", seed=0)


def test_mesh_ring_knn_stays_within_its_rings():
    s = _surface()
    adj = iso.mesh_adjacency(s.n_points, s.faces)
    g = iso.mesh_ring_knn(s.points, adj, 8, rings=3)
    rows = np.repeat(np.arange(s.n_points), 8)
    hops = iso.ring_distance(adj, rows, g.indices.ravel(), 4)
    assert hops.min() >= 1 and hops.max() <= 3
    assert np.all(np.diff(g.distances, axis=1) >= 0)


def test_true_loops_are_oriented_along_the_faces():
    s = _surface()
    loop = iso.oriented_loops(s.faces, [np.asarray(s.boundary_loops[0])[::-1]])[0]
    edges = {tuple(e) for e in np.concatenate([s.faces[:, [0, 1]], s.faces[:, [1, 2]], s.faces[:, [2, 0]]]).tolist()}
    assert all((int(a), int(b)) in edges for a, b in zip(loop, np.roll(loop, -1)))


def test_isolation_on_a_clean_surface_has_no_bridges_or_folds_and_restores_the_front_end():
    s = _surface()
    saved = frontend.knn_graph, frontend.check_user_normals
    ctx = {}
    plain = iso.isolate(s, context=ctx)
    truth = iso.isolate(s, true_normals=True, true_loops=True, mesh_neighbours=True, context=ctx)
    assert (frontend.knn_graph, frontend.check_user_normals) == saved
    assert len(ctx["bridges"]) == 0
    for r in (plain, truth):
        assert r["foldovers"] == 0 and r["n_loops"] == 1 and r["recall"] > 0.95
        assert sum(r["folds_near"].values()) == 0
    assert truth["normal_error_deg"]["all"] < 1e-6 and truth["normal_sign_flips"] == 0
    assert plain["qc_mean"] < 1.1 and truth["qc_mean"] < 1.1


def test_a_given_graph_is_the_same_as_the_mesh_neighbours_option_and_pruning_patches_are_undone():
    from parambench.methods.pointset import surface_neighbours as sn

    s = _surface()
    ctx = {}
    by_option = iso.isolate(s, mesh_neighbours=True, context=ctx)
    graph = iso.mesh_ring_knn(s.points, ctx["adjacency"], 8, rings=3)
    by_graph = iso.isolate(s, graph=graph, context=ctx)
    assert np.array_equal(by_option["uv"], by_graph["uv"])
    saved = sn.pca_normals, sn.consistent_signs
    pruned = iso.pruned_with_true_normals(s)
    assert (sn.pca_normals, sn.consistent_signs) == saved
    assert pruned.indices.shape == (s.n_points, 8)


def test_errors_of_the_isolated_pipeline_name_only_ocp_parameters():
    """bunny10k with its true loops: every hole turns inside out, the k search gives up."""
    from parambench.datasets_gen.errors import ConvergenceError

    with pytest.raises(ConvergenceError) as err:
        iso.isolate(make_surface("real/bunny10k"), true_loops=True)
    assert "normalized" not in str(err.value) and "k_search='direct'" in str(err.value)


def test_truth_cut_graph_leaves_no_edge_across_the_fold_and_keeps_a_gapless_surface_euclidean():
    from parambench.methods.pointset.neighbourhoods import knn_graph

    fold = make_surface("fold", 600, sampling="jittered", seed=0, noise=0.5)
    adj = iso.mesh_adjacency(fold.n_points, fold.faces)
    rows = np.repeat(np.arange(fold.n_points), 8)
    plain = knn_graph(fold.points, 8)
    assert (iso.ring_distance(adj, rows, plain.indices.ravel(), 6) > 6).sum() > 0  # the noise bridges the gap
    cut = iso.truth_cut_knn(fold.points, adj, 8, rings=6)
    assert (iso.ring_distance(adj, rows, cut.indices.ravel(), 6) > 6).sum() == 0
    assert np.all(np.diff(cut.distances, axis=1) >= 0)
    s = _surface()
    same = iso.truth_cut_knn(s.points, iso.mesh_adjacency(s.n_points, s.faces), 8, rings=6)
    assert np.array_equal(same.indices, knn_graph(s.points, 8).indices)


def test_closer_elsewhere_counts_points_the_noise_carried_past_the_middle_of_the_gap():
    def count(name, noise):
        noisy = make_surface(name, 600, sampling="jittered", seed=0, noise=noise)
        clean = make_surface(name, 600, sampling="jittered", seed=0, noise=0.0)
        return iso.closer_elsewhere(noisy.points, clean.points, noisy.faces).size

    assert count("fold", 0.5) > 0
    assert count("fold", 0.25) == 0 and count("bump", 0.5) == 0
    clean = make_surface("fold", 600, sampling="jittered", seed=0)
    assert iso.closer_elsewhere(clean.points, clean.points, clean.faces).size == 0


def test_surface_normals_as_the_truth_of_a_noisy_sampling():
    s = make_surface("bump", 600, sampling="jittered", seed=0, noise=0.5)
    ctx = {}
    out = iso.isolate(s, true_normals=True, normals_truth="surface", context=ctx)
    assert out["normal_error_deg"]["all"] < 1e-6 and out["normal_sign_flips"] == 0
    mesh_truth = iso.isolate(s, true_normals=True, context=ctx)  # the noisy mesh's own vertex normals
    assert mesh_truth["normal_error_deg"]["all"] < 1e-6
    with pytest.raises(ValueError):
        iso.isolate(s, normals_truth="exact", context=ctx)
