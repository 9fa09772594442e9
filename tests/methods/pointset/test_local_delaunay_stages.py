"""The stages of the one-ring kernel on their own: inversion and sort, monotone hull, ring triangles."""

from __future__ import annotations

import numpy as np

from parambench.methods.pointset.local_delaunay import _emit_ring, _inverted_sorted, _monotone_hull, _rings_kernel


def _scratch(m):
    return np.empty(m + 1), np.empty(m + 1), np.empty(m + 1, dtype=np.int64), np.empty(2 * (m + 1) + 2, dtype=np.int64)


def test_inverted_sorted_skips_invalid_and_coincident_candidates():
    coords = np.array([[[2.0, 0.0], [0.0, 0.0], [0.0, -0.5], [5.0, 5.0], [-1.0, 1.0]]])
    valid = np.array([[True, True, True, False, True]])
    xs, ys, ids, _ = _scratch(5)
    cnt = _inverted_sorted(coords, valid, 0, xs, ys, ids)
    # columns 0, 2, 4 inverted (d / |d|^2) plus the origin; column 1 sits on the point, 3 is padding
    assert cnt == 4
    assert ids[:cnt].tolist() == [4, 2, -1, 0]  # sorted by x, then y
    np.testing.assert_allclose(np.c_[xs[:cnt], ys[:cnt]], [[-0.5, 0.5], [0.0, -2.0], [0.0, 0.0], [0.5, 0.0]])


def test_monotone_hull_is_ccw_and_drops_inner_and_collinear_points():
    # sorted by (x, y): a square's corners, an edge midpoint (collinear) and the centre
    pts = np.array([[0, 0], [0, 1], [1, 0], [1, 0.5], [1, 1], [0.5, 0.5]], dtype=float)
    order = np.lexsort((pts[:, 1], pts[:, 0]))
    xs, ys = pts[order, 0].copy(), pts[order, 1].copy()
    hull = np.empty(2 * len(pts) + 2, dtype=np.int64)
    h = _monotone_hull(xs, ys, len(pts), hull)
    corners = [tuple(p) for p in np.c_[xs, ys][hull[:h]]]
    assert corners == [(0, 0), (1, 0), (1, 1), (0, 1)]


def _ring(coords):
    coords = np.asarray(coords, dtype=float)[None]
    valid = np.ones(coords.shape[:2], dtype=bool)
    m = valid.shape[1]
    xs, ys, ids, hull = _scratch(m)
    cnt = _inverted_sorted(coords, valid, 0, xs, ys, ids)
    h = _monotone_hull(xs, ys, cnt, hull)
    out = np.full((1, m, 2), -1, dtype=np.int64)
    _emit_ring(xs, ys, ids, hull, h, out, 0)
    whole = np.full((1, m, 2), -1, dtype=np.int64)
    _rings_kernel(coords, valid, whole)
    np.testing.assert_array_equal(out, whole)  # the stages compose to the kernel
    return {tuple(t) for t in out[0] if t[0] >= 0}


def test_emit_ring_closed_fan_around_an_interior_point():
    # E, N, W, S and a far point outside the Delaunay ring (its image lies inside the hull)
    ring = _ring([[1, 0], [0, 1], [-1, 0], [0, -1], [3, 3]])
    assert ring == {(0, 1), (1, 2), (2, 3), (3, 0)}


def test_emit_ring_open_fan_on_the_local_hull():
    # candidates on one side only: the origin is on the hull, its two edges carry no triangle
    ring = _ring([[1, -1], [1, 0], [1, 1]])
    assert ring == {(0, 1), (1, 2)}
