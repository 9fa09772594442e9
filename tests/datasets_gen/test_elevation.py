"""Elevation rasters as surfaces (:mod:`parambench.datasets_gen.elevation`)."""

import igl
import numpy as np
import pytest

from parambench.datasets_gen.elevation import matplotlib_dem, raster_surface
from parambench.datasets_gen.errors import InvalidInputError
from parambench.methods.mesh.topology import non_manifold_edges, non_manifold_vertices, require_connected_disk_like


def _grid(n_rows: int, n_cols: int):
    y, x = np.mgrid[0:n_rows, 0:n_cols].astype(float)
    return x, y, 0.1 * x * y


def test_a_full_raster_is_two_triangles_a_cell_with_one_rim():
    x, y, z = _grid(4, 5)
    s = raster_surface(x, y, z, np.ones((4, 5), dtype=bool), "grid")
    assert s.n_points == 20 and len(s.faces) == 2 * 3 * 4
    assert len(s.boundary_loops) == 1 and int(s.boundary_mask.sum()) == 2 * (4 + 5) - 4
    # Every triangle faces the same way (+z seen from above): a consistently oriented disk.
    p = s.points[s.faces]
    cross = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    assert (np.sign(cross[:, 2]) == np.sign(cross[0, 2])).all()


def test_a_cell_missing_one_corner_is_one_triangle():
    """The rim cuts across a cell with three kept corners: the fourth corner's neighbour
    on the rim is not a concave corner of the rim but an interior point."""
    x, y, z = _grid(3, 3)
    keep = np.ones((3, 3), dtype=bool)
    keep[2, 2] = False
    s = raster_surface(x, y, z, keep, "notch")
    assert s.n_points == 8 and len(s.faces) == 3 * 2 + 1
    centre = int(np.flatnonzero((s.points[:, 0] == 1) & (s.points[:, 1] == 1))[0])
    assert not s.boundary_mask[centre] and int(s.boundary_mask.sum()) == 7


@pytest.mark.parametrize("seed", range(4))
def test_random_masks_give_consistently_oriented_manifold_disks_or_annuli(seed):
    """Ragged masks (a random field thresholded): no vertex where fans meet, no edge on
    three faces, every triangle facing +z, one piece."""
    rng = np.random.default_rng(seed)
    field = rng.normal(size=(30, 40))
    for _ in range(3):  # smooth a little: coast-like blobs with inlets
        field = 0.5 * field + 0.125 * (np.roll(field, 1, 0) + np.roll(field, -1, 0) + np.roll(field, 1, 1)
                                       + np.roll(field, -1, 1))
    x, y, _ = _grid(30, 40)
    s = raster_surface(x, y, field, field > np.quantile(field, 0.35), "blobs")
    assert non_manifold_vertices(s.faces, s.n_points).size == 0
    assert non_manifold_edges(s.faces)[0].size == 0
    p = s.points[s.faces]
    cross = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    assert (cross[:, 2] > 0).all() or (cross[:, 2] < 0).all()
    assert len(s.boundary_loops) >= 1


def test_the_largest_piece_is_kept():
    x, y, z = _grid(6, 9)
    keep = np.ones((6, 9), dtype=bool)
    keep[:, 3] = False  # a 6 x 3 piece (left) and a 6 x 5 piece (right)
    s = raster_surface(x, y, z, keep, "pieces")
    assert s.n_points == 30 and s.points[:, 0].min() == 4.0


@pytest.mark.parametrize("case", ["shape", "nan", "empty"])
def test_bad_rasters_are_refused(case):
    x, y, z = _grid(4, 4)
    keep = np.ones((4, 4), dtype=bool)
    if case == "shape":
        z = z[:3]
    elif case == "nan":
        z[1, 1] = np.nan
    else:  # every cell has two kept corners
        keep[::2, :] = False
    with pytest.raises(InvalidInputError):
        raster_surface(x, y, z, keep, case)


def test_a_nan_left_out_by_keep_is_accepted():
    x, y, z = _grid(4, 4)
    z[0, 0] = np.nan
    keep = np.isfinite(z)
    s = raster_surface(x, y, z, keep, "hole")
    assert np.isfinite(s.points).all() and s.n_points == 15


def test_matplotlib_dems():
    """The rasters matplotlib ships: sizes, metres, one rim, meshes libigl accepts."""
    full = matplotlib_dem("jacksboro", 4)
    assert full.name == "dem/jacksboro-s4" and full.n_points == 86 * 101
    span = np.ptp(full.points, axis=0)
    assert 20e3 < span[0] < 35e3 and 25e3 < span[1] < 40e3  # about 30 by 32 km
    assert 236.0 <= full.points[:, 2].min() and full.points[:, 2].max() <= 1076.0  # metres
    coast = matplotlib_dem("topobathy")
    assert coast.name == "dem/topobathy" and (coast.points[:, 2] > 0).all()
    for s in (full, coast):
        assert len(s.boundary_loops) == 1
        assert igl.is_edge_manifold(s.faces.astype(np.int64))[0]
        require_connected_disk_like(s.points, s.faces)


@pytest.mark.parametrize("kwargs", [{"name": "etopo"}, {"name": "jacksboro", "step": 0},
                                    # cut to 2, read as 1, and a bare TypeError inside float():
                                    {"name": "jacksboro", "step": 2.5}, {"name": "jacksboro", "step": True},
                                    {"name": "topobathy", "sea_level": None},
                                    {"name": "topobathy", "sea_level": float("nan")}])
def test_matplotlib_dem_refuses_what_it_does_not_know(kwargs):
    with pytest.raises(InvalidInputError):
        matplotlib_dem(**kwargs)
