"""The reference triangulation of height-field points (LiDAR ground returns)."""

from __future__ import annotations

import numpy as np
import pytest

from parambench.datasets_gen.errors import InvalidInputError
from parambench.datasets_gen.height_field import height_field_surface
from parambench.datasets_gen.real import REAL_DATASETS, load_real


def _jittered_terrain(n_side: int = 40, hole: tuple[float, float, float] | None = None, seed: int = 0,
                      offset: float = 0.0, step: float = 1.0) -> np.ndarray:
    """A jittered grid (40 x 40 steps of 1 unless said) under a smooth terrain, optionally with a disc cut out."""
    rng = np.random.default_rng(seed)
    g = np.arange(n_side, dtype=float)
    x, y = (a.ravel() for a in np.meshgrid(g, g))
    x, y = x + rng.uniform(-0.2, 0.2, x.size), y + rng.uniform(-0.2, 0.2, y.size)
    z = 2.0 * np.sin(x / 9.0) * np.cos(y / 7.0)
    pts = np.column_stack([x, y, z])
    if hole is not None:
        cx, cy, r = hole
        pts = pts[np.hypot(x - cx, y - cy) > r]
    return pts * [step, step, 1.0] + [offset, offset, 0.0]


def _signed_xy_areas(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    a, b, c = (points[faces[:, i], :2] for i in range(3))
    return 0.5 * ((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (b[:, 1] - a[:, 1]))


def _euler_characteristic(n_points: int, faces: np.ndarray) -> int:
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    return n_points - len(np.unique(edges, axis=0)) + len(faces)


def test_a_terrain_without_a_hole_is_one_disk_of_every_point():
    pts = _jittered_terrain()
    s = height_field_surface(pts, "terrain")
    assert s.n_points == len(pts) and s.params["n_left_out"] == 0 and s.params["n_voids"] == 0
    assert len(s.boundary_loops) == 1 and _euler_characteristic(s.n_points, s.faces) == 1
    assert (_signed_xy_areas(s.points, s.faces) > 0).all()  # counter-clockwise seen from +z


def test_a_hole_several_steps_wide_is_opened_and_only_it():
    cx, cy, r = 20.0, 18.0, 3.5
    s = height_field_surface(_jittered_terrain(hole=(cx, cy, r)), "terrain")
    assert s.params["n_voids"] == 1 and len(s.boundary_loops) == 2
    assert _euler_characteristic(s.n_points, s.faces) == 0  # a disk with one hole
    hole = s.boundary_loops[1]
    dist = np.hypot(s.points[hole, 0] - cx, s.points[hole, 1] - cy)
    assert dist.min() > r and dist.max() < r + 1.5  # the points next to the cut disc
    centroids = s.points[s.faces].mean(axis=1)
    assert (np.hypot(centroids[:, 0] - cx, centroids[:, 1] - cy) > r).all()  # no triangle across it
    # the outer loop is the grid's rim: its points lie on the outermost rows and columns
    rim = s.points[s.boundary_loops[0], :2]
    assert np.minimum(np.minimum(rim[:, 0], rim[:, 1]), np.minimum(39 - rim[:, 0], 39 - rim[:, 1])).max() < 0.5


def test_survey_coordinates_lose_no_point():
    # qhull's tolerances scale with the coordinates: uncentred, Delaunay at x ~ 2.4e6 left
    # 5 of the shipped tile's returns out of every triangle.
    near = height_field_surface(_jittered_terrain(seed=1, step=0.3), "terrain")
    far = height_field_surface(_jittered_terrain(seed=1, step=0.3, offset=2.4e6), "terrain")
    assert far.n_points == near.n_points and far.params["n_left_out"] == 0
    assert len(far.faces) == len(near.faces)


@pytest.mark.parametrize("points", [np.column_stack([np.arange(10.0), 2 * np.arange(10.0), np.zeros(10)]),
                                    np.array([[0.0, 0.0, 0.0], [1.0, 0.0, np.nan], [0.0, 1.0, 0.0]]),
                                    np.zeros((2, 3))])
def test_points_without_an_xy_area_are_refused(points):
    with pytest.raises(InvalidInputError):
        height_field_surface(points, "bad")


def test_the_shipped_lidar_tile_has_its_rim_and_its_hole():
    spec = REAL_DATASETS["real/lidar-ground"]
    assert spec.location == "package" and spec.path().is_file()
    s = load_real("real/lidar-ground")
    raw = np.loadtxt(spec.path(), skiprows=1)
    assert raw.shape == (9808, 3) and s.n_points == 9808 and np.array_equal(s.points, raw)  # every return, in order
    assert len(s.boundary_loops) == 2 and _euler_characteristic(s.n_points, s.faces) == 0
    assert (_signed_xy_areas(s.points, s.faces) > 0).all() and (s.normals[:, 2] > 0.5).all()
    # The hole lies where vegetation hid the ground, round x 2445213, y 604310.5; the returns
    # around it span 3.7 x 4.3 ft.
    hole = s.points[s.boundary_loops[1], :2]
    assert np.abs(hole.mean(axis=0) - [2445213.0, 604310.5]).max() < 1.0
    assert 3.0 < np.ptp(hole, axis=0).min() and np.ptp(hole, axis=0).max() < 5.0
    # The rim follows the building's notch (x > 2445233, y > 604320 holds no ground), not the hull.
    tri_centroids = s.points[s.faces].mean(axis=1)
    assert not ((tri_centroids[:, 0] > 2445234.0) & (tri_centroids[:, 1] > 604320.0)).any()
