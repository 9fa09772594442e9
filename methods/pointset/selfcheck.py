"""A point-set map checks itself: flipped and degenerate triangles, loop turning, loop coverage.

The uv points are triangulated with the detected boundary loops as constraints
(:func:`parambench.methods.pointset.uv_triangulation.triangulate_uv`) and the triangles are checked
against the 3D geometry. Thresholds (module constants, reported with every check):

* **flipped** (``MAX_FLIPPED`` = 0 allowed): a uv-counter-clockwise triangle whose 3D
  normal disagrees with the mean normal of its points (``dot < 0``). A global mirror is
  not a flip: the majority orientation counts as "not flipped". The test reads the sign
  of the triangle's area projected on the tangent plane of that mean normal. Slivers
  there and in 3D (area below ``SLIVER_QUALITY`` = 0.05 times the squared longest edge;
  equilateral: 0.43) are not counted: three nearly collinear points change orientation
  under any small distortion (counted apart as ``n_flipped_slivers``). Those with a
  corner off the loops (``n_flipped_inner_slivers``) are allowed only up to
  ``MAX_INNER_SLIVER_FRACTION`` = 1e-5 of the triangles (none below 100k triangles)
  where slivers are rare (``n_slivers`` at most ``RARE_SLIVER_FRACTION`` = 0.5 % of the
  triangles). A conformal map keeps shapes, so its uv Delaunay triangles are 3D slivers
  only where three points lie nearly in line (``ocp`` on jittered, graded, blue-noise and
  real-mesh points: 0-0.08 %); a stretched map makes slivers of its own, flipped or not,
  without folding (LEM, Isomap, HLLE on the quick suite's surfaces: 2.0-3.8 %, up to 85
  flipped where the true mesh has no foldover), and so do random samplings (``ocp`` on
  bump, 2k random: 1.6 %, none flipped). Without detected loops (the peers without a
  front end) none is counted: no sliver can be told to lie off a loop (HLLE and LTSA
  on saddle, 2k: 19 flipped slivers, 0.5 % of the triangles, no foldover on the true
  mesh). Before those restrictions, of 108 ``ocp`` maps
  that passed (the 11 generated surfaces jittered, blue-noise and grid at 2k and
  jittered at 20k, random and graded at 2k and 20k; noise 0.25 and 0.5 spacings at 2k;
  the real meshes as points, and scattered at 5k and 20k) two had flipped slivers off
  the loops: the fingertips of ``protrusions`` (jittered 2k: 2 of its 3 slivers, where
  the map folded 4 triangles of the true mesh, QC 2.15x scp-igl's; now ``ocp``'s retries
  give 0 and 1.02x) and scattered ``real/lilium`` at 20k (1, at the ragged rim, where
  slivers are not rare: random points). A triangle that
  is a sliver in the tangent plane but well shaped in 3D (normal noise lifted its
  corners off the plane), or would be a sliver for some reference normal within a
  tolerance of the mean normal, has an uncertain sign. The tolerance is the normals'
  error as the points' noise level predicts it (:func:`normal_tolerance_deg`: ``NORMAL_TOL_FACTOR`` = 2.5 times the
  median predicted error of the kNN plane fits, at most ``NORMAL_TOL_DEG`` = 10; the
  95th percentile error of the front end's normals at noise 0.5 spacings is 9-10
  degrees); on clean surfaces it is 0.5-2.3 degrees and clean triangles, lying in their
  tangent planes, are unaffected by it. Reported as ``normal_tol_deg``. Those uncertain
  flips (``n_flipped_uncertain``) are allowed up to ``MAX_UNCERTAIN_FRACTION`` = 0.1 % of
  the triangles: measured at noise 0.5 spacings, correct maps (0 foldovers on the true
  mesh; 5 surfaces, 2k and 20k jittered points, 3 seeds) had at most 2 (0.03 % at 2k,
  0.005 % at 20k), the broken maps of random samplings (15-708 foldovers) 0.24-0.58 %.
  Under noise the check is only as good as its normals: the front end's are refitted
  on larger neighbourhoods where the fit residual says noise
  (:func:`parambench.methods.pointset.normals.noise_adaptive_normals`).
* **flipped, off the uv triangulation** (``n_ring_flipped`` <= ``MAX_RING_FLIPPED`` = 0):
  the triangulation above may pick, of two triangles sharing a quad, the diagonal along
  which the map stays consistent, and hide a fold (a graded plane's boundary spike). Each
  point's tangent-plane Delaunay one-ring among its neighbours is read too, and a
  well-shaped triangle of it (for every corner's normal within the tolerance) that the map
  clearly reverses fails the check
  (:mod:`parambench.methods.pointset.ring_orientation`; ``n_ring_judged``). Where a point's
  neighbours' normals turn by more than 60 degrees the points do not resolve the surface and
  no test can tell a fold there (``protrusions``' fingertips: maps with 1-3 folds there
  pass): ``n_unresolved`` counts those points, reported, not judged.
* **degenerate** (share of triangles <= ``MAX_DEGENERATE_FRACTION`` = 1 %): zero uv area
  (below ``ZERO_AREA_REL`` = 1e-10 of the median), or a 3D edge longer than
  ``BRIDGE_FACTOR`` = 4 times the local spacing of its points (the triangle bridges a
  gap or a hole the map closed). Without detected loops (peers without a front end)
  the bridging triangles are taken as lying outside the domain and dropped instead.
* **boundary crossing**: the loops' images in uv must not cross each other or
  themselves (a crossing is a fold at the boundary; the constrained triangulation then
  needs extra vertices, and the triangle counts above come from the fallback).
* **turning**: each loop's turning number in uv is +1 for the outer loop and -1 for
  holes, or all reversed under a global mirror, within ``TURNING_TOL`` = 0.25. The outer
  loop is the longest in 3D, or the one whose image bounds the largest area where its
  rim is at least ``COMPARABLE_RIM`` = 0.5 as long (an open cylinder may put either rim
  outside; a small hole put outside has turned inside out).
* **coverage**: the angle-criterion boundary candidates, when known, lie within
  ``COVER_RADIUS`` = 3 mean spacings of a detected loop; a connected group of at least
  ``MIN_MISSED_RING`` = 8 uncovered candidates is a missed hole. The check applies only
  where uncovered candidates in groups smaller than that are rare (at most
  ``MAX_UNCOVERED_FRACTION`` = 2 % of the points): in an irregular sampling the angle criterion also fires around the voids of
  the sampling (uniform random samples: 5-8 % of the points uncovered in small groups,
  groups of up to 20 at 20k, 27 at 100k and 22-27 at 1M points, with correct loops and 0 flipped
  triangles), and there it cannot tell a missed hole from a void; the facts then say
  ``applicable: False``. (Counting every candidate outside the largest group instead
  let several missed holes pass as voids: ``holes`` at 2k points with its three holes
  dropped, groups of 34, 30 and 27, no small ones.) Even
  there a connected group of ``MIN_MISSED_CHAIN`` = 64 uncovered candidates fails the
  check: no void of a sampling rings that many points, a missed boundary does (a real
  face range scan, 85k points, anisotropic where the scanner grazed the surface: its
  2484-point outer boundary on no loop, largest group 514; ``real/cortex-lh``: 72).
  Where the check applies, a missed hole whose rim passes the criterion only here and
  there is caught too: uncovered candidates chained within ``RING_LINK`` = 2.5 mean
  spacings, at least ``MIN_EMPTY_RING`` = 5 of them, whose centroid lies at least
  ``RING_EMPTY`` = 1.5 mean spacings from every point (they ring an empty disk:
  ``empty_ring`` in the facts). Measured (front ends' loops, groups of 5 or more):
  holes 4.2-4.8 mean spacings across in a jittered grid that the loops missed, 1.67-2.17
  (groups of 8-12, each of them under ``MIN_MISSED_RING`` by the kNN graph); the 11
  generated surfaces jittered, graded and blue-noise at 2k and 20k at most 1.26 (graded),
  ``real/camelhead``'s lips 0.40, ``real/bunny10k``'s slits 0.53; uniform random samplings
  reach 1.69, where the check does not apply.

* **distorted** (methods that promise a conformal map, ``ocp``): the Beltrami
  coefficient of the map's inverse, ``nu = (g11 - g22 + 2i g12) / (g11 + g22)`` with g
  the 3D metric in uv coordinates of each triangle (bridging and zero-area ones left
  out), averaged by uv area over cells of the uv bounding box (as many as leave about
  ``COHERENT_CELL_TRIANGLES`` = 100 triangles per cell, at most 8 x 8), must stay within
  :func:`coherent_limit` in the area-weighted RMS over the cells (``coherent_beltrami``):
  ``MAX_COHERENT_BELTRAMI_CLEAN`` = 0.06 where the normal tolerance is at most
  ``CLEAN_TOL_DEG`` = 3 degrees (clean points), rising linearly to
  ``MAX_COHERENT_BELTRAMI`` = 0.15 at ``NORMAL_TOL_DEG`` (noise of half a spacing).
  Noise makes nu random from triangle to triangle, and the cells average it away; a
  map that stretches whole regions one way keeps it. Measured:
  ``ocp`` maps that pass otherwise, clean (generated surfaces random and graded at 2k,
  real meshes as points and scattered at 5k) 0-0.047 (the most on ``protrusions``'
  fingertips), at normal noise 0.5 spacings 0.046-0.078; two maps of uniform random
  points on a developable strip that passed every other check 13.5 % and 3.4 % of the
  diameter off its exact development, 0.40 and 0.27 (the other 18 such maps 0-0.0005).
  A Neumann-energy map of uniform random points on a square (3000, seed 1), with its
  rim complete (:mod:`parambench.methods.pointset.loop_wrap`), is 5.6 % of the diameter
  off the exact development with 0.097 at a tolerance under 1 degree; the clean
  generated surfaces at 2k (random, graded) score 0-0.012 where the tolerance is under
  3 degrees, ``protrusions`` graded 0.040 at 5.4 degrees, and at noise 0.5 spacings
  (tolerance 10) 0.018-0.071; hence the limit follows the noise.
  It is always measured and reported, and judged only for those methods: LEM and LLE
  are not conformal by design (bump, 2k random points: 0.42 and 0.20).
* **outside**: no point off the loops may lie outside the domain they bound in uv
  (total winding number 0) deeper than ``MAX_OUTSIDE_DEPTH`` = 0.25 of its own uv
  spacing from the loops (:func:`points_outside`: ``n_outside``, ``outside_depth``).
  Such points are left out of the uv triangulation, so no other test sees them; they
  mean a loop cuts across the surface. Measured on the real-data benchmark's 84 cases
  before the front end wrapped such loops: 13 cases had 1-3 points outside, up to 0.45
  spacings deep; after it, 3 cases (``real/bunny10k``, 3 points 0.32 deep, failing on
  folds anyway; two slits at 0 and 0.009). It costs 0.3 s at 790k points.

The facts are JSON-serialisable; ``passed`` is their conjunction and ``reason`` says in
one line what failed, and why where the geometry tells
(:mod:`parambench.methods.pointset.failure_causes`). The check never raises and never changes the map.
"""

