"""Exact maps: identity, stereographic projection, cylinder unrolling; the protrusions chart."""

from __future__ import annotations

import numpy as np
import pytest

from parambench.datasets_gen.registry import make_surface
from parambench.datasets_gen.shapes import SHAPES


def test_flat_maps_are_the_identity():
    for name in ("plane", "holes"):
        s = make_surface(name, 1500, sampling="random", seed=0)
        assert s.exact_map_kind == "conformal"
        assert np.array_equal(s.exact_uv, s.points[:, :2]) and np.all(s.points[:, 2] == 0)
    plane = make_surface("plane", 1500, sampling="grid")
    assert plane.points[:, :2].min() == 0.0 and plane.points[:, :2].max() == 1.0  # the unit square


def test_cap_geometry_and_stereographic_formula():
    s = make_surface("cap", 3000, sampling="jittered", seed=2)
    assert np.allclose(np.linalg.norm(s.points, axis=1), 1.0)
    assert np.allclose(s.normals, s.points)
    polar = np.degrees(np.arccos(np.clip(s.points[:, 2], -1, 1)))
    assert polar.max() <= 60.0 + 1e-9 and np.allclose(polar[s.boundary_mask], 60.0)
    # u + iv = tan(theta / 2) e^{i phi}
    expected = s.points[:, :2] / (1 + s.points[:, 2])[:, None]
    assert np.allclose(s.exact_uv, expected)
    assert np.allclose(np.hypot(*s.exact_uv[s.boundary_mask].T), np.tan(np.radians(30)))


def test_cap_stereographic_map_is_conformal_on_a_fine_mesh(helpers):
    s = make_surface("cap", 20000, sampling="grid", seed=0)
    assert s.exact_map_kind == "conformal"
    sv = helpers.jacobian_singular_values(s.points, s.faces, s.exact_uv)
    ratio = sv[:, 0] / sv[:, 1]
    w = helpers.face_areas(s.points, s.faces)
    assert np.sum(w * ratio) / w.sum() < 1.01
    assert ratio.max() < 1.05
    # not isometric: the scale varies by 1 / (1 + cos theta), from 1/2 to 2/3
    scale = np.sqrt(sv[:, 0] * sv[:, 1])
    assert 0.49 < scale.min() < 0.52 and 0.64 < scale.max() < 0.68


def test_cap_grid_is_near_regular_on_the_sphere(helpers):
    s = make_surface("cap", 5000, sampling="grid", seed=0)
    e = helpers.unique_edges(s.faces)
    length = np.linalg.norm(s.points[e[:, 0]] - s.points[e[:, 1]], axis=1)
    assert np.percentile(length, 95) / np.percentile(length, 5) < 1.6


def test_cylinder_unrolling_is_isometric(helpers):
    s = make_surface("cylinder", 4000, sampling="random", seed=3)
    assert s.exact_map_kind == "isometric"
    assert np.allclose(np.hypot(s.points[:, 0], s.points[:, 1]), 1.0)
    e = helpers.unique_edges(s.faces)
    d3 = np.linalg.norm(s.points[e[:, 0]] - s.points[e[:, 1]], axis=1)
    duv = np.linalg.norm(s.exact_uv[e[:, 0]] - s.exact_uv[e[:, 1]], axis=1)
    dtheta = np.abs(s.exact_uv[e[:, 0], 0] - s.exact_uv[e[:, 1], 0])
    chord_error = dtheta - 2 * np.sin(dtheta / 2)  # r = 1: arc minus chord
    assert np.all(d3 <= duv + 1e-12)
    assert np.all(duv - d3 <= chord_error + 1e-12)
    assert np.ptp(s.exact_uv[:, 0]) == pytest.approx(np.pi) and np.ptp(s.exact_uv[:, 1]) == pytest.approx(2.0)


def test_protrusions_chart_is_conformal_and_identity_on_the_base(helpers):
    """The meshing chart is exactly conformal: the discrete distortion vanishes as O(h)."""
    shape = SHAPES["protrusions"]()
    excess = []
    for n in (5000, 20000):
        s = make_surface("protrusions", n, sampling="blue-noise", seed=0)
        assert s.exact_uv is None and s.exact_map_kind is None
        chart = shape.chart(s.points[:, :2])
        flat = s.points[:, 2] == 0
        assert np.array_equal(chart[flat], s.points[flat, :2])
        sv = helpers.jacobian_singular_values(s.points, s.faces, chart)
        w = helpers.face_areas(s.points, s.faces)
        excess.append(np.sum(w * sv[:, 0] / sv[:, 1]) / w.sum() - 1)
    assert excess[1] < 0.05
    assert excess[1] < 0.6 * excess[0]  # h halves: a non-conformal chart would level off instead
    # fingertips are squeezed by ~exp(-7.5): the crowding any conformal map of this surface has
    scale = np.sqrt(sv[:, 0] * sv[:, 1])
    assert np.exp(-8) < scale.min() < np.exp(-7)
    assert s.points[:, 2].max() == pytest.approx(1.0, abs=0.01)
