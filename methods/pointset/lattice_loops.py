"""Boundary loops of a square lattice from its own cells, rebuilt from the points.

An elevation raster or a range image is a lattice, and the tools that mesh one take its
cells: a whole cell where its four grid points are there, its three-point half where one
is missing. The boundary is then the rim of those cells, a fact of the points alone. The
angle criterion reads it from geodesic balls instead, and on a ragged raster coast it can
miss: matplotlib's topobathy land (2,650 points, inlets one cell wide that the nearest
neighbours bridge here and there) closes no loop, and at every second sample (664 points,
a 139-point coast and a one-cell hole) ``ocp`` stopped with NoBoundaryError. Rebuilt from
the points, both get their mesh's loops exactly (recall and precision 1.0).

The cells come from the K nearest neighbours: a point's axis neighbours are those within
:data:`AXIS_REACH` of its nearest neighbour's distance, seen along the mean normal (a
raster's view direction) or else in the point's tangent plane, that count it as theirs
too. Two of them at right angles (:data:`RIGHT_ANGLE_COS`) span a whole cell when they
share another axis neighbour or a point stands at the cell's fourth corner (in the seeing
plane: rough heights put it off the 3D parallelogram's corner), a half cell when none
does. Half cells at a vertex where separate fans meet are dropped, as the raster mesher of
:mod:`parambench.datasets_gen.elevation` drops them. The loops are used only where the
cells make a manifold surface holding nearly every point (:data:`MIN_COVERED`) and the
lattice is square (:func:`_square`). Measured: a rough raster with lakes (height noise 0.3
steps, 8-24 lakes down to one grid point) gets recall 0.991-1.0 and precision 1.0 where
the angle criterion got 0.69-0.85; jacksboro is found along its view direction (in the
tangent planes only half its cells); on pymeshlab's knife-edged terrain at height 0.3 the
8 nearest neighbours miss axis neighbours and the cells overlap, and triangular lattices
(Loop subdivision, the generated grid samplings) are not looked at: the angle criterion's
loops stand there.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from parambench.datasets_gen.mesh_loops import mesh_boundary, pinched_vertices
from parambench.datasets_gen.repair import largest_piece

__all__ = ["AXIS_REACH", "RIGHT_ANGLE_COS", "MIN_COVERED", "lattice_cells", "lattice_loops"]

#: Axis neighbours lie within this many nearest-neighbour distances (tangent plane): a
#: rectangular raster's longer step is under 1.25 times its shorter one where its diagonal
#: (sqrt(2) times for a square one) is beyond.
AXIS_REACH = 1.25
#: Two axis directions are at right angles when the cosine between them is below this.
RIGHT_ANGLE_COS = 0.35
#: Share of the points the cells' largest piece must hold for its loops to be used.
MIN_COVERED = 0.99
#: A fourth corner is missing when no point lies within this share of the nearest-neighbour
#: distance of where it would be, in the plane the lattice is seen in.
CORNER_TOL = 0.5
#: Points looked at around a cell's fourth corner, and how far off the seeing plane (in
#: nearest-neighbour distances) the corner point may stand.
_CORNER_CANDIDATES = 16
_CORNER_HEIGHT = 4.0
#: Points whose axis neighbours are counted to tell a square lattice from a triangular one.
_SQUARE_SAMPLE = 4000
#: Rounds of dropping half cells at pinched vertices.
_PINCH_ROUNDS = 20


def lattice_cells(points: np.ndarray, normals: np.ndarray, knn_indices: np.ndarray,
                  facing: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Triangles of a square lattice's whole and half cells.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    normals : (N, 3) numpy.ndarray of float64
        Unit normals of the planes the lattice is seen in (each point's tangent plane, or
        one view direction for all).
    knn_indices : (N, K) numpy.ndarray of int64
        Nearest neighbours, nearest first, self excluded.
    facing : (N, 3) numpy.ndarray of float64, optional
        Consistently oriented normals the faces are turned to (default ``normals``).

    Returns
    -------
    faces : (M, 3) numpy.ndarray of int64
        Oriented counter-clockwise seen from the normals' side; each whole cell split
        along the diagonal from its lowest-numbered corner.
    is_half : (M,) numpy.ndarray of bool
        The faces that are half cells.
    """
    axis, offset, dist = _axis_neighbours(points, normals, knn_indices)
    near = dist[:, :1]
    # Up to 4 axis neighbours per point, nearest first (-1 padding).
    order = np.argsort(np.where(axis, dist, np.inf), axis=1, kind="stable")[:, :4]
    nbr = np.where(np.take_along_axis(axis, order, axis=1), np.take_along_axis(knn_indices, order, axis=1), -1)
    vec = np.take_along_axis(offset, order[:, :, None], axis=1)
    tree = cKDTree(points)
    whole, half = [], []
    for a, b in ((0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)):
        j, l = nbr[:, a], nbr[:, b]
        u, v = vec[:, a], vec[:, b]
        right = (j >= 0) & (l >= 0) & (np.abs(np.einsum("ni,ni->n", u, v))
                                         < RIGHT_ANGLE_COS * np.linalg.norm(u, axis=1) * np.linalg.norm(v, axis=1))
        i = np.flatnonzero(right)
        j, l = j[i], l[i]
        common = _common_neighbour(nbr, j, l, i)
        has = common >= 0
        whole.append(np.column_stack([i[has], j[has], common[has], l[has]]))
        lone = np.flatnonzero(~has)
        corner = _corner_point(points, normals, tree, i[lone], j[lone], l[lone], near[i[lone], 0])
        found = corner >= 0
        # Where the 8 nearest neighbours missed an axis relation (noisy heights), the fourth
        # corner is still there: a whole cell.
        whole.append(np.column_stack([i[lone][found], j[lone][found], corner[found], l[lone][found]]))
        missing = lone[~found]
        half.append(np.column_stack([i[missing], j[missing], l[missing]]))
    cells = _unique_cycles(np.concatenate(whole))
    halves = np.unique(np.sort(np.concatenate(half), axis=1), axis=0)
    split = np.concatenate([cells[:, [0, 1, 2]], cells[:, [0, 2, 3]]])
    covered = {tuple(t) for t in np.sort(np.concatenate([cells[:, [0, 1, 2]], cells[:, [0, 2, 3]],
                                                       cells[:, [0, 1, 3]], cells[:, [1, 2, 3]]]), axis=1).tolist()}
    halves = halves[[tuple(t) not in covered for t in halves.tolist()]] if len(halves) else halves.reshape(0, 3)
    faces = np.concatenate([split, halves]).astype(np.int64)
    is_half = np.r_[np.zeros(len(split), dtype=bool), np.ones(len(halves), dtype=bool)]
    return _facing(points, normals if facing is None else facing, faces), is_half


