"""Elevation rasters as surfaces: real digital elevation models nobody here made.

A raster (a height per cell of a regular grid, with cells left out: the sea, missing
data) is the commonest real surface after scans; as bare points it is an organised
point cloud whose rim is a lattice's staircase, unlike the smooth rims of generated
surfaces and the zigzag of cut meshes. matplotlib ships two such rasters with its sample
data (``mpl-data/sample_data``), so any machine that has matplotlib has them:

- ``jacksboro_fault_dem.npz``: 344 x 403 elevations (metres) at 3 arc-seconds (about
  92 m north-south, 74 m east-west), a hilly region; one rectangular rim.
- ``topobathy.npz``: 91 x 120 heights and depths (metres) at 1/45 by 1/30 degree (about
  2.4 km), a coast; its land (height above a sea level) has a ragged coastline with
  inlets one or two cells wide.

The mesh of a raster is every triangle the lattice supports, as organised-cloud meshers
make it (PCL's ``OrganizedFastMesh``): a cell whose four corners are kept is two
triangles, one with three kept corners is the triangle of those three. A rim is then the
lattice's outline: where a cell misses one corner the rim cuts across it, and a point at
a concave corner of the kept cells is interior. (With whole cells only, that corner is a
rim point whose open angle is 90 degrees; the points alone cannot tell the two meshes
apart.) Cells that meet only at a corner would make that vertex non-manifold: one of each
such pair is dropped, and so is a three-corner triangle at a vertex it makes
non-manifold. The largest face-connected piece is kept. Coordinates are metres in a local
equirectangular projection.
"""

from __future__ import annotations

import numpy as np

from .errors import InvalidInputError
from .mesh_loops import mesh_boundary, pinched_vertices
from .repair import compact, largest_piece
from .surface import Surface

__all__ = ["raster_surface", "matplotlib_dem", "MATPLOTLIB_DEMS"]

#: The rasters :func:`matplotlib_dem` knows: name -> file in matplotlib's sample data.
MATPLOTLIB_DEMS = {"jacksboro": "jacksboro_fault_dem.npz", "topobathy": "topobathy.npz"}

#: Metres per degree of latitude, and of longitude at the equator.
_M_PER_DEG_LAT = 110_540.0
_M_PER_DEG_LON = 111_320.0


def _without_corner_contacts(cells: np.ndarray) -> np.ndarray:
    """``cells`` with one cell of every pair that touches only at a corner dropped.

    Cell (i, j) is dropped where (i + 1, j + 1) is kept and neither (i + 1, j) nor
    (i, j + 1) is; likewise (i, j + 1) against (i + 1, j). Repeated until none is left.
    """
    cells = cells.copy()
    while True:
        a, b, c, d = cells[:-1, :-1], cells[:-1, 1:], cells[1:, :-1], cells[1:, 1:]
        main = a & d & ~b & ~c
        anti = b & c & ~a & ~d
        if not (main.any() or anti.any()):
            return cells
        cells[:-1, :-1] &= ~main
        cells[:-1, 1:] &= ~anti