from __future__ import annotations

import time
from typing import Any, NamedTuple

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from parambench.datasets_gen.errors import ParambenchError

from ..geometry2d import signed_area_2d, triangle_signed_areas, turning_number
from .failure_causes import NOISY_FIT_DEG, describe_causes, failure_causes, noisy_cause
from .handles import handle_cause
from .ring_orientation import RING_NORMAL_DEG, RING_QUALITY, ring_orientation, unresolved_points
from .row_chunks import for_each_chunk
from .stray_points import ISOLATED_BOX_SHARE, isolated_mask
from .uv_triangulation import loop_winding_numbers, triangulate_uv

__all__ = ["check_pointset_map", "coherent_beltrami", "coherent_limit", "empty_ring", "loop_coverage",
           "normal_tolerance_deg", "uncovered_phrase",
           "points_outside", "pointset_faces",
           "THRESHOLDS"]

MAX_FLIPPED = 0
MAX_DEGENERATE_FRACTION = 0.01
ZERO_AREA_REL = 1e-10
SLIVER_QUALITY = 0.05
NORMAL_TOL_DEG = 10.0
NORMAL_TOL_FACTOR = 2.5
MAX_UNCERTAIN_FRACTION = 0.001
MAX_INNER_SLIVER_FRACTION = 1e-5
RARE_SLIVER_FRACTION = 0.005
BRIDGE_FACTOR = 4.0
TURNING_TOL = 0.25
COVER_RADIUS = 3.0
MIN_MISSED_RING = 8
MIN_MISSED_CHAIN = 64
MAX_UNCOVERED_FRACTION = 0.02
RING_LINK = 2.5
MIN_EMPTY_RING = 5
RING_EMPTY = 1.5
MAX_COHERENT_BELTRAMI = 0.15
MAX_COHERENT_BELTRAMI_CLEAN = 0.06
CLEAN_TOL_DEG = 3.0
COHERENT_CELL_TRIANGLES = 100
MAX_OUTSIDE_DEPTH = 0.25
MAX_RING_FLIPPED = 0
COMPARABLE_RIM = 0.5