def lattice_loops(points: np.ndarray, normals: np.ndarray, knn_indices: np.ndarray) -> list[np.ndarray] | None:
    """The boundary loops of the lattice's cells, or None where they make no clean surface.

    Parameters
    ----------
    points, normals, knn_indices
        As :func:`lattice_cells`.

    Returns
    -------
    list of (L_i,) numpy.ndarray of int64, or None
        Loops longest first, counter-clockwise seen from the normals' side for the outer
        one and clockwise for holes; None when the cells' largest piece is not
        edge-manifold, holds under :data:`MIN_COVERED` of the points, or has no rim.

    The cells are looked for as seen along the mean normal first, then in each point's
    tangent plane.
    """
    mean = normals.sum(axis=0)
    if np.linalg.norm(mean) > 0:
        # A raster's or a range image's lattice is regular seen along its view direction,
        # which the mean normal approximates; in each point's own tangent plane a slope
        # stretches it (jacksboro: half its cells found).
        view = np.broadcast_to(mean / np.linalg.norm(mean), normals.shape)
        seen = _loops_of_cells(points, normals, knn_indices, view)
        if seen is not None:
            return seen
    return _loops_of_cells(points, normals, knn_indices, normals)


def _loops_of_cells(points: np.ndarray, normals: np.ndarray, knn_indices: np.ndarray,
                    view: np.ndarray) -> list[np.ndarray] | None:
    """:func:`lattice_loops` with the cells found in the planes normal to ``view`` (N, 3)."""
    n = points.shape[0]
    if not _square(points, view, knn_indices):
        return None
    faces, is_half = lattice_cells(points, view, knn_indices, facing=normals)
    for _ in range(_PINCH_ROUNDS):
        pinched = pinched_vertices(faces, n)
        drop = is_half & np.isin(faces, pinched).any(axis=1)
        if not drop.any():
            break
        faces, is_half = faces[~drop], is_half[~drop]
    if len(faces) == 0:
        return None
    faces, _ = largest_piece(faces, n)
    if np.unique(faces).size < MIN_COVERED * n or len(pinched_vertices(faces, n)):
        return None
    loops, _ = mesh_boundary(faces, n)
    if not loops:
        return None
    return sorted(loops, key=len, reverse=True)


