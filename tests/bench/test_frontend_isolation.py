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
