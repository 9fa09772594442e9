"""Do the triangles of neighbouring points keep their orientation in uv?

The self-check triangulates the uv points (:mod:`.uv_triangulation`) and judges those
triangles; that triangulation is free to pick, of two triangles sharing a quad, the
diagonal along which the map is still consistent. A map can invert a well-shaped triangle
of neighbouring points and pass: ``ocp`` on ``plane`` (2k points, ``graded``, seed 1)
pulled a boundary point into a spike, the true-mesh triangle beside it folded, and the uv
Delaunay triangles round the spike all kept their orientation.

This test reads each point's one-ring in the Delaunay triangulation of its k nearest
neighbours on its own tangent plane
(:func:`~parambench.methods.pointset.local_delaunay.local_delaunay_rings`; at boundary
points only the triangles on the surface's side,
:func:`~parambench.methods.pointset.local_delaunay.drop_outside_boundary`). Each ring
triangle is counter-clockwise about its centre's normal; a map without folds that is
nearly affine across a triangle keeps that sign (an affine map with a positive
determinant keeps every triangle's). A ring triangle is judged only where its sign is
known:

* it is well shaped and counter-clockwise for each of its three corners' normals: quality
  (area over squared longest edge, on that normal's plane; equilateral 0.43) at least
  ``RING_QUALITY`` = 0.1 for every reference normal within the normals' tolerance (the
  self-check's ``normal_tol_deg``). One normal's error cannot make the verdict: the exact
  map of a jittered grid with normal noise of 0.5 spacings, judged with plain 8-point PCA
  normals (18 degrees mean error) on its centres' normals alone, had 2-5 reversed
  triangles on 4 of 5 seeds;
* its corners' normals lie within ``RING_NORMAL_DEG`` = 60 degrees of the centre's. Where
  they differ more the points do not resolve the surface (a fingertip thinner than the
  sampling, a crease), and neither the triangle's sign nor the map's is known there;
* no edge is longer than the self-check's ``BRIDGE_FACTOR`` local spacings, and its uv
  area is above the self-check's zero-area threshold (a collapsed triangle has no sign).

It counts as reversed only when clearly so: quality at most ``-RING_REVERSAL`` = -0.02 in
uv (the same grid's one remaining false alarm, seed 3, was a 3D sliver stood up by a noise
spike, -0.017 in uv; the graded plane's fold -0.10).

Measured on ``ocp`` with default parameters (the check then retries): the 11 generated
surfaces random, graded and jittered at 2k and 3k points, seeds 0-2 (198 maps), 196 give
the same map as without this test; the graded plane above now retries with 12 neighbours
(QC 1.0000, 0 foldovers, was 1.038 and 1 foldover, passed), and ``fold`` graded 3k seed 1
keeps another map (fails either way: 4 foldovers -> 0). At normal noise 0.25 and 0.5
spacings (2k, random and jittered, seeds 0-2, 132 maps) and on 40 real meshes scattered at
5k and 20k every map is unchanged. On the real-data benchmark (84 cases) only pymeshlab's
fractal terrain h0.3 seed 1 changed: it fails on 6 flipped uv triangles either way (0
true-mesh foldovers, a knife-edge ridge) and got 1 reversed ring triangle more. Not seen:
folds where the normals disagree (``protrusions``' fingertips) and folds of true-mesh
slivers (under noise the folded triangles' quality is 0.002-0.08, the median one's 0.21),
which no triangle of neighbouring points that is judged here contains. Cost at 1M points
(a random height field, 8 neighbours, 2 cores): 1.4 s on a quiet machine, 0.9 of them the
one-rings (3.5 s with the cores shared).
"""

from __future__ import annotations

from pathlib import Path

import numba
import numpy as np

from ..numba_cache import configure_numba_cache
from .local_delaunay import drop_outside_boundary, local_delaunay_rings
from .row_chunks import for_each_chunk

__all__ = ["ring_orientation", "unresolved_points", "RING_QUALITY", "RING_NORMAL_DEG", "RING_REVERSAL"]

_CACHE, _ = configure_numba_cache(Path(__file__).resolve().parent)

#: Least quality (area / longest edge squared) of a judged triangle on each corner normal's plane.
RING_QUALITY = 0.1

#: Largest angle between a judged triangle's corner normals and its centre's, degrees.
RING_NORMAL_DEG = 60.0

#: Least quality in uv of a reversed triangle that counts (a sliver's sign is the noise's).
RING_REVERSAL = 0.02

#: Centres per call of the compiled kernel (calls run on worker threads).
_CHUNK = 65536

#: Verdicts of :func:`_judge_rings` per ring slot.
_EMPTY, _KEPT, _REVERSED = 0, 1, 2


