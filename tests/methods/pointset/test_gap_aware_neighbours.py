"""The default neighbour graph (``neighbours="auto"``): pruned where a gap is, Euclidean elsewhere."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from parambench.bench.metrics import evaluate
from parambench.datasets_gen.registry import make_surface
from parambench.methods.pointset.frontend import build_frontend
from parambench.methods.pointset.neighbourhoods import far_along_graph, knn_graph, symmetric_adjacency
from parambench.methods.pointset.params import FrontEndParams
from parambench.methods.pointset.surface_neighbours import gap_aware_knn_graph, pruned_knn_graph
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


@pytest.mark.parametrize("sampling", ["graded", "random"])
def test_a_gap_switches_to_the_pruned_graph(sampling):
    s = make_surface("fold", 2000, sampling=sampling, seed=0)
    graph, diag = gap_aware_knn_graph(s.points, 8)
    pruned, _ = pruned_knn_graph(s.points, 8)
    assert diag["pruned"] and diag["n_gap_edges"] > 0
    assert np.array_equal(graph.indices, pruned.indices)
    # the gap edges really are long on the surface: the fold is developable, so the
    # distance on it is the distance of the exact map; across the gap it is > 2x the chord
    plain = knn_graph(s.points, 8)
    adj = symmetric_adjacency(plain).tocoo()
    on_surface = np.linalg.norm(s.exact_uv[adj.row] - s.exact_uv[adj.col], axis=1)
    assert np.count_nonzero(on_surface > 2.0 * adj.data) > 0


def test_default_ocp_on_a_graded_fold_has_no_foldovers():
    # Sheets 2-2.5 nominal spacings apart, sampled ~1 local spacing apart where the graded
    # density is low: the Euclidean neighbours bridge them (158 foldovers, QC 244x before
    # neighbours="auto"); the default now gives the pruned graph's map.
    s = make_surface("fold", 2000, sampling="graded", seed=0)
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
