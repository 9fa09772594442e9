"""The stages of find_boundary on their own: the pruned boundary walk and the loop filter."""

from __future__ import annotations

import numpy as np

from parambench.datasets_gen.registry import make_surface
from parambench.methods.pointset.boundary import _true_loops, _walk_pruned, angular_gaps, find_boundary
from parambench.methods.pointset.dem import dem_balls
from parambench.methods.pointset.neighbourhoods import knn_graph, symmetric_adjacency
from parambench.methods.pointset.normals import orient_normals, pca_normals, tangent_frames


def _circle(n, radius=1.0, centre=(0.0, 0.0)):
    t = 2 * np.pi * np.arange(n) / n
    return np.c_[centre[0] + radius * np.cos(t), centre[1] + radius * np.sin(t), np.zeros(n)]


def test_true_loops_drops_small_short_and_void_rings_in_order():
    big = _circle(40)  # perimeter ~6.28, spacing ~0.157
    tiny = _circle(10, 0.02, (3.0, 0.0))  # enough points, but a perimeter of ~0.13
    ring = _circle(12, 0.6, (6.0, 0.0))  # perimeter ~3.8, spacing ~0.31: a void ring on a 0.1 sampling
    few = _circle(3, 1.0, (9.0, 0.0))
    points = np.vstack([big, tiny, ring, few])
    ids = np.split(np.arange(len(points)), np.cumsum([40, 10, 12]))
    ball_radius = np.full(len(points), 0.25)  # loops need a perimeter >= 2 ball radii = 0.5
    kept = _true_loops(points, ids, ball_radius, 0.25, 4, None)
    assert [c[0] for c in kept] == [ids[0][0], ids[2][0]]
    spacing = np.full(len(points), 0.2)
    spacing[ids[2]] = 0.1
    kept = _true_loops(points, ids, ball_radius, 0.25, 4, spacing)
    assert [c[0] for c in kept] == [ids[0][0]]  # 0.157 / 0.2 <= 1.25 but 0.31 / 0.1 > 1.25
    # the typical radius sets the perimeter floor even where the loop's own balls are small
    assert _true_loops(points, ids[:1], np.full(len(points), 0.01), 4.0, 4, None) == []


def _walk_inputs(name, n, sampling, eps):
    pts = make_surface(name, n, sampling=sampling, seed=0).points
    graph = knn_graph(pts, 8)
    nrm = orient_normals(pts, pca_normals(pts, graph.indices), graph.indices)
    balls = dem_balls(pts, nrm, symmetric_adjacency(graph), graph.mean_spacing, ball_eps_factor=eps)
    gap, bisector = angular_gaps(balls.coords, balls.indices >= 0)
    candidates = gap > np.deg2rad(120.0)
    e1, e2 = tangent_frames(nrm)
    outward = bisector[:, :1] * e1 + bisector[:, 1:] * e2
    radius = float(np.median(np.linalg.norm(balls.coords, axis=2).max(axis=1)))
    return pts, nrm, balls, (pts, balls.indices, balls.coords, e1, e2, candidates, outward, bisector, 2.0 * radius)


def test_walk_pruned_leaves_no_small_cycle_on_a_ragged_boundary():
    pts, nrm, balls, args = _walk_inputs("bump", 3000, "random", 1.5)
    candidates = args[5]
    loops, n_pruned, _ = _walk_pruned(*args, 16)
    assert n_pruned > 0  # random sampling with small balls: wrong steps into gaps happen
    assert all(c.size >= 16 for c in loops)
    members = np.concatenate(loops)
    assert np.unique(members).size == members.size and candidates[members].all()
    # without pruning (min size 1) nothing is dropped, and the walk finds at least as many cycles
    unpruned, none, _ = _walk_pruned(*args, 1)
    assert none == 0 and len(unpruned) >= len(loops)
    # find_boundary reports the pruned cycles among its dropped loops
    res = find_boundary(pts, nrm, balls.indices, balls.coords, min_loop_size=16, require_loop=False)
    assert res.diagnostics["n_dropped_loops"] >= n_pruned