def raster_surface(x: np.ndarray, y: np.ndarray, z: np.ndarray, keep: np.ndarray, name: str,
                   params: dict | None = None) -> Surface:
    """The mesh of a raster's kept grid points (see the module notes).

    Parameters
    ----------
    x, y, z : (R, C) numpy.ndarray of float64
        Coordinates of the grid points, length units.
    keep : (R, C) numpy.ndarray of bool
        Grid points that belong to the surface.
    name : str
    params : dict, optional
        Stored on the Surface.

    Returns
    -------
    Surface
        The largest face-connected piece: its points (only those a face uses), faces and
        boundary loops.

    Raises
    ------
    InvalidInputError
        When the arrays disagree in shape, hold non-finite kept values, or no cell has
        three kept corners.
    """
    x, y, z, keep = (np.asarray(v) for v in (x, y, z, keep))
    if not (x.shape == y.shape == z.shape == keep.shape) or x.ndim != 2:
        raise InvalidInputError(f"x, y, z and keep must be 2D arrays of one shape (got {x.shape}, {y.shape}, "
                                f"{z.shape}, {keep.shape}).")
    points = np.column_stack([x.ravel(), y.ravel(), z.ravel()]).astype(np.float64)
    keep = keep.astype(bool)
    if not np.isfinite(points[keep.ravel()]).all():
        raise InvalidInputError("the kept grid points hold NaN or infinite coordinates; leave them out with keep.")
    cells = _without_corner_contacts(keep[:-1, :-1] & keep[:-1, 1:] & keep[1:, :-1] & keep[1:, 1:])
    index = np.arange(keep.size).reshape(keep.shape)
    # Corners of each cell in cyclic order; a triangle of three of them keeps that order,
    # so every face is oriented alike.
    corners = np.stack([index[:-1, :-1], index[:-1, 1:], index[1:, 1:], index[1:, :-1]], axis=-1)
    kept = keep.ravel()[corners]
    p, q, r, t = (corners[cells][:, c] for c in range(4))
    whole = np.concatenate([np.column_stack([p, q, r]), np.column_stack([p, r, t])])
    three = kept.sum(axis=-1) == 3
    tri = corners[three]
    # Drop the one missing corner, keeping the cyclic order of the other three.
    order = np.argsort(~kept[three], axis=1, kind="stable")[:, :3]
    half = np.take_along_axis(tri, order, axis=1)
    faces = np.concatenate([whole, half])
    is_half = np.arange(len(faces)) >= len(whole)
    while True:
        bad = pinched_vertices(faces, keep.size)
        drop = is_half & np.isin(faces, bad).any(axis=1)
        if not drop.any():
            break
        faces, is_half = faces[~drop], is_half[~drop]
    if len(faces) == 0:
        raise InvalidInputError("no grid cell has three or four corners kept: the raster has no surface.")
    points, faces = compact(points, largest_piece(faces, len(points))[0])
    loops, mask = mesh_boundary(faces, len(points))
    return Surface(points=points, faces=faces, name=name, params=dict(params or {}),
                   boundary_loops=loops, boundary_mask=mask)


def matplotlib_dem(name: str, step: int = 1, sea_level: float = 0.0) -> Surface:
    """One of the elevation rasters in matplotlib's sample data as a Surface.

    Parameters
    ----------
    name : {"jacksboro", "topobathy"}
        ``jacksboro``: the whole raster; ``topobathy``: its land, the grid points higher
        than ``sea_level``.
    step : int
        Keep every ``step``-th row and column (1: the full raster, 138,632 points for
        jacksboro, 2,633 for topobathy's land).
    sea_level : float
        Metres; topobathy only.

    Returns
    -------
    Surface
        Named ``dem/{name}`` (with ``-s{step}`` for ``step > 1``, ``-sea{level}`` for a
        sea level other than 0); coordinates in metres, faces and boundary loops.

    Raises
    ------
    InvalidInputError
        For an unknown name, a step that is not a whole number of at least 1, or a sea level
        that is not a finite number.
    """
    from matplotlib import cbook

    if name not in MATPLOTLIB_DEMS:
        raise InvalidInputError(f"unknown DEM {name!r}; known: {', '.join(MATPLOTLIB_DEMS)}.")
    # step=2.5 was cut to 2 and step=True read as 1; sea_level=None failed inside float().
    if isinstance(step, bool) or not isinstance(step, (int, np.integer)) or step < 1:
        raise InvalidInputError(f"step={step!r} must be a whole number of at least 1.")
    if isinstance(sea_level, bool) or not isinstance(sea_level, (int, float, np.number)) \
            or not np.isfinite(sea_level):
        raise InvalidInputError(f"sea_level={sea_level!r} must be a finite number of metres.")
    step = int(step)
    data = np.load(cbook.get_sample_data(MATPLOTLIB_DEMS[name], asfileobj=False))
    if name == "jacksboro":
        z = data["elevation"].astype(np.float64)
        lat = 0.5 * (float(data["ymin"]) + float(data["ymax"]))
        dx = float(data["dx"]) * _M_PER_DEG_LON * np.cos(np.radians(lat))
        dy = float(data["dy"]) * _M_PER_DEG_LAT
        x, y = np.meshgrid(np.arange(z.shape[1]) * dx, np.arange(z.shape[0]) * dy)
        keep = np.ones(z.shape, dtype=bool)
    else:
        z = data["topo"].astype(np.float64)
        lon, lat = data["longitude"].astype(np.float64), data["latitude"].astype(np.float64)
        x, y = np.meshgrid((lon - lon[0]) * _M_PER_DEG_LON * np.cos(np.radians(lat.mean())),
                           (lat - lat[0]) * _M_PER_DEG_LAT)
        keep = z > sea_level
    x, y, z, keep = (v[::step, ::step] for v in (x, y, z, keep))
    label = f"dem/{name}" + (f"-s{step}" if step > 1 else "") + (
        f"-sea{sea_level:g}" if name == "topobathy" and sea_level != 0 else "")
    return raster_surface(x, y, z, keep, label, {"step": step, "sea_level": float(sea_level)})
