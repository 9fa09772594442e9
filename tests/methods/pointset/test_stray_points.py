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
    """A graded sampling (density varying 10-20x), a tight cluster of 30 repeated measurements
    within 1e-4 of a point of a 50 x 50 grid, and a corner sampled 10000 times more densely:
    no point is isolated (the first rule, against the neighbours' own spacing, flagged the
    sparse points beside the cluster). One point far off, even in the surface's own plane, is,
    and so are two junk rows side by side."""
    from scipy.spatial import cKDTree

    from parambench.methods.pointset.stray_points import isolated_mask

    def isolated(pts):
        return isolated_mask(pts, cKDTree(pts).query(pts, 9)[1][:, 1:])

    points = make_surface("holes", 2000, sampling=sampling, seed=1).points
    assert not isolated(points).any()
    far = np.vstack([points, points.mean(axis=0) + [1e3, 0.0, 0.0]])
    assert np.flatnonzero(isolated(far)).tolist() == [len(points)]
    pair = np.vstack([points, [[0.0, 0.0, 50.0], [0.0, 0.01, 50.0]]])
    assert np.flatnonzero(isolated(pair)).tolist() == [len(points), len(points) + 1]
    # four to eight junk rows together are each other's nearest neighbours: the third-nearest
    # rule alone passed them (and the map failed on loops crossing, or points outside them)
    for n_junk in (4, 6, 8):
        junk = np.random.default_rng(n_junk).normal(scale=0.01, size=(n_junk, 3)) + [0.0, 0.0, 50.0]
        assert np.flatnonzero(isolated(np.vstack([points, junk]))).tolist() == list(range(len(points),
                                                                                      len(points) + n_junk))
    rng = np.random.default_rng(0)
    g = np.linspace(0.0, 1.0, 50)
    grid = np.c_[np.stack(np.meshgrid(g, g), -1).reshape(-1, 2), np.zeros(2500)]
    cluster = grid[1250] + rng.uniform(-1e-4, 1e-4, (30, 3)) * [1, 1, 0]
    corner = np.c_[rng.random((3500, 2)) * 0.01, np.zeros(3500)]
    for pts in (np.vstack([grid, cluster]), np.vstack([grid, corner])):
        assert not isolated(pts).any()