@numba.njit(cache=_CACHE, nogil=True)
def _shaped_for(nx, ny, nz, p, unit, sin_tol, q_min):
    """The triangle ``p`` (3 x 3), of 3D normal ``(nx, ny, nz)`` (twice its area), is
    counter-clockwise about ``unit`` with quality >= ``q_min`` on ``unit``'s plane, for
    every reference normal within the tolerance (``sin_tol``): the self-check's tangent-plane
    sliver test (``selfcheck._tangent_sliver``, the same wobble bound) for one triangle and
    one normal, compiled."""
    area = 0.5 * (nx * unit[0] + ny * unit[1] + nz * unit[2])
    cx = ny * unit[2] - nz * unit[1]
    cy = nz * unit[0] - nx * unit[2]
    cz = nx * unit[1] - ny * unit[0]
    wobble = 0.5 * np.sqrt(cx * cx + cy * cy + cz * cz) * sin_tol
    longest = 0.0
    for k in range(3):
        dx = p[(k + 1) % 3, 0] - p[k, 0]
        dy = p[(k + 1) % 3, 1] - p[k, 1]
        dz = p[(k + 1) % 3, 2] - p[k, 2]
        along = dx * unit[0] + dy * unit[1] + dz * unit[2]
        sq = dx * dx + dy * dy + dz * dz - along * along  # on the plane
        longest = max(longest, sq)
    return area - wobble >= q_min * longest


@numba.njit(cache=_CACHE, nogil=True, inline="always")
def _cosine(normals, a, b):
    """Cosine between the unit normals of points a and b."""
    return normals[a, 0] * normals[b, 0] + normals[a, 1] * normals[b, 1] + normals[a, 2] * normals[b, 2]


@numba.njit(cache=_CACHE, nogil=True)
def _judge_rings(lo, hi, points, uv, normals, rings, spacing, sin_tol, cos_max, q_min, reversal, sign,
                 min_uv_area, bridge, out):
    """``out[i, t]``: ``_EMPTY`` (no triangle, or not judged), ``_KEPT`` or ``_REVERSED``."""
    p = np.empty((3, 3))
    for i in range(lo, hi):
        for t in range(rings.shape[1]):
            out[i, t] = _EMPTY
            a, b = rings[i, t, 0], rings[i, t, 1]
            if a < 0:
                continue
            corners = (i, a, b)
            for k in range(3):
                for d in range(3):
                    p[k, d] = points[corners[k], d]
            if _cosine(normals, a, i) < cos_max or _cosine(normals, b, i) < cos_max:
                continue
            reach = bridge * (spacing[i] + spacing[a] + spacing[b]) / 3.0
            too_long = False
            for k in range(3):
                dx = p[(k + 1) % 3, 0] - p[k, 0]
                dy = p[(k + 1) % 3, 1] - p[k, 1]
                dz = p[(k + 1) % 3, 2] - p[k, 2]
                too_long = too_long or dx * dx + dy * dy + dz * dz > reach * reach
            if too_long:
                continue
            e1x, e1y, e1z = p[1, 0] - p[0, 0], p[1, 1] - p[0, 1], p[1, 2] - p[0, 2]
            e2x, e2y, e2z = p[2, 0] - p[0, 0], p[2, 1] - p[0, 1], p[2, 2] - p[0, 2]
            nx, ny, nz = e1y * e2z - e1z * e2y, e1z * e2x - e1x * e2z, e1x * e2y - e1y * e2x
            # One corner normal's error (noise) must not make the verdict: every corner's.
            if not (_shaped_for(nx, ny, nz, p, normals[i], sin_tol, q_min)
                    and _shaped_for(nx, ny, nz, p, normals[a], sin_tol, q_min)
                    and _shaped_for(nx, ny, nz, p, normals[b], sin_tol, q_min)):
                continue
            ux1, uy1 = uv[a, 0] - uv[i, 0], uv[a, 1] - uv[i, 1]
            ux2, uy2 = uv[b, 0] - uv[i, 0], uv[b, 1] - uv[i, 1]
            uv_area = 0.5 * (ux1 * uy2 - uy1 * ux2) * sign
            if abs(uv_area) <= min_uv_area:
                continue
            ux3, uy3 = uv[b, 0] - uv[a, 0], uv[b, 1] - uv[a, 1]
            longest_uv = max(ux1 * ux1 + uy1 * uy1, ux2 * ux2 + uy2 * uy2, ux3 * ux3 + uy3 * uy3)
            out[i, t] = _REVERSED if uv_area < -reversal * longest_uv else _KEPT


