"""The stages of dem_balls on their own: option and centre checks, kernel inputs, the kernel, blocks, assembly."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from parambench.datasets_gen.errors import InvalidInputError
from parambench.methods.pointset import dem
from parambench.methods.pointset.dem import (_assemble, _BallBlock, _BallRule, _centre_ids, _check_options, _copy_rows,
                                  _dem_range, _graph_cloud, _heap_capacity, _put_row, _scratch, _store_for,
                                  dem_balls)
from parambench.methods.pointset.neighbourhoods import knn_graph, symmetric_adjacency
from parambench.methods.pointset.normals import orient_normals, pca_normals


def test_check_options():
    _check_options("plain", "length", 1, 1, 0.0)
    for args, match in [(("exact", "midpoint", 6, 64, 2.5), "dem must be"),
                        (("upwind", "normal", 6, 64, 2.5), "projection must be"),
                        (("upwind", "midpoint", 0, 64, 2.5), "ball_k"),
                        (("upwind", "midpoint", 6, 5, 2.5), "ball_k"),
                        (("upwind", "midpoint", 6, 64, -1.0), "ball_eps_factor")]:
        with pytest.raises(InvalidInputError, match=match):
            _check_options(*args)


def test_centre_ids():
    np.testing.assert_array_equal(_centre_ids(None, 4), np.arange(4))
    ids = _centre_ids(np.array([[3], [0], [3]], dtype=np.int32), 4)
    assert ids.dtype == np.int64 and ids.flags.c_contiguous and ids.tolist() == [3, 0, 3]
    assert _centre_ids([], 4).size == 0
    for bad in ([4], [-1]):
        with pytest.raises(InvalidInputError, match=r"\[0, 3\]"):
            _centre_ids(bad, 4)


def _path(n=6, step=1.0):
    """n points on the x axis, spaced ``step``, normals +z, joined in a path graph."""
    points = np.c_[step * np.arange(n), np.zeros(n), np.zeros(n)]
    normals = np.tile([0.0, 0.0, 1.0], (n, 1))
    i = np.arange(n - 1)
    adj = sp.coo_matrix((np.full(n - 1, step), (i, i + 1)), shape=(n, n))
    return points, normals, (adj + adj.T).tocsr()


def test_graph_cloud_gives_kernel_types():
    points, normals, adj = _path()
    cloud = _graph_cloud(points, normals.astype(np.float32), adj.tocoo())
    assert cloud.indptr.dtype == cloud.nbrs.dtype == np.int64 and cloud.normals.dtype == np.float64
    np.testing.assert_array_equal(cloud.lens, adj.data)
    assert np.allclose(np.einsum("ij,ij->i", cloud.e1, cloud.normals), 0)
    assert np.allclose(np.einsum("ij,ij->i", cloud.e2, cloud.normals), 0)
    assert np.allclose(np.einsum("ij,ij->i", cloud.e1, cloud.e2), 0)


@pytest.mark.parametrize("midpoint", [True, False])
def test_edge_chords_then_rotation_equal_the_transport(midpoint):
    """The kernel's upwind average reads each edge's chord from the table built once
    (``_graph_cloud``) and only rotates it to the centre: bit for bit the transport
    computed from the points and normals, on either projection, at any worker count."""
    rng = np.random.default_rng(3)
    points = rng.normal(size=(40, 3))
    normals = rng.normal(size=(40, 3)) + [0.0, 0.0, 3.0]
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    adj = symmetric_adjacency(knn_graph(points, 6))
    one = _graph_cloud(points, normals, adj, midpoint=midpoint, workers=1)
    two = _graph_cloud(points, normals, adj, midpoint=midpoint, workers=2)
    np.testing.assert_array_equal(one.chords, two.chords)
    assert one.chords.shape == (one.nbrs.size, 6)
    for s in (0, 17):
        for v in range(points.shape[0]):
            for e in range(one.indptr[v], one.indptr[v + 1]):
                want = dem._transport(one.points, one.normals, one.nbrs[e], v, one.normals[s], one.e1[s], one.e2[s],
                                      midpoint)
                assert dem._rotate_to(*one.chords[e], one.normals[s], one.e1[s], one.e2[s]) == want
    assert _graph_cloud(points, normals, adj, upwind=False).chords.shape == (0, 6)  # the plain DEM needs none


def test_heap_capacity_follows_the_largest_degree():
    _, _, adj = _path()  # degrees 1 and 2
    star = sp.csr_matrix(np.r_[[np.r_[0, np.ones(5)]], np.c_[np.ones(5), np.zeros((5, 5))]])  # degree 5
    assert _heap_capacity(adj.indptr, 4) == 6 * 2 + 1
    assert _heap_capacity(star.indptr, 4) == 6 * 5 + 1


@pytest.mark.parametrize("upwind", [True, False])
def test_kernel_on_a_straight_path_gives_signed_arc_length(upwind):
    points, normals, adj = _path(step=0.5)
    cloud = _graph_cloud(points, normals, adj)
    n = len(points)
    rule = _BallRule(ball_k=1, radii=np.full(n, 1.1), max_ball=4, upwind=upwind, w_eps=1e-6 * 0.25,
                     midpoint=True, front_weight=True)
    centres = np.array([2, 0, 2], dtype=np.int64)  # a repeated centre: stamps must still separate rows
    out = _BallBlock(idx=np.full((3, 4), -1, dtype=np.int64), uv=np.zeros((3, 4, 2)),
                     dist=np.full((3, 4), np.inf), size=np.zeros(3, dtype=np.int64))
    spill = _BallBlock(idx=np.empty((3, 4), dtype=np.int64), uv=np.empty((3, 4, 2)), dist=np.empty((3, 4)),
                       size=out.size)
    work = _scratch(1, n, _heap_capacity(cloud.indptr, rule.max_ball), rule.max_ball)[0]
    assert _dem_range(centres, 0, 3, cloud, rule, out, spill, 0, work) == 0
    assert out.size.tolist() == [4, 2, 4]
    # Ties in distance pop in either order; compare as sets keyed by the member.
    for row, c in enumerate(centres):
        members = out.idx[row, : out.size[row]]
        assert sorted(members.tolist()) == sorted(v for v in range(n) if 0 < abs(v - c) * 0.5 <= 1.1)
        np.testing.assert_allclose(out.dist[row, : out.size[row]], 0.5 * np.abs(members - c))
        # a straight line is its own tangent plane: T_s p = (p - s) in the frame of s
        offset = points[members] - points[c]
        want = np.c_[offset @ cloud.e1[c], offset @ cloud.e2[c]]
        np.testing.assert_allclose(out.uv[row, : out.size[row]], want, atol=1e-12)
    np.testing.assert_array_equal(out.uv[0], out.uv[2])


def test_kernel_counts_truncated_balls():
    points, normals, adj = _path()
    cloud = _graph_cloud(points, normals, adj)
    rule = _BallRule(ball_k=1, radii=np.full(6, 10.0), max_ball=2, upwind=True, w_eps=1e-6, midpoint=True,
                     front_weight=True)
    out = _BallBlock(idx=np.full((2, 2), -1, dtype=np.int64), uv=np.zeros((2, 2, 2)), dist=np.full((2, 2), np.inf),
                     size=np.zeros(2, dtype=np.int64))
    spill = out._replace(idx=np.empty((2, 2), dtype=np.int64))
    work = _scratch(1, 6, _heap_capacity(cloud.indptr, 2), 2)[0]
    # centre 0 reaches 5 points within the radius, centre 5 also: both cut at 2
    assert _dem_range(np.array([0, 5]), 0, 2, cloud, rule, out, spill, 0, work) == 2
    assert out.idx.tolist() == [[1, 2], [4, 3]]


def _block(idx, uv, dist):
    return _BallBlock(idx=np.array(idx, dtype=np.int64), uv=np.array(uv, dtype=np.float64),
                      dist=np.array(dist, dtype=np.float64), size=(np.array(idx) >= 0).sum(axis=1))


def test_kernel_spills_balls_wider_than_the_store():
    points, normals, adj = _path(step=0.5)
    cloud = _graph_cloud(points, normals, adj)
    rule = _BallRule(ball_k=1, radii=np.full(6, 1.1), max_ball=4, upwind=True, w_eps=1e-6 * 0.25, midpoint=True,
                     front_weight=True)
    sizes = np.zeros(2, dtype=np.int64)
    store = _BallBlock(idx=np.full((2, 3), 7, dtype=np.int64), uv=np.full((2, 3, 2), 7.0), dist=np.full((2, 3), 7.0),
                       size=sizes)
    spill = _BallBlock(idx=np.full((1, 4), 9, dtype=np.int64), uv=np.zeros((1, 4, 2)), dist=np.zeros((1, 4)),
                       size=sizes)
    work = _scratch(1, 6, _heap_capacity(cloud.indptr, 4), 4)[0]
    # centre 0 has 2 members (fits the 3 columns: padded), centre 2 has 4 (spilled to row 2 - 1 of spill)
    _dem_range(np.array([0, 2]), 0, 2, cloud, rule, store, spill, 1, work)
    assert sizes.tolist() == [2, 4]
    assert store.idx[0].tolist() == [1, 2, -1] and store.dist[0, 2] == np.inf and store.uv[0, 2].tolist() == [0, 0]
    assert store.idx[1].tolist() == [7, 7, 7]  # untouched
    assert sorted(spill.idx[0].tolist()) == [0, 1, 3, 4]


def _block(idx, uv, dist, sizes):
    return _BallBlock(idx=np.array(idx, dtype=np.int64), uv=np.array(uv, dtype=np.float64),
                      dist=np.array(dist, dtype=np.float64), size=sizes)


def test_blocks_are_copied_padded_widened_and_narrowed_to_the_widest_ball():
    sizes = np.zeros(3, dtype=np.int64)
    empty = _store_for(None, 0, 0, sizes, max_ball=64)
    assert empty.idx.shape == (3, 0)  # the first block's balls all spill
    first = _block([[4, 7, 9]], np.ones((1, 3, 2)), [[1.0, 2.0, 9.0]], sizes)
    sizes[0] = 2  # column 2 is stale data beyond the ball: not copied
    store = _store_for(empty, 2, 0, sizes, max_ball=64)
    assert store.idx.shape[1] == 2 + 4  # the first block's width plus the margin
    _copy_rows(empty, first, store, 0, 0, 1)
    # second block: row 1 fits the store (the kernel wrote it there), row 2 is 7 wide and spilled
    sizes[1:] = [1, 7]
    _put_row(store.idx, store.uv, store.dist, 1, np.array([5]), 2 * np.ones((1, 2)), np.array([3.0]), 1, 6)
    second = _block([[-1] * 8, [6, 8, 10, 11, 12, 13, 14, -1]], 2 * np.ones((2, 8, 2)),
                    [[0.0] * 8, [4.0, 5.0, 6.0, 6.0, 6.0, 6.0, 6.0, 0.0]], sizes)
    assert _store_for(store, 6, 1, sizes, 64) is store
    wide = _store_for(store, 7, 1, sizes, max_ball=8)  # wider than the store: rows so far copied over
    assert wide.idx.shape[1] == 8
    assert wide.idx[0].tolist() == [4, 7] + [-1] * 6
    _copy_rows(store, second, wide, 1, 0, 2)
    idx, coords, gdist = _assemble(wide, sizes)
    assert idx.tolist() == [[4, 7] + [-1] * 5, [5] + [-1] * 6, [6, 8, 10, 11, 12, 13, 14]]
    assert coords[:, :3, 0].tolist() == [[1, 1, 0], [2, 0, 0], [2, 2, 2]]
    assert gdist[:, :3].tolist() == [[1, 2, np.inf], [3, np.inf, np.inf], [4, 5, 6]]
    assert idx.flags.c_contiguous and coords.flags.c_contiguous and gdist.flags.c_contiguous
    empty_sizes = np.zeros(0, dtype=np.int64)
    empty = _assemble(_store_for(None, 0, 0, empty_sizes, 64), empty_sizes)
    assert [a.shape for a in empty] == [(0, 0), (0, 0, 2), (0, 0)]


@pytest.mark.parametrize("margin", [0.25, 0.0])
def test_small_blocks_give_the_same_balls(make_cap, monkeypatch, margin):
    """Many blocks of different widths (run_blocks + assemble, the store widened) match one block bit for bit."""
    patch = make_cap(1.0, 1.0, 20, "jittered")
    graph = knn_graph(patch.points, 8)
    adj = symmetric_adjacency(graph)
    normals = orient_normals(patch.points, pca_normals(patch.points, graph.indices), graph.indices)
    one = dem_balls(patch.points, normals, adj, graph.mean_spacing, ball_eps_factor=2.0)
    monkeypatch.setattr(dem, "_BLOCK", 7)
    monkeypatch.setattr(dem, "_WIDTH_MARGIN", margin)  # fewer spare columns: more blocks widen
    many = dem_balls(patch.points, normals, adj, graph.mean_spacing, ball_eps_factor=2.0)
    assert one.n_truncated == many.n_truncated
    for f in ("indices", "coords", "sizes", "graph_dist"):
        np.testing.assert_array_equal(getattr(one, f), getattr(many, f))


@pytest.mark.parametrize("workers,pieces", [(1, 1), (2, 1), (2, 8), (3, 5)])
def test_pieces_shared_out_to_workers_give_the_same_balls(make_cap, monkeypatch, workers, pieces):
    """Any split of the centres between workers (scratch borrowed per piece) matches one worker bit for bit."""
    import numba

    patch = make_cap(1.0, 1.0, 20, "jittered")
    graph = knn_graph(patch.points, 8)
    adj = symmetric_adjacency(graph)
    normals = orient_normals(patch.points, pca_normals(patch.points, graph.indices), graph.indices)
    monkeypatch.setattr(numba.config, "NUMBA_NUM_THREADS", 1)
    one = dem_balls(patch.points, normals, adj, graph.mean_spacing, ball_eps_factor=2.0)
    monkeypatch.setattr(numba.config, "NUMBA_NUM_THREADS", workers)
    monkeypatch.setattr(dem, "_PIECES_PER_WORKER", pieces)
    monkeypatch.setattr(dem, "_BLOCK", 50)
    many = dem_balls(patch.points, normals, adj, graph.mean_spacing, ball_eps_factor=2.0)
    assert one.n_truncated == many.n_truncated
    for f in ("indices", "coords", "sizes", "graph_dist"):
        np.testing.assert_array_equal(getattr(one, f), getattr(many, f))