#: The thresholds as reported in ``diagnostics["selfcheck"]["thresholds"]``.
THRESHOLDS = {"max_flipped": MAX_FLIPPED, "max_degenerate_fraction": MAX_DEGENERATE_FRACTION,
              "zero_area_rel": ZERO_AREA_REL, "sliver_quality": SLIVER_QUALITY,
              "normal_tol_deg_max": NORMAL_TOL_DEG, "normal_tol_factor": NORMAL_TOL_FACTOR,
              "max_uncertain_fraction": MAX_UNCERTAIN_FRACTION,
              "max_inner_sliver_fraction": MAX_INNER_SLIVER_FRACTION,
              "rare_sliver_fraction": RARE_SLIVER_FRACTION, "bridge_factor": BRIDGE_FACTOR, "turning_tol": TURNING_TOL,
              "cover_radius_spacings": COVER_RADIUS, "min_missed_ring": MIN_MISSED_RING,
              "min_missed_chain": MIN_MISSED_CHAIN,
              "max_uncovered_fraction": MAX_UNCOVERED_FRACTION, "ring_link_spacings": RING_LINK,
              "min_empty_ring": MIN_EMPTY_RING, "ring_empty_spacings": RING_EMPTY, "noisy_fit_deg": NOISY_FIT_DEG,
              "max_coherent_beltrami": MAX_COHERENT_BELTRAMI,
              "max_coherent_beltrami_clean": MAX_COHERENT_BELTRAMI_CLEAN, "clean_tol_deg": CLEAN_TOL_DEG,
              "max_outside_depth": MAX_OUTSIDE_DEPTH, "max_ring_flipped": MAX_RING_FLIPPED,
              "ring_quality": RING_QUALITY, "ring_normal_deg": RING_NORMAL_DEG,
              "isolated_box_share": ISOLATED_BOX_SHARE}

#: Most cells per side of the uv bounding box over which :func:`coherent_beltrami` averages ...
_MAX_CELLS = 8
#: ... and most triangles it reads (every m-th beyond).
_MAX_BELTRAMI_FACES = 200_000

#: Neighbours for the local spacing when no kNN graph is given.
_SPACING_K = 8

#: Rows (points or triangles) per chunk of the per-row arithmetic (a few MB of temporaries).
_CHUNK = 32768


def _knn(points: np.ndarray, k: int = _SPACING_K) -> np.ndarray:
    _, idx = cKDTree(points).query(points, k=k + 1, workers=-1)
    return np.ascontiguousarray(idx[:, 1:], dtype=np.int64)


def _local_spacing(points: np.ndarray, knn: np.ndarray) -> np.ndarray:
    out = np.empty(points.shape[0])

    def rows_of(rows: slice) -> None:
        out[rows] = np.linalg.norm(points[knn[rows]] - points[rows, None, :], axis=-1).mean(axis=1)

    for_each_chunk(rows_of, points.shape[0], _CHUNK)
    return out


def _longest_edge(points: np.ndarray, faces: np.ndarray, corners: np.ndarray | None = None) -> np.ndarray:
    p = points[faces] if corners is None else corners  # (M, 3, 3) corner positions when the caller has them
    edges = np.stack([p[:, 1] - p[:, 0], p[:, 2] - p[:, 1], p[:, 0] - p[:, 2]], axis=1)
    return np.sqrt(np.einsum("mij,mij->mi", edges, edges)).max(axis=1)


def _bridging(longest: np.ndarray, faces: np.ndarray, spacing_pt: np.ndarray) -> np.ndarray:
    """Triangles with a 3D edge longer than ``BRIDGE_FACTOR`` local spacings."""
    return longest > BRIDGE_FACTOR * spacing_pt[faces].mean(axis=1)


def normal_tolerance_deg(points: np.ndarray, knn_indices: np.ndarray, median_error_deg: float | None = None) -> float:
    """The normals' error the flip test allows for, from the points' own noise level.

    ``NORMAL_TOL_FACTOR`` times the median predicted error of the kNN plane fits
    (:func:`parambench.methods.pointset.normals.pca_fit`: the fit residual against the in-plane
    spread), at most ``NORMAL_TOL_DEG``. Clean generated surfaces predict 0.2-0.9
    degrees (median), so the tolerance there is 0.5-2.3 degrees; normal noise of 0.25 or
    0.5 spacings predicts 8-15 degrees at K = 8 and gets ``NORMAL_TOL_DEG``.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    knn_indices : (N, K) numpy.ndarray of int64
    median_error_deg : float, optional
        That median, in degrees, when the caller has it (the front end's normals stage
        fits the same kNN graph: ``normal_fit["predicted_error_deg"]["median"]``); the
        fits are not repeated then (0.4 s at 200k points).

    Returns
    -------
    float
        Degrees.
    """
    return float(min(NORMAL_TOL_DEG, NORMAL_TOL_FACTOR * median_fit_error_deg(points, knn_indices, median_error_deg)))


def median_fit_error_deg(points: np.ndarray, knn_indices: np.ndarray, given: float | None = None) -> float:
    """The median predicted error of the points' kNN plane fits, degrees (``given`` when known)."""
    if given is not None:
        return float(given)
    from .normals import pca_fit

    return float(np.degrees(np.median(pca_fit(points, knn_indices)[2])))


def _tangent_sliver(p: np.ndarray, normal3d: np.ndarray, mean_normal: np.ndarray,
                    tol_deg: float = NORMAL_TOL_DEG) -> tuple[np.ndarray, np.ndarray]:
    """Triangles whose projection on their vertices' mean tangent plane is, or may be, a sliver.

    Quality = projected area / (longest projected edge)^2 below ``SLIVER_QUALITY``, for
    the mean normal and for every reference normal within ``tol_deg`` of it: the
    flip test reads the sign of that projected area, so this is where it is decided. A
    triangle of noisy points can be well shaped in 3D (the noise lifts its corners off
    the plane) while its projection is a sliver whose sign the noise and the normals'
    error set. Measured at noise 0.5 spacings, on correct maps (0 foldovers on the true
    mesh): saddle 20k, a triangle the normals called flipped with 3D quality 0.28 and
    projected quality 0.03; cap 2k seed 1, one with projected quality 0.059 whose true
    quality is 0.004 (a sliver at the boundary), within the tolerance term here.
    On a clean surface a triangle lies in its tangent plane and the tolerance adds
    nothing.

    Returns
    -------
    sliver, uncertain : (M,) numpy.ndarray of bool
        Slivers for the mean normal; and the others that are slivers for some normal
        within ``tol_deg`` (their sign is uncertain).
    """
    length = np.linalg.norm(mean_normal, axis=1)
    unit = mean_normal / np.where(length > 0, length, 1.0)[:, None]
    flat = p - np.einsum("mki,mi->mk", p, unit)[:, :, None] * unit[:, None, :]
    edges = np.stack([flat[:, 1] - flat[:, 0], flat[:, 2] - flat[:, 1], flat[:, 0] - flat[:, 2]], axis=1)
    longest_sq = np.einsum("mij,mij->mi", edges, edges).max(axis=1)
    area = 0.5 * np.abs(np.einsum("mi,mi->m", normal3d, unit))
    # How much the projected area changes when the reference normal tilts by NORMAL_TOL:
    # nothing for a triangle lying in the tangent plane, a lot for one noise stood up.
    wobble = 0.5 * np.linalg.norm(np.cross(normal3d, unit), axis=1) * np.sin(np.radians(tol_deg))
    sliver = (area < SLIVER_QUALITY * longest_sq) | (length == 0)
    return sliver, ~sliver & (area < SLIVER_QUALITY * longest_sq + wobble)


