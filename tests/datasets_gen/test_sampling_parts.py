"""The building blocks: lattice, sizing, boundary placement, crowding removal, Poisson disk, area sampling."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from parambench.datasets_gen.domains import Disk, Domain, Rect
from parambench.datasets_gen.sampling.area_uniform import sample_by_area
from parambench.datasets_gen.sampling.boundary import near_boundary, place_boundary
from parambench.datasets_gen.sampling.lattice import jitter_in_disk, triangular_lattice
from parambench.datasets_gen.sampling.poisson_disk import poisson_disk_select
from parambench.datasets_gen.sampling.sizing import BOUNDARY_EXCESS, LATTICE_DENSITY, spacing_for_count
from parambench.datasets_gen.shapes import SHAPES


def test_triangular_lattice_is_equilateral():
    pts = triangular_lattice([0, 0], [1, 1], 0.1, origin=(0, 0))
    dist, _ = cKDTree(pts).query(pts, k=7)
    inner = np.all((pts > 0.15) & (pts < 0.85), axis=1)
    assert np.allclose(dist[inner, 1:], 0.1)  # six neighbours at exactly h
    assert np.any(np.all(pts == [0, 0], axis=1))  # the origin is a lattice point
    rotated = triangular_lattice([-1, -1], [1, 1], 0.2, origin=(0.05, 0), angle=0.3)
    d = rotated - [0.05, 0]
    # a lattice point along the rotated row direction
    assert np.min(np.linalg.norm(d - 0.2 * np.array([np.cos(0.3), np.sin(0.3)]), axis=1)) < 1e-12


def test_jitter_stays_in_its_disk():
    d = jitter_in_disk(20000, 0.3, np.random.default_rng(0))
    r = np.hypot(*d.T)
    assert r.max() <= 0.3 and abs(np.mean(r < 0.15) - 0.25) < 0.02  # uniform by area


def test_spacing_solves_the_count_equation():
    h = spacing_for_count(5000, area=4.0, length=8.0)
    assert LATTICE_DENSITY * 4.0 / h ** 2 + BOUNDARY_EXCESS * 8.0 / h == pytest.approx(5000)


def test_boundary_points_keep_corners_and_spacing():
    shape = SHAPES["plane"]()
    (loop,) = place_boundary(shape, 0.1, "param")
    assert len(loop) == 40
    for corner in ([0, 0], [1, 0], [1, 1], [0, 1]):
        assert np.any(np.all(loop == corner, axis=1))
    step = np.linalg.norm(np.roll(loop, -1, axis=0) - loop, axis=1)
    assert np.allclose(step, 0.1)
    jittered = place_boundary(shape, 0.1, "param", jitter=0.25, rng=np.random.default_rng(0))[0]
    for corner in ([0, 0], [1, 0], [1, 1], [0, 1]):
        assert np.any(np.all(jittered == corner, axis=1))
    step = np.linalg.norm(np.roll(jittered, -1, axis=0) - jittered, axis=1)
    assert step.min() >= 0.05 - 1e-12 and not np.allclose(step, 0.1)


def test_boundary_spacing_measured_on_the_surface():
    cap = SHAPES["cap"]()
    (rim,) = place_boundary(cap, 0.05, "3d")
    p = cap.lift(rim)[0]
    step = np.linalg.norm(np.roll(p, -1, axis=0) - p, axis=1)
    circumference = 2 * np.pi * np.sin(np.radians(60))
    assert len(rim) == round(circumference / 0.05)
    assert np.allclose(step, step.mean(), rtol=1e-3)


def test_near_boundary_clears_the_diametral_disks():
    loop = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    pts = np.array([[0.5, 0.55], [0.5, 0.65], [0.5, 0.5], [0.05, 0.3]])
    crowd = near_boundary(pts, [loop])
    # chord midpoints (0.5, 0), (1, 0.5), ... with radius 0.6 * 1; vertices with radius 0.45
    assert crowd.tolist() == [True, True, True, True]
    square = np.array([[x, 0.0] for x in np.arange(0, 1, 0.1)] + [[1.0, y] for y in np.arange(0, 1, 0.1)]
                      + [[x, 1.0] for x in np.arange(1, 0, -0.1)] + [[0.0, y] for y in np.arange(1, 0, -0.1)])
    probes = np.array([[0.55, 0.059], [0.55, 0.061], [0.5, 0.044], [0.5, 0.046], [0.5, 0.5]])
    # above a chord midpoint: radius 0.6 x 0.1; above a boundary point: 0.45 x 0.1
    assert near_boundary(probes, [square]).tolist() == [True, False, True, False, False]


def test_poisson_disk_select_is_greedy_dart_throwing():
    line = np.column_stack([np.arange(10) * 0.4, np.zeros(10)])
    keep = poisson_disk_select(line, 1.0)
    assert np.flatnonzero(keep).tolist() == [0, 3, 6, 9]  # each kept point blocks the next two
    keep = poisson_disk_select(line, 1.0, n_fixed=2)  # 0 and 1 fixed although close
    assert np.flatnonzero(keep).tolist() == [0, 1, 4, 7]
    pts = np.random.default_rng(0).random((5000, 2))
    keep = poisson_disk_select(pts, 0.02)
    kept = pts[keep]
    assert cKDTree(kept).query(kept, k=2)[0][:, 1].min() >= 0.02  # a Poisson-disk set
    assert cKDTree(kept).query(pts[~keep])[0].max() < 0.02  # maximal: every rejected point is covered
    # equal to sequential dart throwing in index order
    accepted = []
    for i, p in enumerate(pts[:600]):
        if all(np.linalg.norm(p - pts[j]) >= 0.05 for j in accepted):
            accepted.append(i)
    assert np.flatnonzero(poisson_disk_select(pts[:600], 0.05)).tolist() == accepted


def test_area_uniform_sampling_on_the_cap():
    """Fraction of points within polar angle 30 deg = its share of the cap's area."""
    cap = SHAPES["cap"]()
    x = sample_by_area(cap, 40000, np.random.default_rng(0))
    assert cap.domain.contains(x).all()
    theta = np.hypot(*x.T)
    expected = (1 - np.cos(np.radians(30))) / (1 - np.cos(np.radians(60)))
    assert abs(np.mean(theta < np.radians(30)) - expected) < 0.01
    assert cap.surface_area == pytest.approx(2 * np.pi * (1 - np.cos(np.radians(60))), rel=2e-3)


def test_domain_contains_and_area():
    dom = Domain(Rect((-1, -1), (1, 1)), (Disk((0.5, 0.5), 0.2),))
    assert dom.contains(np.array([[0, 0], [0.5, 0.5], [1, 0], [0.9, 0.9]])).tolist() == [True, False, False, True]
    assert dom.area == pytest.approx(4 - np.pi * 0.04)
    with pytest.raises(ValueError):
        Domain(Rect((-1, -1), (1, 1)), (Disk((0.9, 0.0), 0.2),))
    with pytest.raises(ValueError):
        Domain(Rect((-1, -1), (1, 1)), (Disk((0.0, 0.0), 0.3), Disk((0.4, 0.0), 0.2)))
