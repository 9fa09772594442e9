"""The two-plane gap test of bench/sheet_split.py (a diagnostic of fold under noise, issue 11)."""

import numpy as np

from parambench.bench import frontend_isolation as iso
from parambench.bench import sheet_split
from parambench.datasets_gen.registry import make_surface
from parambench.methods.pointset.neighbourhoods import knn_graph


def _across(surface, graph, rings=6):
    adj = iso.mesh_adjacency(surface.n_points, surface.faces)
    rows = np.repeat(np.arange(surface.n_points), graph.indices.shape[1])
    return int((iso.ring_distance(adj, rows, graph.indices.ravel(), rings) > rings).sum())


def test_two_parallel_planes_split_two_noisy_sheets_and_not_one():
    """Jittered unit-spacing sheets: two 2.25 apart (noise 0.25), or one alone (noise 0.5)."""
    rng = np.random.default_rng(0)
    g = np.stack(np.meshgrid(np.arange(-8.0, 8.5), np.arange(-8.0, 8.5)), axis=-1).reshape(-1, 2)

    def sheet(z, sigma):
        xy = g + rng.uniform(-0.3, 0.3, g.shape)
        return np.column_stack([xy, z + sigma * rng.standard_normal(len(g))])

    one = sheet(0.0, 0.5)
    two = np.concatenate([sheet(0.0, 0.25), sheet(2.25, 0.25)])
    for pts, expect_two in ((one, False), (two, True)):
        ratio, _, normal, _ = sheet_split.two_plane_models(pts, knn_graph(pts, 64).indices)
        centre = np.argmin(np.linalg.norm(pts[:, :2], axis=1))  # far from the patch's edges
        assert (ratio[centre] > sheet_split.MIN_RATIO) == expect_two
        assert abs(normal[centre, 2]) > 0.98  # the sheets' normal, not tilted by their distance


def test_confirmed_sheet_graph_cuts_the_noisy_fold_and_leaves_one_noisy_sheet_euclidean():
    fold = make_surface("fold", 2000, sampling="jittered", seed=0, noise=0.25)
    plain = knn_graph(fold.points, 8)
    graph, n_cut = sheet_split.confirmed_sheet_graph(fold.points, 8)
    assert _across(fold, plain) > 100 and n_cut > 0
    assert _across(fold, graph) == 0
    bump = make_surface("bump", 2000, sampling="jittered", seed=0, noise=0.5)
    graph, n_cut = sheet_split.confirmed_sheet_graph(bump.points, 8)
    assert n_cut == 0 and np.array_equal(graph.indices, knn_graph(bump.points, 8).indices)