def loop_coverage(points: np.ndarray, loops: list, candidates: np.ndarray, knn_indices: np.ndarray,
                  spacing: float) -> dict:
    """Do the detected loops cover the angle-criterion boundary candidates?

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    loops : list of (L_i,) numpy.ndarray of int64
        Detected boundary loops.
    candidates : (N,) numpy.ndarray of bool
        Points passing the angle criterion.
    knn_indices : (N, K) numpy.ndarray of int64
        Neighbour graph used to group uncovered candidates.
    spacing : float
        Mean point spacing ``l`` (length units of ``points``).

    Returns
    -------
    dict
        ``n_candidates``, ``n_uncovered`` (farther than ``COVER_RADIUS * l`` from every
        loop point), ``largest_uncovered_group`` (connected in the kNN graph),
        ``n_scattered`` (uncovered candidates in groups of fewer than ``MIN_MISSED_RING``),
        ``applicable`` (those are at most ``MAX_UNCOVERED_FRACTION`` of the points: a
        regular enough sampling), ``empty_ring`` (where applicable, the size of the
        largest chain of uncovered candidates around an empty disk, :func:`empty_ring`;
        0 if none) and ``passed``
        (that group has fewer than ``MIN_MISSED_RING`` points and there is no empty ring
        where applicable, fewer than ``MIN_MISSED_CHAIN`` where not).
    """
    cand = np.flatnonzero(np.asarray(candidates, dtype=bool))
    loop_pts = np.concatenate([np.asarray(lp, dtype=np.int64) for lp in loops]) if loops else np.empty(0, np.int64)
    if cand.size and loop_pts.size:
        dist, _ = cKDTree(points[loop_pts]).query(points[cand], k=1, distance_upper_bound=COVER_RADIUS * spacing)
        uncovered = cand[~np.isfinite(dist)]
    else:
        uncovered = cand
    largest = scattered = 0
    if uncovered.size:
        flag = np.zeros(points.shape[0], dtype=bool)
        flag[uncovered] = True
        rows = np.repeat(uncovered, knn_indices.shape[1])
        cols = knn_indices[uncovered].ravel()
        keep = flag[cols]
        adj = sp.coo_matrix((np.ones(int(keep.sum())), (rows[keep], cols[keep])), shape=(points.shape[0],) * 2)
        _, labels = connected_components(adj, directed=False)
        group_size = np.bincount(labels[uncovered])[labels[uncovered]]
        largest = int(group_size.max())
        scattered = int(np.count_nonzero(group_size < MIN_MISSED_RING))
    # Many small groups of uncovered candidates mark the voids of an irregular sampling.
    applicable = scattered <= MAX_UNCOVERED_FRACTION * points.shape[0]
    ring = empty_ring(points, uncovered, spacing) if applicable else 0
    passed = largest < MIN_MISSED_RING and not ring if applicable else largest < MIN_MISSED_CHAIN
    return {"n_candidates": int(cand.size), "n_uncovered": int(uncovered.size),
            "largest_uncovered_group": largest, "n_scattered": scattered, "applicable": bool(applicable),
            "empty_ring": ring, "passed": bool(passed)}


def uncovered_phrase(coverage: dict) -> str:
    """What a failed coverage check found, as a clause: "12 connected boundary candidates
    lie on no detected loop", or "9 boundary candidates ring an empty disk on no detected
    loop" where only the empty ring failed it (:func:`loop_coverage`'s facts)."""
    if coverage.get("empty_ring") and coverage["largest_uncovered_group"] < MIN_MISSED_RING:
        return f"{coverage['empty_ring']} boundary candidates ring an empty disk on no detected loop"
    return f"{coverage['largest_uncovered_group']} connected boundary candidates lie on no detected loop"


def empty_ring(points: np.ndarray, uncovered: np.ndarray, spacing: float) -> int:
    """The largest chain of uncovered boundary candidates that rings an empty disk, or 0.

    Chains link candidates within ``RING_LINK`` mean spacings (a hole's rim where only
    every second or third point passes the angle criterion); a chain of at least
    ``MIN_EMPTY_RING`` whose centroid is ``RING_EMPTY`` mean spacings or more from every
    point surrounds a hole the loops missed.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    uncovered : (U,) numpy.ndarray of int64
        Candidates off every loop (indices of ``points``).
    spacing : float
        Mean point spacing ``l``.

    Returns
    -------
    int
        Its number of candidates.
    """
    if uncovered.size < MIN_EMPTY_RING:
        return 0
    pairs = cKDTree(points[uncovered]).query_pairs(RING_LINK * spacing, output_type="ndarray")
    adj = sp.coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(uncovered.size,) * 2)
    _, labels = connected_components(adj, directed=False)
    sizes = np.bincount(labels)
    chains = np.flatnonzero(sizes >= MIN_EMPTY_RING)
    if not chains.size:
        return 0
    xyz = points[uncovered]
    centroids = np.stack([np.bincount(labels, weights=xyz[:, axis])[chains] for axis in range(3)], axis=1)
    gap, _ = cKDTree(points).query(centroids / sizes[chains, None], k=1)
    empty = gap >= RING_EMPTY * spacing
    return int(sizes[chains[empty]].max()) if empty.any() else 0


class _PerFace(NamedTuple):
    """Per-triangle facts of :func:`_per_face`, one entry per face."""

    bridging: np.ndarray  # that edge longer than BRIDGE_FACTOR local spacings
    area: np.ndarray  # |uv area|
    agree: np.ndarray  # 3D normal . the corners' summed normals (sign: orientation)
    sliver: np.ndarray  # a sliver in the tangent plane and in 3D: never judged
    uncertain: np.ndarray  # a sign the normals' error could change


