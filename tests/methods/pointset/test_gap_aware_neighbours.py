"""The default neighbour graph (``neighbours="auto"``): gap edges cut where a gap is, Euclidean elsewhere."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from parambench.bench.metrics import evaluate
from parambench.datasets_gen.registry import make_surface
from parambench.methods.pointset.frontend import build_frontend
from parambench.methods.pointset.neighbourhoods import far_along_graph, knn_graph, symmetric_adjacency
from parambench.methods.pointset.params import FrontEndParams
from parambench.methods.pointset.normals import pca_normals
from parambench.methods.pointset.surface_neighbours import _fitted_normals, gap_aware_knn_graph, pruned_knn_graph
from parambench.methods.registry import get_method


def _path_graph(n: int) -> sp.csr_matrix:
    i = np.arange(n - 1)
    a = sp.csr_matrix((np.ones(n - 1), (i, i + 1)), shape=(n, n))
    return (a + a.T).tocsr()


def test_far_along_graph_counts_hops_by_hand():
    adj = _path_graph(10)
    rows = np.array([0, 0, 0, 3, 9, 5])
    cols = np.array([3, 4, 5, 7, 2, 5])
    # 3 and 4 hops are within reach, 5 and 7 hops are not; a point reaches itself
    assert far_along_graph(adj, rows, cols, 4).tolist() == [False, False, True, False, True, False]
    assert far_along_graph(adj, np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64), 4).size == 0


def test_default_is_auto():
    assert FrontEndParams().neighbours == "auto"


@pytest.mark.parametrize("name,sampling", [("protrusions", "random"), ("bump", "random"), ("plane", "graded")])
def test_no_gap_keeps_the_euclidean_graph(name, sampling):
    # protrusions/random: the pruning alone drops edges at the fingertips (curvature at the
    # sample scale), but each has a short detour, so no gap is found
    s = make_surface(name, 2000, sampling=sampling, seed=0)
    graph, diag = gap_aware_knn_graph(s.points, 8)
    plain = knn_graph(s.points, 8)
    assert not diag["pruned"] and diag["n_gap_edges"] == 0
    assert np.array_equal(graph.indices, plain.indices) and np.array_equal(graph.distances, plain.distances)
    if name == "protrusions":
        assert pruned_knn_graph(s.points, 8)[1]["n_dropped_edges"] > 0


def _cross_sheet_edges(surface, graph):
    """Undirected edges whose ends are more than twice as far apart on the fold as in space.

    The fold is developable and its unrolled domain convex, so the distance on the
    surface is that of the exact uv coordinates; a chord across the U bend has ratio at
    most pi / 2, an edge across the gap between the flat sheets at least 2.
    """
    adj = symmetric_adjacency(graph).tocoo()
    on_surface = np.linalg.norm(surface.exact_uv[adj.row] - surface.exact_uv[adj.col], axis=1)
    return int(np.count_nonzero(on_surface > 2.0 * adj.data)) // 2


@pytest.mark.parametrize("sampling", ["graded", "random"])
def test_a_gap_cuts_every_edge_across_the_fold(sampling):
    s = make_surface("fold", 2000, sampling=sampling, seed=0)
    assert _cross_sheet_edges(s, knn_graph(s.points, 8)) > 10  # the Euclidean graph bridges the sheets
    graph, diag = gap_aware_knn_graph(s.points, 8)
    assert diag["pruned"] and diag["n_gap_edges"] > 0 and diag["n_cut_edges"] > 0
    assert _cross_sheet_edges(s, graph) == 0
    assert np.all(np.diff(graph.distances, axis=1) >= 0) and np.all(graph.indices != np.arange(s.n_points)[:, None])
    assert connected_components(symmetric_adjacency(graph), directed=False)[0] == 1
    if sampling == "random":
        # the plain pruning keeps edges between the sheets' free edges (normals fitted
        # across the gap there): the reason for the second pruning with borrowed normals
        assert _cross_sheet_edges(s, pruned_knn_graph(s.points, 8)[0]) > 0


def test_borrowed_normals_replace_only_poor_fits():
    rng = np.random.default_rng(0)
    # a jittered planar grid z = 0 and, over its corner, a 3 x 3 patch of a second sheet
    # 0.8 spacings above: points next to the patch fit planes across the gap
    xy = np.stack(np.meshgrid(np.arange(12.0), np.arange(12.0)), axis=-1).reshape(-1, 2)
    xy += rng.uniform(-0.2, 0.2, xy.shape)
    plane = np.column_stack([xy, np.zeros(len(xy))])
    corner = np.all(xy < 2.5, axis=1)
    pts = np.concatenate([plane, plane[corner] + [0.5, 0.5, 0.8]])
    idx = knn_graph(pts, 6).indices
    own = pca_normals(pts, idx)
    assert np.array_equal(_fitted_normals(pts, idx, None), own)
    borrowed = _fitted_normals(pts, idx, 5.0)
    changed = np.flatnonzero(np.any(borrowed != own, axis=1))
    assert changed.size > 0
    # every borrowed normal is a better fit's: nearer a sheet's normal (z) than its own
    assert np.all(np.abs(borrowed[changed, 2]) > np.abs(own[changed, 2]))
    # points of the plane away from the patch keep their own normal
    away = np.flatnonzero(np.linalg.norm(xy - 1.0, axis=1) > 5.0)
    assert not np.isin(away, changed).any()


@pytest.mark.parametrize("sampling", ["graded", "random"])
def test_default_ocp_on_a_fold_has_no_foldovers(sampling):
    # Sheets 2-2.5 nominal spacings apart (graded: ~1 local spacing where the density is
    # low). Before neighbours="auto": graded 158 foldovers, QC 244x scp-igl's; random a
    # ConvergenceError (two loops for one), also with neighbours="pruned".
    s = make_surface("fold", 2000, sampling=sampling, seed=0)
    given = s.method_input(False)
    base = evaluate(s.points, s.faces, get_method("scp-igl")(s).uv, boundary_loops=s.boundary_loops,
                    diameter=s.diameter)
    res = get_method("ocp")(given)
    q = evaluate(s.points, s.faces, res.uv, boundary_loops=s.boundary_loops, diameter=s.diameter)
    assert q["foldovers"] == 0 and q["qc_mean"] < 1.03 * base["qc_mean"]
    assert res.diagnostics["selfcheck"]["passed"]
    assert len(res.diagnostics["boundary_loops"]) == 1


def test_frontend_reports_the_choice():
    s = make_surface("fold", 2000, sampling="graded", seed=0)
    fe = build_frontend(s.points)
    assert fe.params["neighbours"] == "auto"
    nbr = fe.diagnostics["neighbours"]
    assert nbr["mode"] == "auto" and nbr["pruned"] and nbr["n_gap_edges"] > 0
    flat = build_frontend(make_surface("bump", 1000, sampling="random", seed=1).points)
    assert flat.diagnostics["neighbours"]["pruned"] is False


def test_the_screen_flags_a_gap_and_spares_a_surface_without_one(monkeypatch):
    """The cheap screen on the front end's own normals: the gap-aware graph only where it may matter."""
    import parambench.methods.pointset.frontend as frontend

    fold = build_frontend(make_surface("fold", 2000, sampling="random", seed=0).points)
    assert fold.diagnostics["neighbours"]["screen_suspects"] > 0 and fold.diagnostics["neighbours"]["pruned"]

    def refuse(*args, **kwargs):
        raise AssertionError("the gap-aware graph was built on a surface without a gap")

    monkeypatch.setattr(frontend, "gap_aware_knn_graph", refuse)
    bump = make_surface("bump", 2000, sampling="random", seed=0).points
    screened = build_frontend(bump)
    plain = build_frontend(bump, neighbours="euclidean")
    assert screened.diagnostics["neighbours"]["screen_suspects"] == 0
    np.testing.assert_array_equal(screened.ball_indices, plain.ball_indices)