def _axis_neighbours(points: np.ndarray, normals: np.ndarray, knn_indices: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(N, K) axis-neighbour mask, (N, K, 3) offsets in the planes normal to ``normals`` and
    (N, K) their lengths."""
    offset, dist = _plane_offsets(points, normals, knn_indices, np.arange(points.shape[0]))
    return _mutual(knn_indices, _within_reach(dist)), offset, dist


def _square(points: np.ndarray, normals: np.ndarray, knn_indices: np.ndarray) -> bool:
    """Whether the points of a seeded sample that have the most neighbours within axis
    reach (the 90th percentile) have 4 (a square lattice's inside; a triangular one's has
    6): the cells are only looked for then."""
    n = points.shape[0]
    rows = np.arange(n) if n <= _SQUARE_SAMPLE else np.random.default_rng(0).choice(n, _SQUARE_SAMPLE, replace=False)
    _, dist = _plane_offsets(points, normals, knn_indices, rows)
    # Inside, not the median: a small raster's rim points (2-3 axis neighbours) can be half of it.
    return bool(np.percentile(_within_reach(dist).sum(axis=1), 90) == 4)


def _plane_offsets(points: np.ndarray, normals: np.ndarray, knn_indices: np.ndarray, rows: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray]:
    """(R, K, 3) offsets of the ``rows``' neighbours in the planes normal to their
    ``normals``, and (R, K) their lengths."""
    offset = points[knn_indices[rows]] - points[rows, None, :]
    offset -= np.einsum("nki,ni->nk", offset, normals[rows])[:, :, None] * normals[rows, None, :]
    return offset, np.linalg.norm(offset, axis=2)


def _within_reach(dist: np.ndarray) -> np.ndarray:
    """(R, K) bool: the neighbours within :data:`AXIS_REACH` of each row's nearest."""
    return dist <= AXIS_REACH * dist.min(axis=1, keepdims=True)


def _mutual(knn_indices: np.ndarray, chosen: np.ndarray) -> np.ndarray:
    """``chosen`` where the neighbour chose the point too."""
    n = knn_indices.shape[0]
    rows = np.repeat(np.arange(n), knn_indices.shape[1])
    flat = chosen.ravel()
    key = rows[flat] * np.int64(n) + knn_indices.ravel()[flat]
    back = knn_indices.ravel()[flat] * np.int64(n) + rows[flat]
    out = np.zeros(chosen.size, dtype=bool)
    out[np.flatnonzero(flat)] = np.isin(back, key)
    return out.reshape(chosen.shape)


def _corner_point(points: np.ndarray, normals: np.ndarray, tree: cKDTree, i: np.ndarray, j: np.ndarray,
                  l: np.ndarray, near: np.ndarray) -> np.ndarray:
    """The point at the fourth corner ``j + l - i`` of each cell (-1: none).

    Judged in the plane normal to ``normals[i]`` (within :data:`CORNER_TOL` of ``near``), and
    within ``near`` of that plane's height at the corner: heights of a rough raster put the
    corner point off the 3D parallelogram's fourth corner by more than the tolerance.
    """
    if i.size == 0:
        return np.empty(0, dtype=np.int64)
    k = _CORNER_CANDIDATES
    target = points[j] + points[l] - points[i]
    _, cand = tree.query(target, k=k)
    off = points[cand] - target[:, None, :]
    along = np.einsum("rki,ri->rk", off, normals[i])
    across = np.linalg.norm(off - along[:, :, None] * normals[i][:, None, :], axis=2)
    # A corner point must also stand off the plane by less than a rough raster's slopes allow.
    ok = (across <= CORNER_TOL * near[:, None]) & (np.abs(along) <= _CORNER_HEIGHT * near[:, None])
    ok &= (cand != i[:, None]) & (cand != j[:, None]) & (cand != l[:, None])
    first = np.argmax(ok, axis=1)
    return np.where(ok.any(axis=1), cand[np.arange(len(i)), first], -1)


def _common_neighbour(nbr: np.ndarray, j: np.ndarray, l: np.ndarray, i: np.ndarray) -> np.ndarray:
    """Per row, the lowest axis neighbour of both ``j`` and ``l`` other than ``i`` (-1: none)."""
    a, b = nbr[j], nbr[l]                                   # (R, 4) each
    match = (a[:, :, None] == b[:, None, :]) & (a[:, :, None] >= 0) & (a[:, :, None] != i[:, None, None])
    candidates = np.where(match.any(axis=2), a, np.iinfo(np.int64).max)
    best = candidates.min(axis=1)
    return np.where(best == np.iinfo(np.int64).max, -1, best)


def _unique_cycles(cells: np.ndarray) -> np.ndarray:
    """Whole cells (R, 4) in cyclic order, each once: rotated to start at its lowest corner
    and turned so that its second corner is the lower of that corner's two neighbours."""
    if len(cells) == 0:
        return cells.reshape(0, 4)
    start = np.argmin(cells, axis=1)
    rolled = np.take_along_axis(cells, (start[:, None] + np.arange(4)) % 4, axis=1)
    turn = rolled[:, 1] > rolled[:, 3]
    rolled[turn] = rolled[turn][:, [0, 3, 2, 1]]
    return np.unique(rolled, axis=0)


def _facing(points: np.ndarray, normals: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """``faces`` turned where their 3D normal faces away from their corners' normals."""
    p = points[faces]
    normal = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    away = np.einsum("ij,ij->i", normal, normals[faces].sum(axis=1)) < 0
    faces = faces.copy()
    faces[away] = faces[away][:, [0, 2, 1]]
    return faces