def _per_face(points, uv, normals, faces, spacing_pt, tol_deg: float) -> _PerFace:
    """Every triangle's own facts, computed in row chunks on worker threads.

    Each face's arithmetic depends on that face alone, so chunks give the same numbers as
    one pass over all faces (bit for bit) with temporaries of a chunk's size: at a million
    points (2M triangles) the whole-array pass took 5 s of the check's 10.5 s.
    """
    m = faces.shape[0]
    out = _PerFace(np.empty(m, dtype=bool), np.empty(m), np.empty(m), np.empty(m, dtype=bool),
                   np.empty(m, dtype=bool))

    def rows_of(rows: slice) -> None:
        f = faces[rows]
        p = points[f]
        e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
        longest = _longest_edge(points, f, p)
        normal3d = np.cross(e1, e2)
        mean_normal = normals[f].sum(axis=1)
        tangent_sliver, uncertain = _tangent_sliver(p, normal3d, mean_normal, tol_deg)
        # Never judged: slivers both in the tangent plane and in 3D (three nearly collinear
        # points). A tangent-plane sliver that is well shaped in 3D was stood up by noise:
        # its sign is uncertain, counted with the others.
        sliver = tangent_sliver & (0.5 * np.linalg.norm(normal3d, axis=1) < SLIVER_QUALITY * longest**2)
        out.bridging[rows] = _bridging(longest, f, spacing_pt)
        out.area[rows] = np.abs(triangle_signed_areas(uv, f))  # faces are uv-CCW
        out.agree[rows] = np.einsum("mi,mi->m", normal3d, mean_normal)
        out.sliver[rows] = sliver
        out.uncertain[rows] = uncertain | (tangent_sliver & ~sliver)

    for_each_chunk(rows_of, m, _CHUNK)
    return out


class _FailedFaces(NamedTuple):
    """The triangles the facts counted as failing (for :mod:`.failure_causes`)."""

    faces: np.ndarray  # (M, 3) the triangles judged
    flipped: np.ndarray  # (M,) flipped, slivers and uncertain ones included
    zero: np.ndarray  # (M,) zero uv area, off the rim
    zero_area: float  # the uv area at or below which a triangle has none


def _face_facts(points, uv, normals, faces, spacing_pt, drop_bridging: bool,
                tol_deg: float = NORMAL_TOL_DEG, on_loop: np.ndarray | None = None
                ) -> tuple[dict, int, _FailedFaces]:
    per = _per_face(points, uv, normals, faces, spacing_pt, tol_deg)
    n_dropped = 0
    if drop_bridging:
        n_dropped = int(per.bridging.sum())
        faces = faces[~per.bridging]
        per = _PerFace(*(a[~per.bridging] for a in per))
    # Slivers with every corner on a loop: where a rim is straight in 3D and its image
    # straight in uv (a refined map of a plane's edge), the triangulation fills the loop's
    # own bends of 1e-13 with triangles of no area, fanning along the rim. Not the map's.
    rim = per.sliver & (on_loop[faces].all(axis=1) if on_loop is not None else False)
    bridging, area, agree, sliver, uncertain = per
    zero_area = ZERO_AREA_REL * (float(np.median(area)) if area.size else 0.0)
    zero = area <= zero_area
    # Nor is a triangle of three points collinear in 3D that the map keeps collinear: the
    # exact map of a square, given without loops (scikit-learn's peers, a plugin), failed
    # with 2.9 % "degenerate" triangles, each along a straight edge of the square.
    rim = rim | (sliver & zero)
    valid = ~(zero | bridging)
    n_neg = np.count_nonzero(agree[valid] < 0)
    n_pos = np.count_nonzero(agree[valid] > 0)
    mirrored = n_neg > n_pos
    flipped = valid & ((agree > 0) if mirrored else (agree < 0))
    m = int(area.size)
    n_degenerate = int(((zero | bridging) & ~rim).sum())
    facts = {"n_triangles": m, "n_flipped": int((flipped & ~sliver & ~uncertain).sum()),
             "n_flipped_slivers": int((flipped & sliver).sum()),
             # Without loops (drop_bridging) no sliver can be told to lie off them: none counted.
             "n_slivers": int(sliver.sum()),
             "n_flipped_inner_slivers": 0 if drop_bridging else int((flipped & sliver & ~rim).sum()),
             "n_flipped_uncertain": int((flipped & uncertain).sum()), "mirrored": bool(mirrored),
             "n_zero_area": int(zero.sum()), "n_bridging": int(bridging.sum()), "n_rim_slivers": int(rim.sum()),
             "n_degenerate": n_degenerate,
             "degenerate_fraction": n_degenerate / m if m else 1.0,
             "coherent_beltrami": round(coherent_beltrami(points, uv, faces[valid]), 5)}
    return facts, n_dropped, _FailedFaces(faces, flipped, zero & ~rim, zero_area)


def _with_ring_facts(facts: dict, failing: _FailedFaces, points, uv, normals, knn, loops, spacing_pt,
                     tol_deg: float) -> _FailedFaces:
    """Add :func:`~parambench.methods.pointset.ring_orientation.ring_orientation`'s facts (with
    the uv triangulation's mirror and zero-area threshold) and ``n_unresolved`` to ``facts``;
    the failing triangles with the reversed ring triangles added as flipped."""
    ring, reversed_ = ring_orientation(points, uv, normals, knn, loops, spacing_pt, tol_deg=tol_deg,
                                       mirrored=bool(facts.get("mirrored", False)), min_uv_area=failing.zero_area,
                                       bridge_factor=BRIDGE_FACTOR)
    facts.update(ring, n_unresolved=int(unresolved_points(normals, knn).sum()))
    added = np.ones(len(reversed_), dtype=bool)
    return _FailedFaces(np.concatenate([failing.faces, reversed_]), np.concatenate([failing.flipped, added]),
                        np.concatenate([failing.zero, ~added]), failing.zero_area)


