"""Map a thinned point set, then carry the map to every point (inputs larger than memory holds).

A scan of several million points may need more memory than the machine has
(:mod:`parambench.methods.memory_budget`). Its surface is usually sampled far more finely
than its shape needs, so a well-spread subsample of it can be mapped instead
(:func:`thin_indices`: one point per occupied cell of a voxel grid, the one nearest the
cell's centre, with the cell size chosen so that at most the asked number remain), and
every point is then given the uv of its place on the subsample's mapped triangles
(:func:`extend_uv`): each point is projected onto the plane of each triangle around its
nearest subsample point, and takes the barycentric combination of the corners' uv in the
triangle that holds it best (the least negative barycentric coordinate; slightly negative
just outside the subsample's rim, where the map is carried on linearly). A map that is
linear over each triangle is reproduced exactly (a plane's), and the extension adds no
fold the subsample's triangles do not have.

Thinning can lose a hole: one a few subsample spacings across closes up in the subsample,
whose map then treats it as surface and passes its own check. :func:`uncovered_spans`
looks for that after the fact, in the full points: probes on the subsample's triangles
(each centroid and edge midpoint) far from every input point, in units of the input's
local spacing, set against the typical probe of the same map (a random sampling's own
voids reach 2 spacings, a regular one's about 1).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from parambench.datasets_gen.errors import InvalidInputError

__all__ = ["thin_indices", "extend_uv", "uncovered_spans", "carry_map", "map_through_subsample", "CarriedMap",
           "SubsampleMap", "EXTENSION_CHUNK", "LOST_HOLE_OUTLIER"]

#: Points extended per block (bounds the work arrays: 100k points with 16 candidate
#: triangles each hold about 0.5 GB of float64 temporaries).
EXTENSION_CHUNK = 100_000

#: Candidate triangles per point: those around its nearest subsample point, up to this many.
_MAX_FAN = 16

#: A probe of the subsample's triangles this many times farther from every input point
#: (in local spacings) than the typical probe marks a region the input leaves empty: a
#: hole the subsample lost. Measured (largest probe over the typical one): maps of intact
#: subsamples (random, graded, blue-noise, jittered generated surfaces at 20k-1M points
#: thinned to 10-50 %; real scans lidar-ground, meg-helmet, lilium, bump-domain thinned to
#: 35-50 %) 1.02-1.44; lost holes (lidar-ground's at 25 % and 35 %, a plane's hole 2-4 grid
#: steps in radius at 25-50 %, jittered or random) 1.64-3.54.
LOST_HOLE_OUTLIER = 1.6
#: ... and at least this many local spacings from every input point (an absolute floor: a
#: regular sampling's typical probe is 0.6-0.9 of a spacing, a jittered grid's 0.7).
_LOST_HOLE_FLOOR = 1.0
#: The typical probe is the quantile that leaves out this many probes (at most 1 in 1,000),
#: so a lost hole's own few probes do not raise it.
_TAIL_PROBES = 20
#: Neighbours whose mean distance is a point's local spacing (the front end's default k_nn).
_SPACING_NEIGHBOURS = 8


def _voxel_keys(points: np.ndarray, size: float) -> np.ndarray:
    cells = np.floor((points - points.min(axis=0)) / size).astype(np.int64)
    span = cells.max(axis=0) + 1
    return (cells[:, 0] * span[1] + cells[:, 1]) * span[2] + cells[:, 2]


def _count_cells(points: np.ndarray, size: float) -> int:
    return int(np.unique(_voxel_keys(points, size)).size)


def thin_indices(points: np.ndarray, max_points: int) -> np.ndarray:
    """Indices of at most ``max_points`` well-spread points: one per voxel, nearest its centre.

    The voxel size is found by bisection on the number of occupied cells (every cell
    holds a point of the result), so the result is deterministic and holds between about
    0.9 ``max_points`` and ``max_points`` points on a surface sampled more finely than that.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    max_points : int
        At least 3.

    Returns
    -------
    (M,) numpy.ndarray of int64
        Sorted indices, M <= max_points; all of ``range(N)`` when N <= max_points.

    Raises
    ------
    InvalidInputError
        ``max_points`` below 3.
    """
    pts = np.asarray(points, dtype=np.float64)
    n = pts.shape[0]
    if int(max_points) != max_points or max_points < 3:
        raise InvalidInputError(f"max_points must be a whole number of at least 3, got {max_points}.")
    if n <= max_points:
        return np.arange(n, dtype=np.int64)
    extent = float(np.ptp(pts, axis=0).max())
    if not extent > 0.0:
        return np.arange(max_points, dtype=np.int64)  # all one point: the method refuses it
    lo, hi = 0.0, 2.0 * extent  # cells of size `hi` hold few enough points (one cell here); of size `lo`, too many
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        if mid <= 0.0:
            break
        count = _count_cells(pts, mid)
        if count > max_points:
            lo = mid
        else:
            hi = mid
            if count >= 0.97 * max_points:
                break
    size = hi
    keys = _voxel_keys(pts, size)
    centre = (np.floor((pts - pts.min(axis=0)) / size) + 0.5) * size + pts.min(axis=0)
    dist = ((pts - centre) ** 2).sum(axis=1)
    order = np.lexsort((np.arange(n), dist, keys))  # per cell: nearest the centre, then lowest index
    first = np.ones(n, dtype=bool)
    first[1:] = keys[order][1:] != keys[order][:-1]
    return np.sort(order[first])


def _vertex_faces(faces: np.ndarray, n_vertices: int) -> np.ndarray:
    """(V, _MAX_FAN) triangles around each vertex, -1 where there are fewer."""
    rows = faces.ravel()
    cols = np.repeat(np.arange(faces.shape[0]), 3)
    incidence = sp.csr_matrix((np.ones(rows.size, dtype=np.int8), (rows, cols)), shape=(n_vertices, faces.shape[0]))
    out = np.full((n_vertices, _MAX_FAN), -1, dtype=np.int64)
    per_row = np.diff(incidence.indptr)
    slot = np.arange(rows.size) - np.repeat(incidence.indptr[:-1], per_row)
    keep = slot < _MAX_FAN
    out[np.repeat(np.arange(n_vertices), per_row)[keep], slot[keep]] = incidence.indices[keep]
    return out


def extend_uv(points: np.ndarray, sub: np.ndarray, sub_uv: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, dict]:
    """uv of every point from a subsample's map, barycentric on the subsample's mapped triangles.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
        All points.
    sub : (M,) numpy.ndarray of int64
        Indices of the subsample into ``points``.
    sub_uv : (M, 2) numpy.ndarray of float64
        The subsample's map.
    faces : (F, 3) numpy.ndarray of int64
        Triangles over the subsample (indices into ``sub``), e.g. the self-check's uv
        triangulation (:func:`parambench.methods.pointset.selfcheck.pointset_faces`).

    Returns
    -------
    uv : (N, 2) numpy.ndarray of float64
        Subsample points keep their uv exactly.
    facts : dict
        ``offset_spacings``: the median and largest distance of the points from the plane
        of the triangle that carries them, in the subsample's median edge lengths;
        ``n_outside``: points beyond every candidate triangle by more than a tenth of its
        size (most negative barycentric coordinate below -0.1: past the subsample's rim);
        ``n_untriangulated``: points whose nearest subsample point is in no triangle (they
        take its uv).

    Raises
    ------
    InvalidInputError
        Shapes that disagree, or no triangles.
    """
    pts = np.asarray(points, dtype=np.float64)
    sub = np.asarray(sub, dtype=np.int64)
    sub_uv = np.asarray(sub_uv, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    if sub_uv.shape != (sub.size, 2) or faces.ndim != 2 or faces.shape[1:] != (3,) or faces.shape[0] == 0:
        raise InvalidInputError("extend_uv needs (M,) subsample indices, their (M, 2) uv and (F, 3) triangles over them.")
    q = pts[sub]
    fan = _vertex_faces(faces, sub.size)
    edge = np.median(np.linalg.norm(q[faces[:, 0]] - q[faces[:, 1]], axis=1))
    tree = cKDTree(q)
    uv = np.empty((pts.shape[0], 2))
    offsets = np.empty(pts.shape[0])
    n_outside = n_untriangulated = 0
    for start in range(0, pts.shape[0], EXTENSION_CHUNK):
        block = pts[start:start + EXTENSION_CHUNK]
        _, near = tree.query(block, k=1, workers=-1)
        cand = fan[near]  # (B, _MAX_FAN)
        valid = cand >= 0
        tri = faces[np.where(valid, cand, 0)]  # (B, K, 3)
        a, b, c = q[tri[..., 0]], q[tri[..., 1]], q[tri[..., 2]]
        e1, e2, d = b - a, c - a, block[:, None, :] - a
        d11, d12, d22 = (e1 * e1).sum(-1), (e1 * e2).sum(-1), (e2 * e2).sum(-1)
        r1, r2 = (d * e1).sum(-1), (d * e2).sum(-1)
        det = d11 * d22 - d12 * d12
        with np.errstate(divide="ignore", invalid="ignore"):
            w1 = (d22 * r1 - d12 * r2) / det
            w2 = (d11 * r2 - d12 * r1) / det
        w0 = 1.0 - w1 - w2
        worst = np.minimum(np.minimum(w0, w1), w2)
        worst = np.where(valid & (det > 0) & np.isfinite(worst), worst, -np.inf)
        best = np.argmax(worst, axis=1)
        rows = np.arange(block.shape[0])
        t = tri[rows, best]
        bw = np.stack([w0[rows, best], w1[rows, best], w2[rows, best]], axis=1)
        normal = np.cross(e1[rows, best], e2[rows, best])
        with np.errstate(divide="ignore", invalid="ignore"):
            normal /= np.linalg.norm(normal, axis=1, keepdims=True)
        here = slice(start, start + block.shape[0])
        uv[here] = np.einsum("bk,bkd->bd", bw, sub_uv[t])
        offsets[here] = np.abs((d[rows, best] * normal).sum(-1)) / edge
        lone = ~np.isfinite(worst[rows, best])
        if lone.any():
            uv[here][lone] = sub_uv[near[lone]]
            offsets[here][lone] = np.linalg.norm(block[lone] - q[near[lone]], axis=1) / edge
        n_untriangulated += int(np.count_nonzero(lone))
        n_outside += int(np.count_nonzero(worst[rows, best] < -0.1) - np.count_nonzero(lone))
    uv[sub] = sub_uv
    offsets[sub] = 0.0
    return uv, {"offset_spacings": {"median": float(np.median(offsets)), "max": float(offsets.max())},
                "n_outside": n_outside, "n_untriangulated": n_untriangulated}


def uncovered_spans(points: np.ndarray, sub: np.ndarray, faces: np.ndarray) -> dict:
    """Where the subsample's triangles span a region the input points leave empty.

    Each triangle is probed at its centroid and its edge midpoints; a probe's gap is its
    distance to the nearest input point over the mean local spacing of the triangle's
    corners (the mean distance to their :data:`_SPACING_NEIGHBOURS` nearest input
    points). Where the input covers the triangle every probe has an input point within
    about one spacing; a triangle across a hole of the input that the subsample closed
    has probes as far from every point as the hole is wide.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
        All the input points.
    sub : (M,) numpy.ndarray of int64
        Indices of the subsample into ``points``.
    faces : (F, 3) numpy.ndarray of int64
        Triangles over the subsample (indices into ``sub``), F >= 1.

    Returns
    -------
    dict
        ``gap_spacings``: ``{"typical": ..., "max": ...}``, the typical probe's gap (the
        quantile leaving out :data:`_TAIL_PROBES` probes, at most 1 in 1,000) and the
        largest, in local spacings; ``lost_hole``: the largest is at least
        :data:`LOST_HOLE_OUTLIER` times the typical one and at least one spacing;
        ``n_spanning_faces``: triangles with a probe past that limit, and ``spanning``, a
        (F,) numpy.ndarray of bool marking them (all False where no hole was lost);
        ``where``: the 3D position of the largest gap's probe, a list of three floats.
    """
    pts = np.asarray(points, dtype=np.float64)
    q = pts[np.asarray(sub, dtype=np.int64)]
    faces = np.asarray(faces, dtype=np.int64)
    tree = cKDTree(pts)
    near, _ = tree.query(q, k=_SPACING_NEIGHBOURS + 1, workers=-1)
    spacing = near[:, 1:].mean(axis=1)[faces].mean(axis=1)
    corners = q[faces]
    probes = [corners.mean(axis=1)] + [0.5 * (corners[:, i] + corners[:, (i + 1) % 3]) for i in range(3)]
    gaps = np.column_stack([tree.query(p, workers=-1)[0] for p in probes]) / spacing[:, None]  # (F, 4)
    level = max(0.999, 1.0 - _TAIL_PROBES / gaps.size)
    typical = float(np.quantile(gaps, level))
    worst = np.unravel_index(int(np.argmax(gaps)), gaps.shape)
    largest = float(gaps[worst])
    limit = max(LOST_HOLE_OUTLIER * typical, _LOST_HOLE_FLOOR)
    spanning = (gaps >= limit).any(axis=1)
    return {"gap_spacings": {"typical": typical, "max": largest}, "lost_hole": bool(largest >= limit),
            "n_spanning_faces": int(np.count_nonzero(spanning)), "spanning": spanning,
            "where": [float(x) for x in probes[worst[1]][worst[0]]]}


class CarriedMap(NamedTuple):
    """A subsample's map carried to every point (:func:`carry_map`).

    Attributes
    ----------
    uv : (N, 2) numpy.ndarray of float64
        Every point's uv (:func:`extend_uv`).
    faces : (F, 3) numpy.ndarray of int64
        The subsample's uv triangles, as rows of all the points.
    facts : dict
        :func:`extend_uv`'s facts.
    spans : dict
        :func:`uncovered_spans` of those triangles (``spans["lost_hole"]``).
    """

    uv: np.ndarray
    faces: np.ndarray
    facts: dict
    spans: dict


def carry_map(points: np.ndarray, sub: np.ndarray, sub_uv: np.ndarray, loops: list | None) -> CarriedMap:
    """Carry a subsample's map to every point, and check the points cover its triangles.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
        All the points.
    sub : (M,) numpy.ndarray of int64
        Indices of the subsample into ``points``.
    sub_uv : (M, 2) numpy.ndarray of float64
        The subsample's map.
    loops : list of (L_i,) array_like of int, or None
        The subsample's boundary loops (indices into ``sub``; a point-set result's
        ``diagnostics["boundary_loops"]``): its uv triangles leave their holes empty
        (:func:`parambench.methods.pointset.selfcheck.pointset_faces`).

    Returns
    -------
    CarriedMap

    Raises
    ------
    InvalidInputError
        The subsample's uv points cannot be triangulated (a collapsed map).
    """
    from .selfcheck import pointset_faces

    pts = np.asarray(points, dtype=np.float64)
    sub = np.asarray(sub, dtype=np.int64)
    sub_faces = pointset_faces(pts[sub], sub_uv, loops)
    uv, facts = extend_uv(pts, sub, sub_uv, sub_faces)
    return CarriedMap(uv, sub[sub_faces], facts, uncovered_spans(pts, sub, sub_faces))


class SubsampleMap(NamedTuple):
    """A point set mapped through a subsample (:func:`map_through_subsample`).

    Attributes
    ----------
    subsample : (M,) numpy.ndarray of int64
        Indices of the mapped points (all of them when there were no more than asked).
    result : MethodResult
        The method's result on the subsample (its ``diagnostics["selfcheck"]``).
    carried : CarriedMap or None
        Every point's uv; None where the subsample's map failed its self-check or the
        points were not thinned.
    """

    subsample: np.ndarray
    result: Any
    carried: CarriedMap | None

    @property
    def uv(self) -> np.ndarray | None:
        """(N, 2) uv of every point (None where the subsample's map failed its self-check)."""
        if self.carried is not None:
            return self.carried.uv
        return self.result.uv if self.passed else None

    @property
    def passed(self) -> bool:
        """The subsample's map passed its self-check and no hole of the points was lost."""
        check = self.result.diagnostics.get("selfcheck") or {}
        return bool(check.get("passed", True)) and not (self.carried is not None and self.carried.spans["lost_hole"])


def map_through_subsample(method: Any, points: np.ndarray, max_points: int, *, normals: np.ndarray | None = None,
                          **params: Any) -> SubsampleMap:
    """Map at most ``max_points`` well-spread points with a point-set method, then carry the map to all.

    What ``parambench flatten --max-points`` does, from Python: :func:`thin_indices`, the
    method on the subsample, and, where its map passes its self-check, :func:`carry_map`.

    Parameters
    ----------
    method : str or Method
        A point-set method (e.g. ``"ocp"``).
    points : (N, 3) array_like of float
    max_points : int
        At least 3.
    normals : (N, 3) array_like of float, optional
        Unit normals, when they are data.
    **params
        The method's parameters.

    Returns
    -------
    SubsampleMap
        ``.uv`` and ``.passed``: check ``passed`` before using the map.

    Raises
    ------
    InvalidInputError
        ``max_points`` below 3, or a method that needs faces.
    ParambenchError
        Whatever the method raises on the subsample.
    """
    from parambench.datasets_gen.surface import MethodInput

    from ..registry import get_method

    method = get_method(method) if isinstance(method, str) else method
    if method.needs_faces:
        raise InvalidInputError(f"method {method.name!r} needs faces; a subsample is a point set (e.g. use ocp).")
    pts = np.asarray(points, dtype=np.float64)
    keep = thin_indices(pts, max_points)
    given = None if normals is None else np.asarray(normals, dtype=np.float64)[keep]
    result = method(MethodInput(pts[keep], normals=given), **params)
    thinned = keep.size < pts.shape[0]
    check = result.diagnostics.get("selfcheck") or {}
    carried = (carry_map(pts, keep, result.uv, result.diagnostics.get("boundary_loops"))
               if thinned and check.get("passed", True) else None)
    return SubsampleMap(keep, result, carried)
