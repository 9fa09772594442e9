"""Stray points off the surface (a scan's outliers): found from positions alone, and nothing else."""

from __future__ import annotations

import numpy as np
import pytest

from parambench.datasets_gen.registry import make_surface
from parambench.methods.pointset.stray_points import STRAY_OFFSET, find_stray_points


def _plane(n_side: int = 40, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    g = np.stack(np.meshgrid(np.arange(n_side), np.arange(n_side), indexing="ij"), -1).reshape(-1, 2) / n_side
    g = g + rng.uniform(-0.2, 0.2, g.shape) / n_side
    return np.column_stack([g, np.zeros(len(g))])


def test_points_lifted_off_a_plane_are_found_and_no_other():
    points = _plane()
    rng = np.random.default_rng(1)
    lifted = rng.choice(len(points), 15, replace=False)
    points[lifted, 2] += 3.0 / 40  # 3 grid steps, about 2.2 mean 8-NN distances
    stray = find_stray_points(points)
    assert np.array_equal(np.flatnonzero(stray), np.sort(lifted))


def test_points_lifted_less_than_the_limit_stay():
    points = _plane()
    points[::97, 2] += 0.5 * STRAY_OFFSET / 40  # under the limit whatever the spacing's definition
    assert not find_stray_points(points).any()


def test_a_clump_of_outliers_is_found_over_the_passes():
    # Pairs of outliers close to each other: each lies in the plane of the other's fit at
    # first; with the far ones gone, the next pass sees them.
    points = _plane()
    rng = np.random.default_rng(2)
    centres = np.column_stack([rng.uniform(0.2, 0.8, (6, 2)), np.full(6, 4.0 / 40)])
    pairs = np.vstack([centres, centres + [0.3 / 40, 0.0, 0.0]])
    stray = find_stray_points(np.vstack([points, pairs]))
    assert stray[len(points):].all() and not stray[:len(points)].any()


def test_two_sheets_a_third_of_a_spacing_apart_are_not_stray():
    # A thin flap: every point lies in the planes of its own sheet's neighbours.
    lower = _plane(20, seed=3)
    upper = _plane(20, seed=4)
    upper[:, 2] = 0.3 / 20
    assert not find_stray_points(np.vstack([lower, upper])).any()


@pytest.mark.parametrize("name, sampling", [("bump", "random"), ("holes", "graded"), ("saddle", "random"),
                                            ("fold", "graded"), ("real/lilium", "scattered")])
def test_clean_samplings_have_no_stray_point(name, sampling):
    surface = make_surface(name, 4000, sampling=sampling, seed=0)
    assert not find_stray_points(surface.points).any()


@pytest.mark.parametrize("sampling", ["random", "graded"])
def test_isolated_points_are_far_ones_only(sampling):
    """A graded sampling's density varies 10-20x, smoothly: no point is isolated (measured: the
    largest ratio over the generated surfaces and real meshes 7.9, camelhead's density jumps).
    A point far off, even in the surface's own plane, is."""
    from scipy.spatial import cKDTree

    from parambench.methods.pointset.stray_points import isolated_mask

    points = make_surface("holes", 2000, sampling=sampling, seed=1).points
    far = np.vstack([points, points.mean(axis=0) + [1e3, 0.0, 0.0]])
    for pts, expected in ((points, 0), (far, 1)):
        dist, idx = cKDTree(pts).query(pts, 9)
        found = isolated_mask(dist[:, 1:].mean(axis=1), idx[:, 1:])
        assert found.sum() == expected and (expected == 0 or found[-1])