def coherent_beltrami(points: np.ndarray, uv: np.ndarray, faces: np.ndarray) -> float:
    """How far a map stretches whole regions one way: its Beltrami coefficient averaged over cells.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    uv : (N, 2) numpy.ndarray of float64
    faces : (M, 3) numpy.ndarray of int64
        Triangles with area in uv and in 3D.

    Returns
    -------
    float
        The area-weighted RMS over cells of the uv bounding box of the cells' mean
        ``nu = (g11 - g22 + 2i g12) / (g11 + g22)``, g the 3D metric in uv coordinates
        of each triangle (0 for a conformal map, any similarity of it too); 0.0 without
        faces. See the module docstring.
    """
    if faces.shape[0] == 0:
        return 0.0
    # Cells hold ~100 triangles at the least; at a million points a stride keeps ~3000
    # in each of the 64 cells, in 0.1 s instead of 1 s.
    faces = faces[::-(-faces.shape[0] // _MAX_BELTRAMI_FACES)]
    i, j, k = (np.ascontiguousarray(c) for c in faces.T)  # strided indices gather 2x slower
    p0, q0, q1, q2 = points[i], uv[i], uv[j], uv[k]
    e3, f3 = points[j] - p0, points[k] - p0
    (a1, a2), (b1, b2) = (q1 - q0).T, (q2 - q0).T
    ee, ef, ff = (np.einsum("ij,ij->i", x, y) for x, y in ((e3, e3), (e3, f3), (f3, f3)))
    # g = adj(D)^T G adj(D), D = [uv edges], G their 3D Gram matrix: the metric times
    # det(D)^2, a factor nu does not see.
    g11 = ee * b2 * b2 - 2.0 * ef * a2 * b2 + ff * a2 * a2
    g22 = ee * b1 * b1 - 2.0 * ef * a1 * b1 + ff * a1 * a1
    g12 = -ee * b1 * b2 + ef * (a1 * b2 + a2 * b1) - ff * a1 * a2
    area = 0.5 * np.abs(a1 * b2 - a2 * b1)
    trace = g11 + g22
    keep = (area > 0) & (trace > 0)
    nu = (g11[keep] - g22[keep] + 2j * g12[keep]) / trace[keep]
    area = area[keep]
    centre = ((q0 + q1 + q2) / 3.0)[keep]
    cells = int(np.clip(np.sqrt(centre.shape[0] / COHERENT_CELL_TRIANGLES), 1, _MAX_CELLS))
    lo, extent = centre.min(axis=0), np.ptp(centre, axis=0)
    ij = np.minimum((cells * (centre - lo) / np.where(extent > 0, extent, 1.0)).astype(np.int64), cells - 1)
    cell = ij[:, 0] * cells + ij[:, 1]
    cell_area = np.bincount(cell, area, cells * cells)
    cell_nu = (np.bincount(cell, area * nu.real, cells * cells)
               + 1j * np.bincount(cell, area * nu.imag, cells * cells))
    used = cell_area > 0
    mean_nu = np.abs(cell_nu[used] / cell_area[used])
    return float(np.sqrt(np.sum(cell_area[used] * mean_nu**2) / cell_area[used].sum()))


#: Loop segments examined per point for its distance to the loops (nearest by midpoint).
_NEAR_SEGMENTS = 8


def _distance_to_loops(query: np.ndarray, uv: np.ndarray, loops: list) -> np.ndarray:
    """Distance in uv from each query point to the nearest of the loops' segments (of the
    ``_NEAR_SEGMENTS`` with the nearest midpoints)."""
    a = np.concatenate([uv[lp] for lp in loops])
    b = np.concatenate([uv[np.roll(lp, -1)] for lp in loops])
    k = min(_NEAR_SEGMENTS, a.shape[0])
    _, near = cKDTree(0.5 * (a + b)).query(query, k=k)
    near = near.reshape(query.shape[0], k)
    ab = b[near] - a[near]
    t = np.clip(np.einsum("qkj,qkj->qk", query[:, None, :] - a[near], ab)
                / np.maximum(np.einsum("qkj,qkj->qk", ab, ab), np.finfo(float).tiny), 0.0, 1.0)
    foot = a[near] + t[..., None] * ab
    return np.sqrt(np.min(np.sum((foot - query[:, None, :]) ** 2, axis=2), axis=1))


def points_outside(uv: np.ndarray, loops: list, knn_indices: np.ndarray) -> dict:
    """Points off the loops that the map puts outside the domain the loops bound.

    A correct boundary has every other point inside its outer loop and outside its
    holes; where a loop cuts across the surface (the walk chained interior candidates,
    as on the voids of a random sampling), the points beyond it lie outside in uv too,
    and the uv triangulation leaves them out, so no other check sees them.

    Parameters
    ----------
    uv : (N, 2) numpy.ndarray of float64
    loops : list of (L_i,) numpy.ndarray of int64
        Detected boundary loops (at least one).
    knn_indices : (N, K) numpy.ndarray of int64
        Neighbour graph; a point's uv spacing is its mean uv distance to them.

    Returns
    -------
    dict
        ``n_outside`` (points off the loops with total winding number 0) and
        ``outside_depth`` (the largest distance of one of them from the loops' segments,
        in its own uv spacings; 0.0 when there is none).
    """
    loops = [lp for lp in loops if len(lp) >= 3]
    if not loops:
        return {"n_outside": 0, "outside_depth": 0.0}
    on_loop = np.zeros(uv.shape[0], dtype=bool)
    on_loop[np.concatenate(loops)] = True
    rest = np.flatnonzero(~on_loop)
    out = rest[loop_winding_numbers(uv[rest], uv, loops) == 0]
    if not out.size:
        return {"n_outside": 0, "outside_depth": 0.0}
    spacing = np.linalg.norm(uv[knn_indices[out]] - uv[out, None, :], axis=2).mean(axis=1)
    depth = _distance_to_loops(uv[out], uv, loops) / np.maximum(spacing, np.finfo(float).tiny)
    return {"n_outside": int(out.size), "outside_depth": round(float(depth.max()), 4)}


def _outer_in_uv(uv: np.ndarray, loops: list, points: np.ndarray) -> int:
    """The loop the map may put outside: the one whose image bounds the largest area, where
    its rim is at least :data:`COMPARABLE_RIM` as long in 3D as the longest loop's; else the
    longest (``loops[0]``).

    Which of two alike rims a map puts outside is its choice: an open cylinder's two rims
    are alike, and ``ocp`` put either outside (a correct map, radius ratio 20.0 against
    e^3 = 20.09, refused as "loop 0 turns -1.00 (expected +1)"). A small hole put outside
    is a hole turned inside out (``real/bunny10k``: one of 1.42 and 3551 in area), which
    squeezes the rest of the surface into a point.
    """
    areas = [abs(signed_area_2d(uv[np.asarray(lp, dtype=np.int64)])) for lp in loops]
    outer = int(np.argmax(areas))
    if outer and _rim_length(points, loops[outer]) < COMPARABLE_RIM * _rim_length(points, loops[0]):
        return 0
    return outer


def _rim_length(points: np.ndarray, loop) -> float:
    loop = np.asarray(loop, dtype=np.int64)
    return float(np.linalg.norm(points[np.roll(loop, -1)] - points[loop], axis=1).sum())


def _turning(uv: np.ndarray, loops: list, mirrored: bool, outer: int) -> dict:
    sign = -1.0 if mirrored else 1.0
    turns = [turning_number(uv[np.asarray(lp, dtype=np.int64)]) for lp in loops]
    expected = [sign * (1.0 if i == outer else -1.0) for i in range(len(turns))]
    ok = all(abs(t - e) <= TURNING_TOL for t, e in zip(turns, expected))
    return {"turning_numbers": [round(t, 4) for t in turns], "expected_turning": expected, "turning_ok": bool(ok)}


def _too_uncertain(facts: dict) -> bool:
    """More flips within the normals' error than noise makes on a correct map."""
    return facts.get("n_flipped_uncertain", 0) > MAX_UNCERTAIN_FRACTION * facts.get("n_triangles", 0)


def _too_many_inner_slivers(facts: dict) -> bool:
    """More flipped slivers off the loops than correct maps have (none measured), where slivers are rare."""
    m = facts.get("n_triangles", 0)
    rare = facts.get("n_slivers", 0) <= RARE_SLIVER_FRACTION * m
    return rare and facts.get("n_flipped_inner_slivers", 0) > MAX_INNER_SLIVER_FRACTION * m


def coherent_limit(normal_tol_deg: float | None) -> float:
    """The largest ``coherent_beltrami`` a conformal map may have at this normal tolerance:
    :data:`MAX_COHERENT_BELTRAMI_CLEAN` up to :data:`CLEAN_TOL_DEG`, rising linearly to
    :data:`MAX_COHERENT_BELTRAMI` at :data:`NORMAL_TOL_DEG` (the noisiest inputs)."""
    tol = CLEAN_TOL_DEG if normal_tol_deg is None else float(normal_tol_deg)
    share = np.clip((tol - CLEAN_TOL_DEG) / (NORMAL_TOL_DEG - CLEAN_TOL_DEG), 0.0, 1.0)
    return float(MAX_COHERENT_BELTRAMI_CLEAN + share * (MAX_COHERENT_BELTRAMI - MAX_COHERENT_BELTRAMI_CLEAN))


def _stretched(facts: dict) -> bool:
    """The map stretches whole regions one way: over :func:`coherent_limit`, judged or not."""
    return facts.get("coherent_beltrami", 0.0) > coherent_limit(facts.get("normal_tol_deg"))


def _too_distorted(facts: dict) -> bool:
    """A map that should be conformal stretches whole regions (judged only where asked)."""
    return bool(facts.get("conformal_judged")) and _stretched(facts)


def _too_far_outside(facts: dict) -> bool:
    """Points lie beyond the loops deeper than a rim's own zigzag: a loop cuts across the surface."""
    return facts.get("n_outside", 0) > 0 and facts.get("outside_depth", 0.0) > MAX_OUTSIDE_DEPTH


def _reason(facts: dict) -> str:
    parts = []
    if facts.get("boundary_crosses", False):
        parts.append("the boundary loops' images cross in uv (the map folds at the boundary)")
    if facts.get("n_flipped", 0) > MAX_FLIPPED:
        parts.append(f"{facts['n_flipped']} flipped triangle(s) of {facts['n_triangles']}")
    if _too_many_inner_slivers(facts):
        parts.append(f"{facts['n_flipped_inner_slivers']} flipped sliver triangle(s) off the boundary loops")
    if facts.get("n_ring_flipped", 0) > MAX_RING_FLIPPED:
        parts.append(f"{facts['n_ring_flipped']} well-shaped triangle(s) of neighbouring points reversed in uv "
                     f"(the map folds where its uv triangulation does not show it)")
    if _too_uncertain(facts):
        parts.append(f"{facts['n_flipped_uncertain']} triangles flipped within the normals' error "
                     f"(more than {100 * MAX_UNCERTAIN_FRACTION:g} % of {facts['n_triangles']})")
    if facts.get("degenerate_fraction", 0.0) > MAX_DEGENERATE_FRACTION:
        parts.append(f"{100 * facts['degenerate_fraction']:.1f} % degenerate triangles "
                     f"({facts['n_zero_area']} zero-area, {facts['n_bridging']} bridging a gap)")
    if not facts.get("turning_ok", True):
        bad = [f"loop {i} turns {t:+.2f} (expected {e:+.0f})" for i, (t, e)
               in enumerate(zip(facts["turning_numbers"], facts["expected_turning"])) if abs(t - e) > TURNING_TOL]
        parts.append("; ".join(bad))
    if _too_distorted(facts):
        parts.append(f"the map stretches whole regions one way (coherent Beltrami coefficient "
                     f"{facts['coherent_beltrami']:.2f} > {coherent_limit(facts.get('normal_tol_deg')):.2g}): "
                     f"it is not conformal")
    if _too_far_outside(facts):
        parts.append(f"{facts['n_outside']} point(s) lie outside the boundary loops, up to "
                     f"{facts['outside_depth']:.2g} spacings deep (a loop cuts across the surface)")
    if facts.get("n_isolated"):
        parts.append(f"{facts['n_isolated']} point(s) lie far from all the others (alone or in a small group, more "
                     f"than {ISOLATED_BOX_SHARE:g} of the point set's extent from the rest): not samples of the "
                     "surface, and their uv means nothing")
    cov = facts.get("coverage")
    if cov and not cov["passed"]:
        parts.append(f"{uncovered_phrase(cov)} (a missed hole?)")
    return "; ".join(parts) if parts else "ok"


def check_pointset_map(points: np.ndarray, uv: np.ndarray, normals: np.ndarray, loops: list | None, *,
                       knn_indices: np.ndarray | None = None, spacing: float | None = None,
                       candidates: np.ndarray | None = None, normal_error_deg: float | None = None,
                       conformal: bool = False) -> dict:
    """Check a point-set map; see the module docstring for the checks and thresholds.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    uv : (N, 2) numpy.ndarray of float64
        The map, one row per point.
    normals : (N, 3) numpy.ndarray of float64
        Consistently oriented point normals (the front end's).
    loops : list of (L_i,) array_like of int, or None
        Detected boundary loops, outer first. None or empty: no constraint, no turning
        check, bridging triangles dropped as outside.
    knn_indices : (N, K) numpy.ndarray of int64, optional
        Neighbour graph; computed (K = 8) when omitted.
    spacing : float, optional
        Mean spacing ``l``; the mean kNN distance when omitted.
    candidates : (N,) numpy.ndarray of bool, optional
        Angle-criterion boundary candidates; no coverage check when omitted.
    normal_error_deg : float, optional
        Median predicted error of the kNN plane fits on ``knn_indices``, degrees, when
        known (see :func:`normal_tolerance_deg`); computed when omitted.
    conformal : bool
        The method promises a conformal map: judge ``coherent_beltrami`` too (the
        "distorted" check); it is reported either way.

    Returns
    -------
    dict
        JSON-serialisable: ``passed`` (bool), ``reason`` (one line; "ok" when passed),
        ``failed`` (names among "triangulation", "flipped", "boundary-crossing",
        "degenerate", "turning", "coverage", "distorted", "outside", "isolated"), ``coherent_beltrami``,
        ``n_isolated`` (points far from all others,
        :func:`~parambench.methods.pointset.stray_points.isolated_mask`),
        ``n_outside`` and ``outside_depth`` (:func:`points_outside`; with loops),
        ``conformal_judged``, ``stretched`` (``coherent_beltrami`` over :func:`coherent_limit`,
        judged or not),
        ``triangulation`` ("cdt", "delaunay", "delaunay-fallback" or "none"),
        ``n_triangles``, ``n_removed_outside``, ``normal_tol_deg``, ``n_flipped``,
        ``n_flipped_slivers`` (of them ``n_flipped_inner_slivers``, not all corners on a
        loop), ``n_flipped_uncertain``, ``mirrored``, ``n_ring_judged`` and ``n_ring_flipped``
        (:func:`~parambench.methods.pointset.ring_orientation.ring_orientation`), ``n_unresolved``
        (:func:`~parambench.methods.pointset.ring_orientation.unresolved_points`),
        ``n_zero_area``, ``n_bridging``, ``n_degenerate``, ``degenerate_fraction``,
        ``turning_numbers`` and ``expected_turning`` (per loop), ``turning_ok``,
        ``coverage`` (:func:`loop_coverage`, or None), ``thresholds``, ``seconds``; when
        flipped or degenerate triangles fail it, ``causes``
        (:func:`~parambench.methods.pointset.failure_causes.failure_causes`: a thin part or a
        collapse, named in ``reason`` too).
    """
    start = time.perf_counter()
    points = np.asarray(points, dtype=np.float64)
    uv = np.asarray(uv, dtype=np.float64)
    loops = [np.asarray(lp, dtype=np.int64) for lp in (loops or [])]
    knn = _knn(points) if knn_indices is None else knn_indices
    spacing_pt = _local_spacing(points, knn)
    l_mean = float(spacing_pt.mean()) if spacing is None else float(spacing)
    facts: dict[str, Any] = {"conformal_judged": bool(conformal),
                             "n_isolated": int(isolated_mask(points, knn).sum())}
    failing = fit_error = None
    if not np.all(np.isfinite(uv)):
        facts.update(triangulation="none", n_triangles=0, reason_override="the map has non-finite uv coordinates")
    else:
        try:
            tri = triangulate_uv(uv, loops)
        except ParambenchError as exc:
            facts.update(triangulation="none", n_triangles=0, reason_override=str(exc).rstrip("."))
        else:
            fit_error = median_fit_error_deg(points, knn, normal_error_deg if knn_indices is not None else None)
            tol = normal_tolerance_deg(points, knn, fit_error)
            on_loop = np.zeros(points.shape[0], dtype=bool)
            for loop in loops or ():
                on_loop[np.asarray(loop, dtype=np.int64)] = True
            face_facts, n_dropped, failing = _face_facts(points, uv, normals, tri.faces, spacing_pt,
                                                         drop_bridging=not loops, tol_deg=tol, on_loop=on_loop)
            facts.update(normal_tol_deg=round(tol, 3), triangulation=tri.kind, n_removed_outside=tri.n_removed + n_dropped,
                         boundary_crosses=tri.boundary_crosses, **face_facts)
            failing = _with_ring_facts(facts, failing, points, uv, normals, knn, loops, spacing_pt, tol)
    if loops and np.all(np.isfinite(uv)):
        # Without triangles to tell a mirror, the outer loop's own sign is taken as the mirror's.
        outer = _outer_in_uv(uv, loops, points)
        mirrored = facts.get("mirrored", turning_number(uv[loops[outer]]) < 0)
        facts.update(_turning(uv, loops, mirrored, outer))
        facts.update(points_outside(uv, loops, knn))
    facts["coverage"] = (loop_coverage(points, loops, candidates, knn, l_mean) if candidates is not None else None)
    failed = []
    if "reason_override" in facts:
        failed.append("triangulation")
    if (facts.get("n_flipped", 0) > MAX_FLIPPED or _too_uncertain(facts) or _too_many_inner_slivers(facts)
            or facts.get("n_ring_flipped", 0) > MAX_RING_FLIPPED):
        failed.append("flipped")
    if facts.get("boundary_crosses", False):
        failed.append("boundary-crossing")
    if facts.get("degenerate_fraction", 0.0) > MAX_DEGENERATE_FRACTION:
        failed.append("degenerate")
    if not facts.get("turning_ok", True):
        failed.append("turning")
    if facts["coverage"] is not None and not facts["coverage"]["passed"]:
        failed.append("coverage")
    # Reported for every map: a method that does not aim at conformality (lem: coherent
    # Beltrami 0.38 on a plane, 0.90 on a frustum) passes its check, and says so.
    facts["stretched"] = _stretched(facts)
    if _too_distorted(facts):
        failed.append("distorted")
    if _too_far_outside(facts):
        failed.append("outside")
    if facts["n_isolated"]:
        failed.append("isolated")
    if failing is not None and ("flipped" in failed or "degenerate" in failed):
        facts["causes"] = failure_causes(points, uv, normals, knn, spacing_pt, failing.faces, failing.flipped,
                                         failing.zero)
    noisy = noisy_cause(fit_error, knn.shape[1])
    if failed and noisy is not None:
        facts.setdefault("causes", {})["noisy"] = noisy
    if failed and "isolated" not in failed:
        handle = handle_cause(points, normals)  # no map to the plane exists: the other causes are beside the point
        if handle is not None:
            facts.setdefault("causes", {})["handle"] = handle
    override = facts.pop("reason_override", None)
    reason = "; ".join(r for r in (override, _reason(facts), describe_causes(facts.get("causes", {})))
                       if r and r != "ok") or "ok"
    facts.update(passed=not failed, reason=reason, failed=failed, thresholds=dict(THRESHOLDS),
                 seconds=round(time.perf_counter() - start, 4))
    return facts


def pointset_faces(points: np.ndarray, uv: np.ndarray, loops: list | None) -> np.ndarray:
    """The triangles the self-check judges a map on, for writing a point-set result as a mesh.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    uv : (N, 2) numpy.ndarray of float64
    loops : list of (L_i,) array_like of int, or None
        Detected boundary loops (``diagnostics["boundary_loops"]``); without them the
        Delaunay triangles bridging more than ``BRIDGE_FACTOR`` local spacings in 3D are
        dropped as lying outside the surface.

    Returns
    -------
    (M, 3) numpy.ndarray of int64
        Counter-clockwise in uv; holes of the loops left empty.

    Raises
    ------
    InvalidInputError
        The uv points cannot be triangulated (a collapsed map).
    """
    points = np.asarray(points, dtype=np.float64)
    loops = [np.asarray(lp, dtype=np.int64) for lp in (loops or [])]
    faces = triangulate_uv(uv, loops).faces
    if loops:
        return faces
    spacing_pt = _local_spacing(points, _knn(points))
    return faces[~_bridging(_longest_edge(points, faces), faces, spacing_pt)]
