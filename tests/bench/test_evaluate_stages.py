"""The stages of parambench.bench.metrics.evaluate on their own: per-face shape metrics and oriented turning numbers."""

from __future__ import annotations

import numpy as np
from scipy.spatial import Delaunay

from parambench.bench.metrics.evaluate import _SHAPE_KEYS, _face_shape_metrics, _oriented_turning_numbers
from parambench.bench.metrics.jacobian import face_jacobian_sv
from parambench.bench.metrics.orientation import collapsed_mask


def _planar_mesh():
    g = np.stack(np.meshgrid(np.linspace(0, 1, 6), np.linspace(0, 1, 6)), axis=-1).reshape(-1, 2)
    tri = Delaunay(g).simplices.astype(np.int64)
    return np.c_[g, np.zeros(len(g))], tri


def _metrics(pts, tri, uv, live=None):
    s1, s2, signed, area = face_jacobian_sv(pts, tri, uv)
    return _face_shape_metrics(pts, tri, uv, s1, s2, signed, area, ~collapsed_mask(signed) if live is None else live)


def test_similarity_has_no_shape_distortion():
    pts, tri = _planar_mesh()
    rot = np.array([[np.cos(0.7), -np.sin(0.7)], [np.sin(0.7), np.cos(0.7)]])
    m = _metrics(pts, tri, 3.0 * pts[:, :2] @ rot.T)
    assert set(m) == set(_SHAPE_KEYS)
    assert np.isclose(m["qc_mean"], 1) and np.isclose(m["qc_max"], 1) and np.isclose(m["qc_p95"], 1)
    assert m["mu_mean"] < 1e-12 and m["mu_sd"] < 1e-12 and m["sigma_ratio_max"] < 1e-12
    assert m["angle_error_mean"] < 1e-9 and m["flipped_share"] == 0.0
    assert sum(m["angle_hist"]) == 3 * len(tri)  # every corner of every live face


def test_stretch_gives_its_aspect_ratio():
    pts, tri = _planar_mesh()
    m = _metrics(pts, tri, pts[:, :2] * [2.0, 1.0])
    assert np.isclose(m["qc_mean"], 2) and np.isclose(m["qc_max"], 2)
    assert np.isclose(m["mu_mean"], 1 / 3) and m["mu_sd"] < 1e-12  # (2 - 1) / (2 + 1)
    assert np.isclose(m["sigma_ratio_max"], 0.5)  # 2 + 1/2 - 2


def test_dead_faces_are_left_out():
    pts, tri = _planar_mesh()
    uv = pts[:, :2].copy()
    uv[tri[0, 0]] += [0.1, 0.05]  # distorts the faces around one vertex
    bad = np.any(tri == tri[0, 0], axis=1)
    assert _metrics(pts, tri, uv)["qc_max"] > 1.1
    kept = _metrics(pts, tri, uv, live=~bad)
    assert np.isclose(kept["qc_max"], 1) and sum(kept["angle_hist"]) == 3 * int((~bad).sum())
    assert _metrics(pts, tri, uv, live=np.zeros(len(tri), bool)) == dict.fromkeys(_SHAPE_KEYS)


def test_oriented_turning_numbers():
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=float)
    loops = [np.arange(4), np.arange(4)[::-1]]
    assert _oriented_turning_numbers(square, loops, 1) == [1.0, -1.0]
    # a mirrored map has majority orientation -1: the sign is restored
    assert _oriented_turning_numbers(square * [1, -1], loops, -1) == [1.0, -1.0]
    assert _oriented_turning_numbers(square, [], 1) == []
