"""Loops that cut across the surface are wrapped round the points they leave outside."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.path import Path
from scipy.spatial import cKDTree

from parambench.methods.pointset.frontend import build_frontend
from parambench.methods.pointset.loop_wrap import wrap_outside_points
from parambench.methods.pointset.selfcheck import points_outside


def _outside_2d(xy: np.ndarray, loops: list[np.ndarray]) -> np.ndarray:
    """Points off the loops outside the outer loop's polygon (flat inputs: xy is the surface)."""
    on_loop = np.zeros(len(xy), dtype=bool)
    on_loop[np.concatenate(loops)] = True
    inside = Path(xy[loops[0]]).contains_points(xy)
    return np.flatnonzero(~inside & ~on_loop)


def _balls(points: np.ndarray, radius: float) -> np.ndarray:
    """Neighbours within ``radius``, nearest first, -1 padded (as the front end's balls)."""
    rows = cKDTree(points).query_ball_point(points, radius)
    width = max(len(r) for r in rows)
    out = np.full((len(points), width), -1, dtype=np.int64)
    for i, r in enumerate(rows):
        r = np.array([j for j in r if j != i], dtype=np.int64)
        r = r[np.argsort(np.linalg.norm(points[r] - points[i], axis=1))]
        out[i, :r.size] = r
    return out


def _square_with_a_shortcut():
    """A 21 x 21 jittered grid on the unit square and its rim loop (counter-clockwise),
    but with the middle of the right side replaced by a step one row inside: the 7 rim
    points there lie outside the loop."""
    rng = np.random.default_rng(3)
    n = 21
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    xy = np.c_[i.ravel(), j.ravel()] / (n - 1.0)
    rim = (i.ravel() == 0) | (i.ravel() == n - 1) | (j.ravel() == 0) | (j.ravel() == n - 1)
    xy[~rim] += rng.uniform(-0.01, 0.01, (int((~rim).sum()), 2))
    xy[rim] += rng.uniform(0.001, 0.01, (int(rim.sum()), 1)) * np.sign(xy[rim] - 0.5)  # no three rim points in line
    index = lambda a, b: a * n + b  # noqa: E731 - a grid index
    bottom = [index(a, 0) for a in range(n)]
    right = [index(n - 1, b) for b in range(1, n)]
    top = [index(a, n - 1) for a in range(n - 2, -1, -1)]
    left = [index(0, b) for b in range(n - 2, 0, -1)]
    # The right side from row 7 to 13 is skipped: the loop steps in to column n-2.
    right = right[:6] + [index(n - 2, b) for b in range(7, 14)] + right[13:]
    loop = np.array(bottom + right + top + left, dtype=np.int64)
    points = np.c_[xy, np.zeros(len(xy))]
    centre = np.array([0.5, 0.5, 0.0])
    outward = points - centre
    outward /= np.linalg.norm(outward, axis=1, keepdims=True)
    normals = np.tile([0.0, 0.0, 1.0], (len(xy), 1))
    return points, normals, loop, outward


def test_a_shortcut_across_the_surface_is_wrapped_round_the_points_it_left_out():
    points, normals, loop, outward = _square_with_a_shortcut()
    n = 21
    skipped = [(n - 1) * n + b for b in range(7, 14)]
    step = [(n - 2) * n + b for b in range(7, 14)]
    assert set(_outside_2d(points[:, :2], [loop]).tolist()) == set(skipped)
    wrapped, count, dropped = wrap_outside_points(points, normals, [loop], outward, _balls(points, 2.6 / 20))
    assert count >= 6 and dropped == len(step)
    assert _outside_2d(points[:, :2], wrapped).size == 0
    # The rim is back and the step inside is off the loop (its points left as deep notches are dropped).
    assert np.isin(skipped, wrapped[0]).sum() >= 6
    assert not np.isin(step, wrapped[0]).any()
    assert np.unique(wrapped[0]).size == wrapped[0].size
    # The rest of the loop keeps its order.
    kept = [p for p in loop.tolist() if p not in step]
    position = {p: k for k, p in enumerate(wrapped[0].tolist())}
    order = np.array([position[p] for p in kept])
    assert np.count_nonzero(np.diff(order) < 0) <= 1  # one wrap-around of the start