def ring_orientation(points: np.ndarray, uv: np.ndarray, normals: np.ndarray, knn_indices: np.ndarray,
                     loops: list, spacing_pt: np.ndarray, *, tol_deg: float, mirrored: bool,
                     min_uv_area: float, bridge_factor: float) -> tuple[dict, np.ndarray]:
    """Count the well-shaped triangles of neighbouring points whose orientation the map reverses.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    uv : (N, 2) numpy.ndarray of float64
    normals : (N, 3) numpy.ndarray of float64
        Unit normals, oriented consistently (the front end's).
    knn_indices : (N, K) numpy.ndarray of int64
        Each point's nearest neighbours (itself excluded).
    loops : list of (L_i,) array_like of int
        Detected boundary loops; may be empty.
    spacing_pt : (N,) numpy.ndarray of float64
        Local spacing per point (mean distance to its neighbours).
    tol_deg : float
        The normals' error, degrees: a triangle must keep its quality for every reference
        normal this far from the centre's.
    mirrored : bool
        The map is a mirror image (the uv triangulation's majority says so): counter-
        clockwise in 3D then means clockwise in uv.
    min_uv_area : float
        uv area below which a triangle has no sign.
    bridge_factor : float
        Triangles with an edge longer than this many local spacings are not judged.

    Returns
    -------
    facts : dict
        ``n_ring_judged`` (ring triangles judged, counted once per centre) and
        ``n_ring_flipped`` (distinct triangles among them whose uv orientation is reversed).
    flipped : (F, 3) numpy.ndarray of int64
        Those triangles, each once.
    """
    n = points.shape[0]
    knn = np.ascontiguousarray(knn_indices, dtype=np.int64)
    rings = local_delaunay_rings(points, normals, knn)
    if loops:
        rings = drop_outside_boundary(rings, points, normals, loops, knn)
    verdict = np.empty(rings.shape[:2], dtype=np.int8)
    args = (np.ascontiguousarray(points, dtype=np.float64), np.ascontiguousarray(uv, dtype=np.float64),
            np.ascontiguousarray(normals, dtype=np.float64), rings, np.ascontiguousarray(spacing_pt, dtype=np.float64),
            float(np.sin(np.radians(tol_deg))), float(np.cos(np.radians(RING_NORMAL_DEG))), RING_QUALITY,
            RING_REVERSAL, -1.0 if mirrored else 1.0, float(min_uv_area), float(bridge_factor), verdict)
    for_each_chunk(lambda rows: _judge_rings(rows.start, rows.stop, *args), n, _CHUNK)
    centre, slot = np.nonzero(verdict == _REVERSED)
    flipped = np.c_[centre, rings[centre, slot]].astype(np.int64)
    if flipped.size:
        _, first = np.unique(np.sort(flipped, axis=1), axis=0, return_index=True)
        flipped = flipped[np.sort(first)]
    return {"n_ring_judged": int(np.count_nonzero(verdict)), "n_ring_flipped": int(flipped.shape[0])}, flipped


def unresolved_points(normals: np.ndarray, knn_indices: np.ndarray) -> np.ndarray:
    """Points with a neighbour whose normal is more than ``RING_NORMAL_DEG`` from theirs.

    There the points do not resolve the surface (a part thinner than the sampling or bent
    more sharply than it: fingertips, ears, creases) and no triangle with them is judged by
    :func:`ring_orientation`. Measured (8 neighbours, the front end's normals): 0 on the
    generated surfaces without such parts at every sampling (bump, cap, cylinder, holes,
    plane, saddle, slit, gnome-strip: random, graded, jittered, 2k-3k), at most 6 under
    normal noise of 0.5 spacings; 45-307 on ``protrusions``, 3-198 on ``fold`` (1377 at
    noise 0.5), 20-106 on ``real/spot-top`` scattered (its ears), 243-979 on
    ``real/camelhead`` scattered; 0 on scattered lilium, meg-helmet and bump-domain.

    Parameters
    ----------
    normals : (N, 3) numpy.ndarray of float64
        Unit normals, oriented consistently.
    knn_indices : (N, K) numpy.ndarray of int64
        Each point's nearest neighbours.

    Returns
    -------
    (N,) numpy.ndarray of bool
    """
    out = np.empty(normals.shape[0], dtype=bool)
    cos_max = np.cos(np.radians(RING_NORMAL_DEG))

    def rows_of(rows: slice) -> None:
        out[rows] = np.einsum("ij,ikj->ik", normals[rows], normals[knn_indices[rows]]).min(axis=1) < cos_max

    for_each_chunk(rows_of, normals.shape[0], _CHUNK)
    return out
