"""A reference triangulation for the points of a height field: a terrain scan's ground truth.

Airborne LiDAR keeps points, not faces. Its ground returns (class 2 of a LAS file) sample a
height field z(x, y), so their surface is the Delaunay triangulation in the xy plane, less
what is not ground: the convex hull's fringe beyond the ragged rim, and the voids where no
return came back (under a building, a parked car, a pond). That triangulation is what a
benchmark needs to score a point-set method on such data: mesh baselines (``scp-igl``) run
on it, foldovers and QC are counted on it, and its loops are the boundary to find.

Construction, in the xy plane:

- Voids: edge-connected groups of at least :data:`VOID_MIN_TRIANGLES` Delaunay triangles
  whose 3D circumradius exceeds :data:`VOID_RADIUS_SPACINGS` mean spacings, not touching
  the hull, are opened as holes. A scan line's nearly collinear neighbours make single
  slivers of large circumradius (up to 10 spacings on the shipped tile), which are no void;
  the tile's hole spans 15 such triangles, its other gaps at most 1.
- Rim: the hull's slivers are peeled from outside as an alpha shape would
  (:func:`parambench.datasets_gen.scattered.peel_rim`, at the scattered meshes' radius).
- Pinched vertices keep their largest fan, the largest piece is kept, and points in no
  triangle are left out (returns stacked above each other: Delaunay keeps one of an xy
  pair; none on the shipped tile).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from scipy.spatial import Delaunay, cKDTree

from .errors import InvalidInputError
from .mesh_loops import mesh_boundary, one_fan_per_vertex
from .repair import compact, largest_piece
from .scattered import PEEL_RADIUS_SPACINGS, peel_rim
from .surface import Surface, circumradii, counter_clockwise

__all__ = ["VOID_RADIUS_SPACINGS", "VOID_MIN_TRIANGLES", "height_field_surface"]

#: A triangle wider than this (circumradius, in mean nearest-neighbour spacings) may be
#: part of a void; a Delaunay triangle of the shipped tile's interior has a median of 0.92.
VOID_RADIUS_SPACINGS = 2.0

#: ... and a void holds at least this many of them, edge to edge.
VOID_MIN_TRIANGLES = 8


def height_field_surface(points: np.ndarray, name: str, params: dict | None = None) -> Surface:
    """The reference triangulation of height-field points (see the module notes).

    Parameters
    ----------
    points : (N, 3) array_like of float
        Points of a surface that is a graph over the xy plane (x, y, z in one length unit).
    name : str
    params : dict, optional
        Stored on the Surface, with ``spacing`` (mean nearest-neighbour distance of the
        points), ``n_voids`` (holes opened), ``n_dropped_faces`` and ``n_left_out`` (points
        in no kept triangle, left out of the Surface) added.

    Returns
    -------
    Surface
        The points a kept triangle uses, in input order; faces counter-clockwise seen from
        +z; boundary loops (outer rim first).

    Raises
    ------
    InvalidInputError
        Fewer than three points, non-finite coordinates, or points whose xy positions are
        all collinear.
    """
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 3 or pts.shape[0] < 3 or not np.isfinite(pts).all():
        raise InvalidInputError("a height field needs (N, 3) finite points, N >= 3.")
    spacing = float(cKDTree(pts).query(pts, k=2)[0][:, 1].mean())
    try:
        # Centred: qhull's tolerances are relative to the coordinates' magnitude, and at a
        # survey grid's (x ~ 2.4e6 ft) it merged returns 0.22-0.30 ft apart into their neighbours.
        tri = Delaunay(pts[:, :2] - pts[:, :2].mean(axis=0))
    except Exception as exc:  # qhull's own error type; collinear or too few distinct xy positions
        raise InvalidInputError(f"{name}: the points' xy positions span no area ({exc}).") from exc
    faces = counter_clockwise(pts, np.asarray(tri.simplices, dtype=np.int64))
    void, n_voids = _voids(pts, faces, np.asarray(tri.neighbors), spacing)
    faces = peel_rim(pts, faces[~void], PEEL_RADIUS_SPACINGS * spacing)
    faces = largest_piece(one_fan_per_vertex(faces, len(pts)), len(pts))[0]
    n_dropped = len(tri.simplices) - len(faces)
    kept, faces = compact(pts, faces)
    loops, mask = mesh_boundary(faces, len(kept))
    info = {**dict(params or {}), "spacing": spacing, "n_voids": n_voids, "n_dropped_faces": int(n_dropped),
            "n_left_out": int(len(pts) - len(kept))}
    return Surface(points=kept, faces=faces, name=name, params=info, boundary_loops=loops, boundary_mask=mask)


def _voids(points: np.ndarray, faces: np.ndarray, neighbours: np.ndarray, spacing: float) -> tuple[np.ndarray, int]:
    """Mask of the interior voids' triangles and their count.

    Void triangles are wide, in edge-connected groups of ``VOID_MIN_TRIANGLES`` or more,
    none of whose members lies on the hull.
    """
    wide = circumradii(points, faces) > VOID_RADIUS_SPACINGS * spacing
    rows, slots = np.nonzero((neighbours >= 0) & wide[:, None])
    cols = neighbours[rows, slots]
    joined = wide[cols]
    graph = sp.coo_matrix((np.ones(int(joined.sum())), (rows[joined], cols[joined])), shape=(len(faces),) * 2)
    _, label = connected_components(graph, directed=False)
    size = np.bincount(label[wide], minlength=label.max() + 1)
    on_hull = np.zeros(size.size, dtype=bool)
    on_hull[label[wide & (neighbours < 0).any(axis=1)]] = True
    is_void = (size >= VOID_MIN_TRIANGLES) & ~on_hull
    return wide & is_void[label], int(is_void.sum())