def test_a_correct_loop_is_left_as_it_is():
    points, normals, loop, outward = _square_with_a_shortcut()
    n = 21
    start = loop.tolist().index((n - 1) * n + 6)
    # The true rim: the skipped points back, the inner step left out.
    true_loop = np.r_[loop[:start + 1], [(n - 1) * n + b for b in range(7, 14)], loop[start + 8:]]
    assert _outside_2d(points[:, :2], [true_loop]).size == 0
    wrapped, count, dropped = wrap_outside_points(points, normals, [true_loop], outward, _balls(points, 2.6 / 20))
    assert count == 0 and dropped == 0
    np.testing.assert_array_equal(wrapped[0], true_loop)


@pytest.mark.parametrize("seed", [1, 2, 3, 11, 17, 18])
def test_uniform_random_points_on_a_tile_lie_inside_their_rim(seed):
    """Uniform random points on a nearly flat square (a LiDAR tile's sampling): on these
    seeds the walk cut across the surface and left 2-13 points outside the rim (on 32 of
    40 seeds, up to 4 spacings deep); `ocp`'s maps were then 9e-5 to 1.8e-2 of the
    diameter off the exact development with their self-checks passed, and seed 11's folded
    a triangle. Wrapped, no point is left outside."""
    rng = np.random.default_rng(seed)
    xy = rng.uniform(-1, 1, (3000, 2))
    fe = build_frontend(np.c_[xy, 0.06 * np.sin(xy[:, 0])])
    assert _outside_2d(xy, fe.boundary_loops).size == 0
    assert fe.diagnostics["boundary"]["n_wrapped"] >= 1


def test_a_loop_that_cuts_a_corner_gets_the_corner_back():
    """4000 uniform random points on a unit square turned in space (seed 5): the loop cut the
    corner (0.997, 0.004) off, and the corner's one edge into the surface crossed the loop's
    edge before the shortcut, where its foot lay at 1.69 of the edge's length: it stayed
    outside (0.26 of its spacing deep in uv) and ``ocp`` failed its check, its map 3.6e-3 of
    the square off the exact one. The edges next to a crossed one are tried too now."""
    rng = np.random.default_rng(5)
    uv = rng.random((4000, 2))
    rotation = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    points = np.c_[uv, np.zeros(len(uv))] @ rotation.T
    fe = build_frontend(points)
    flat = (fe.points @ rotation)[:, :2]
    assert _outside_2d(flat, fe.boundary_loops).size == 0
    corner = np.argmin(np.linalg.norm(flat - [0.99687172, 0.00422386], axis=1))
    assert corner in fe.boundary_loops[0]


def test_points_outside_counts_points_the_map_leaves_beyond_its_loops():
    x, y = np.meshgrid(np.linspace(0, 1, 11), np.linspace(0, 1, 11))
    uv = np.c_[x.ravel(), y.ravel()]
    knn = cKDTree(uv).query(uv, k=5)[1][:, 1:]
    rim = list(range(11)) + [10 + 11 * r for r in range(1, 11)] + [120 - k for k in range(1, 11)] + \
        [110 - 11 * r for r in range(1, 10)]
    loop = np.array(rim, dtype=np.int64)
    assert points_outside(uv, [loop], knn) == {"n_outside": 0, "outside_depth": 0.0}
    # The corner (0, 0) cut off by the chord from (0, 0.1) to (0.1, 0): 0.07 beyond it,
    # about half its spacing.
    facts = points_outside(uv, [loop[1:]], knn)
    assert facts["n_outside"] == 1 and 0.3 < facts["outside_depth"] < 0.8
    moved = uv.copy()
    moved[12] = [-0.05, -0.05]  # an interior point mapped beyond the corner
    facts = points_outside(moved, [loop], knn)
    assert facts["n_outside"] == 1 and 0.2 < facts["outside_depth"] < 1.0
