"""Why a point-set map failed its self-check, told from the geometry where it failed.

A parameter hint ("try --param k_nn=16") helps where the neighbourhoods were too small
for the sampling. It cannot help where the points do not resolve the surface, or where
the map itself is right but useless, and there each hint leads to the next one (a cow cut
open and loop-subdivided to 22k points as bare points: ``k_nn=16`` then suggested
``boundary_angle_deg=100``, ``ball_eps_factor=3.5`` suggested ``k_nn=16``), or where the
points themselves are at fault. Three such causes are recognised, and the self-check's
reason names them:

* **thin**: the flipped triangles have a corner with a neighbour across the surface (off
  its tangent plane, within 45 degrees of its normal, nearer than ``THIN_GAP`` local
  spacings) far more often than the points at large do: at least ``MIN_SHARE`` of them,
  and ``ENRICHMENT`` times the share of all points (a sample of ``BASE_SAMPLE``). The
  surface there comes back within about a spacing of itself (an ear, a lip, a fold, a
  fingertip thinner than the sampling) and the neighbourhoods join its two sides.
  Measured on failed ``ocp`` maps (8 neighbours): the cow's ears (18k of the 22k points
  above) all 17 flipped triangles; ``real/camelhead``'s lips 43 % of 116 against 3.3 % of
  all points; ``protrusions`` random 2k 59 % against 1.4 %; ``real/bunny10k`` all 17
  against 5.8 %. Under normal noise of 0.5 spacings most points have such a neighbour
  (77-79 % within 2 spacings), so the share of the flipped ones says nothing there and the
  enrichment rule keeps quiet.
* **collapse**: most zero-area triangles are ones the map shrank, not ones the points
  made: their scale (longest uv edge over longest 3D edge) is below ``COLLAPSE_SCALE`` of
  the median triangle's. A conformal map shrinks a long protrusion exponentially along it
  (the cow's side with its legs, 9.6k points: 607 triangles shrunk 7e4-1e6
  times in length, and ``scp-igl`` on the true mesh has QC 1.43 there); no parameter
  changes that, cutting the protrusion off or a seam along it does.

* **stray**: the flipped or zero-area triangles have a corner off the surface
  (:mod:`.stray_points`), at least ``MIN_SHARE`` of them and ``ENRICHMENT`` times the
  share of all points: a scan's outliers. No parameter of the method helps; removing the
  points does (the command line's ``--repair`` does it). ``bump`` 10k with 5 points at
  random in its bounding box, 100 there, or 50 points lifted 1.9 spacings off the surface
  failed the self-check with a ``k_nn`` hint before.

* **noisy** (named by the self-check, which has the front end's fit facts): a failed map
  of points whose 8-neighbour plane fits predict a median normal error of
  :data:`NOISY_FIT_DEG` = 12 degrees or more (:func:`noisy_cause`; normal noise of 0.25 / 0.5 / 1
  spacings predicts about 8 / 15-16.6 / 18.6 degrees, clean real scans 0.8-1.5). The
  advice: thin the points or smooth them. laspy's test tile ``plane.laz`` (18,335 distinct
  points 1-2 cm apart, heights rounded to 1 cm: 15.4 degrees) failed every retry of
  ``ocp``, ``sdp`` too, and the parameter hints led from one to the next; thinned by
  Poisson-disk sampling to 3 cm (2,685 points) or 5 cm it passes. The front end names the
  same cause where it finds no boundary at all (:func:`noisy_points_note`).

* **handle** (named by the self-check, :func:`~parambench.methods.pointset.handles.handle_cause`):
  the triangles the points' tangent-plane neighbourhoods agree on have genus 1 or more
  over at least half the points. No map to the plane exists; the advice is to cut the
  surface open across each handle, and the method's retries are not run (a torus cut open,
  15,792 points: 4 retries, 16 s, each folding about 950 triangles).

Where no map came out at all (every k search of ``ocp`` failed), :func:`protrusion_shrink`
looks for the same shape in a map that always exists: the harmonic map of the points'
kNN graph (uniform weights) with the outer loop fixed on a circle. It shrinks a
protrusion exponentially along it too, and only a protrusion: measured minimum scale
relative to the median point's, 8 neighbours, ``protrusions`` 2k random / 5k jittered
2.5e-4, the cow's side with its leg stumps (8k points, where every search of ``ocp``
fails with turning numbers 2 on its three correctly found loops) 3.9e-4, against
3.1e-2 to 1.5e-1 on bump, holes, cap (jittered 5k) and saddle (random 5k).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from parambench.datasets_gen.errors import ParambenchError

from .boundary_first_map import harmonic_extension
from ..spectral.subspace import loop_arc_fraction
from .neighbourhoods import KnnGraph, symmetric_adjacency
from .stray_points import offsets_off_surface, stray_mask

__all__ = ["failure_causes", "protrusion_shrink", "harmonic_scale", "describe_causes", "cause_advice", "THIN_GAP", "ENRICHMENT",
           "BASE_SAMPLE", "COLLAPSE_SCALE", "MIN_SHARE", "PROTRUSION_SCALE", "PROTRUSION_MAX_POINTS"]

#: Largest distance across the surface, in local spacings, that counts as "thin".
THIN_GAP = 1.5

#: How many times the share of all points the flipped triangles' share must be.
ENRICHMENT = 5.0

#: Points sampled (evenly by index) for the share of all points.
BASE_SAMPLE = 20000

#: Cosine of the largest angle between a neighbour's offset and the normal, for "across".
_ACROSS_COS = np.cos(np.deg2rad(45.0))

#: Largest scale factor, relative to the median triangle's, of a collapsed triangle.
COLLAPSE_SCALE = 1e-3

#: Share of the failing triangles a cause must explain to be named.
MIN_SHARE = 0.35

#: Largest scale, relative to the median point's, at which the harmonic map of
#: :func:`protrusion_shrink` shows a protrusion (an order of magnitude below what the
#: surfaces without one reach, measured above).
PROTRUSION_SCALE = 1e-3

#: Most points :func:`protrusion_shrink` looks at: it factorises the kNN graph's
#: Laplacian once, which from the two-level path's sizes on costs what a solve does.
PROTRUSION_MAX_POINTS = 200_000

#: Harmonic-map scale under which a point is on a part joined to the rest at a single
#: point (the map is constant there, to rounding): pymeshlab's range scan ``face000``
#: has 49 points under it, in groups whose smallest scales are 6e-16 to 6e-10, where a
#: true protrusion (the cow's leg stumps) reaches 1.2e-4.
HANGING_SCALE = 1e-8


def failure_causes(points: np.ndarray, uv: np.ndarray, normals: np.ndarray, knn_indices: np.ndarray,
                   spacing_pt: np.ndarray, faces: np.ndarray, flipped: np.ndarray, zero: np.ndarray) -> dict:
    """The recognised causes of a failed check, with the figures behind them.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    uv : (N, 2) numpy.ndarray of float64
    normals : (N, 3) numpy.ndarray of float64
        Unit point normals (orientation not used).
    knn_indices : (N, K) numpy.ndarray of int64
        Nearest neighbours of each point (the point itself may be among them).
    spacing_pt : (N,) numpy.ndarray of float64
        Local spacing per point.
    faces : (M, 3) numpy.ndarray of int64
        The self-check's uv triangles.
    flipped, zero : (M,) numpy.ndarray of bool
        Flipped triangles, and zero-area ones.

    Returns
    -------
    dict
        JSON-serialisable; a key per recognised cause: ``"thin"`` with ``share`` (of the
        flipped triangles), ``base_share`` (of all points) and ``gap_spacings`` (median
        distance across, in local spacings), ``"collapse"`` with ``share`` (of the zero-area triangles) and
        ``scale`` (their median scale factor relative to the median triangle's), ``"stray"`` with
        ``share`` (of the flipped and zero-area triangles with a stray corner), ``base_share``
        (of all points), ``points`` (stray points in all) and ``offset_spacings`` (their
        median offset).
    """
    causes: dict = {}
    stray, at_stray = _stray_cause(points, normals, knn_indices, spacing_pt, faces[flipped | zero])
    n_flipped = int(flipped.sum())
    if stray:
        causes["stray"] = stray
        # A point above the surface also looks like the surface coming back near itself:
        # the triangles at stray points are the stray cause's, not a thin part's.
        flipped = flipped & ~at_stray[faces].any(axis=1)
    if flipped.any():
        corners = faces[flipped]
        gap = np.full(points.shape[0], np.inf)
        vertices = np.unique(corners)
        gap[vertices] = _gap_across(points, normals, knn_indices, spacing_pt, vertices)
        face_gap = gap[corners].min(axis=1)
        thin = face_gap < THIN_GAP
        share = float(thin.sum()) / n_flipped  # of every flipped triangle, those at stray points included
        sample = np.arange(0, points.shape[0], max(1, points.shape[0] // BASE_SAMPLE))
        base = float(np.mean(_gap_across(points, normals, knn_indices, spacing_pt, sample) < THIN_GAP))
        if share >= max(MIN_SHARE, ENRICHMENT * base):
            causes["thin"] = {"share": round(share, 3), "base_share": round(base, 4),
                              "gap_spacings": round(float(np.median(face_gap[thin])), 3)}
    if zero.any():
        scale = _scale_factors(points, uv, faces)
        relative = scale[zero] / max(float(np.median(scale)), np.finfo(float).tiny)
        shrunk = relative < COLLAPSE_SCALE
        if shrunk.mean() >= MIN_SHARE:
            causes["collapse"] = {"share": round(float(shrunk.mean()), 3),
                                  "scale": float(f"{np.median(relative[shrunk]):.2g}")}
    return causes


def protrusion_shrink(points: np.ndarray, knn_indices: np.ndarray, outer_loop: np.ndarray) -> dict:
    """A protrusion told from the harmonic map of the points, for an error where no map came out.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    knn_indices : (N, K) numpy.ndarray of int64
        Nearest neighbours of each point (the point itself may be among them).
    outer_loop : (L,) numpy.ndarray of int64
        The outer boundary loop, in order.

    Returns
    -------
    dict
        ``{"protrusion": {"scale": ..., "share": ...}}`` when the smallest scale of
        :func:`harmonic_scale` is below :data:`PROTRUSION_SCALE` (``share``: of the points
        shrunk 100 times or more), ``{"hanging": {"points": ...}}`` for the points whose
        scale is under :data:`HANGING_SCALE` (parts that hang on the rest by single
        points, left out of the protrusion's figures), else empty; empty too above
        :data:`PROTRUSION_MAX_POINTS` points, for fewer than 3 loop points, or when the
        graph's interior block is singular (a piece not connected to the loop).
    """
    if points.shape[0] > PROTRUSION_MAX_POINTS or len(outer_loop) < 3:
        return {}
    try:
        scale = harmonic_scale(points, knn_indices, outer_loop)
    except ParambenchError:
        return {}
    # A harmonic map is constant on a part joined to the rest at one point: its scale is
    # rounding, not an exponential decay (a range scan's loose flaps: 1e-16).
    hanging = scale < HANGING_SCALE
    causes = {}
    if hanging.any():
        causes["hanging"] = {"points": int(hanging.sum())}
    rest = scale[~hanging]
    if rest.size and rest.min() < PROTRUSION_SCALE:
        causes["protrusion"] = {"scale": float(f"{rest.min():.2g}"), "share": round(float(np.mean(rest < 1e-2)), 3)}
    return causes


def harmonic_scale(points: np.ndarray, knn_indices: np.ndarray, outer_loop: np.ndarray) -> np.ndarray:
    """Per point, the local scale of the points' harmonic map, relative to the median point's.

    The symmetrised kNN graph's Laplacian (uniform weights) is solved with ``outer_loop``
    fixed on the unit circle by arc length, every other point free (holes included). A
    point's scale is its mean uv distance to its neighbours over its mean 3D distance.
    On a flat disc the map is near a similarity (scales near 1); on an open tube of
    girth C pinned at one rim, the free rim a length L away shrinks like
    ``1 / cosh(2 pi L / C)`` against the pinned one (the circle's first Fourier mode
    decaying along the tube), ``1 / cosh(pi L / C)`` against the middle.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    knn_indices : (N, K) numpy.ndarray of int64
    outer_loop : (L,) numpy.ndarray of int64

    Returns
    -------
    (N,) numpy.ndarray of float64

    Raises
    ------
    SolverError
        The interior block is singular (a piece of the graph not connected to the loop).
    """
    outer = np.asarray(outer_loop, dtype=np.int64)
    knn = np.asarray(knn_indices, dtype=np.int64)
    lengths = np.linalg.norm(points[knn] - points[:, None, :], axis=2)
    adj = symmetric_adjacency(KnnGraph(knn, lengths, float(lengths.mean())))
    adj.data[:] = 1.0  # uniform weights
    lap = (sp.diags(np.asarray(adj.sum(axis=1)).ravel()) - adj).tocsr()
    angle = 2.0 * np.pi * loop_arc_fraction(points, outer)
    uv = harmonic_extension(lap, outer, np.column_stack([np.cos(angle), np.sin(angle)]))
    uv_lengths = np.linalg.norm(uv[knn] - uv[:, None, :], axis=2)
    scale = uv_lengths.mean(axis=1) / np.maximum(lengths.mean(axis=1), np.finfo(float).tiny)
    return scale / max(float(np.median(scale)), np.finfo(float).tiny)


def _stray_cause(points, normals, knn_indices, spacing_pt, bad_faces) -> tuple[dict, np.ndarray | None]:
    """The "stray" cause's figures and the stray points, or ({}, None) when the failing triangles' corners are not enriched in them."""
    if not len(bad_faces):
        return {}, None
    offset = offsets_off_surface(points, normals, knn_indices, spacing_pt)
    stray = stray_mask(offset)
    face_share = float(stray[bad_faces].any(axis=1).mean())
    if face_share < max(MIN_SHARE, ENRICHMENT * float(stray.mean())):
        return {}, None
    return {"share": round(face_share, 3), "base_share": round(float(stray.mean()), 4), "points": int(stray.sum()),
            "offset_spacings": round(float(np.median(offset[stray])), 2)}, stray


def _gap_across(points, normals, knn_indices, spacing_pt, vertices) -> np.ndarray:
    """Per vertex, the nearest neighbour's offset along the normal, among those across the surface, in spacings (inf: none)."""
    nb = knn_indices[vertices]
    d = points[nb] - points[vertices][:, None, :]
    dist = np.linalg.norm(d, axis=2)
    along = np.abs(np.einsum("vki,vi->vk", d, normals[vertices]))
    across = (dist > 0) & (along > _ACROSS_COS * dist)
    return np.where(across, along, np.inf).min(axis=1) / spacing_pt[vertices]


def _scale_factors(points, uv, faces) -> np.ndarray:
    """Longest uv edge over longest 3D edge, per triangle.

    Edge lengths, not areas: a triangle whose uv corners fall in line has no area but
    keeps its size, and is not a shrunk one.
    """
    def longest(x):
        c = x[faces]
        return np.sqrt(np.max([np.sum((c[:, i] - c[:, (i + 1) % 3]) ** 2, axis=1) for i in range(3)], axis=0))

    with np.errstate(divide="ignore", invalid="ignore"):
        return np.nan_to_num(longest(uv) / longest(points), nan=0.0, posinf=0.0)


#: Median predicted error (degrees) of the points' plane fits on 8 neighbours from which
#: the points are called noisy (:func:`noisy_cause`).
NOISY_FIT_DEG = 12.0


def noisy_cause(fit_error_deg: float | None, k: int) -> dict | None:
    """The ``noisy`` cause from the median predicted error of plane fits on ``k`` neighbours.

    The fits' error falls as 1/K with the K neighbours fitted (measured: 15.4 degrees at 8,
    10.0 at 12 on the same noisy points), so it is judged as on 8.

    Parameters
    ----------
    fit_error_deg : float or None
        Median predicted normal error of the K-neighbour fits, degrees (None: unknown).
    k : int
        Neighbours per fit.

    Returns
    -------
    dict or None
        ``{"normal_fit_error_deg": e}`` (rounded to 0.1) where the error on 8 neighbours is
        at least :data:`NOISY_FIT_DEG`, else None.
    """
    if fit_error_deg is None:
        return None
    on_eight = float(fit_error_deg) * int(k) / 8
    return {"normal_fit_error_deg": round(on_eight, 1)} if on_eight >= NOISY_FIT_DEG else None


def noisy_points_note(fit_error_deg: float | None, k: int) -> str:
    """A sentence naming noise as the likely reason no boundary was found ("" for clean points).

    A rim drowns in noise of half a spacing where two sheets of the surface lie a few
    spacings apart (``fold`` at noise 0.5: its 8-neighbour fits predict 17.9 degrees), and
    points that fill a volume fit planes as badly as points under noise of a spacing (a
    uniform cube: 18.7 degrees); without this note either read as "a closed surface".
    """
    cause = noisy_cause(fit_error_deg, k)
    if cause is None:
        return ""
    said = describe_causes({"noisy": cause})
    advice, _ = cause_advice({"noisy": cause}, [])
    return (f"{said[0].upper()}{said[1:]} (or two sheets of the surface lie within a few spacings of each other, or "
            f"the points fill a volume): {advice}.")


def describe_causes(causes: dict) -> str:
    """What the causes say, for the check's one-line reason ("" without any)."""
    parts = []
    if "thin" in causes:
        c = causes["thin"]
        parts.append(f"{100 * c['share']:.0f} % of the flipped triangles lie where the surface comes within "
                     f"{c['gap_spacings']:.2g} point spacings of itself (a part thinner than the sampling, or bent more "
                     "sharply than it)")
    if "collapse" in causes:
        c = causes["collapse"]
        parts.append(f"{100 * c['share']:.0f} % of the zero-area triangles are ones the map shrank "
                     f"{1 / c['scale']:.1e} times in length (a protrusion: a conformal map shrinks it exponentially)")
    if "stray" in causes:
        c = causes["stray"]
        parts.append(f"{100 * c['share']:.0f} % of the failing triangles have a corner off the surface "
                     f"({c['points']} stray point(s) in all, a median {c['offset_spacings']:g} spacings off their "
                     "neighbours' tangent planes)")
    if "noisy" in causes:
        parts.append(f"the points are noisy: plane fits on 8 neighbours err by {causes['noisy']['normal_fit_error_deg']:g} "
                     "degrees at the median, as under noise of about half their spacing or more")
    if "handle" in causes:
        c = causes["handle"]
        parts.append(f"the points sample a surface with {c['genus']} handle(s), which no map lays flat without a cut "
                     f"(the triangles their neighbourhoods agree on, over {100 * c['share']:.0f} % of the points, "
                     f"have genus {c['genus']})")
    if "hanging" in causes:
        parts.append(f"{causes['hanging']['points']} points hang on the rest by single points (the harmonic map "
                     "of the points is constant on them: loose flaps or strands)")
    if "protrusion" in causes:
        c = causes["protrusion"]
        parts.append(f"the surface has a protrusion: a harmonic map of the points shrinks parts of it "
                     f"{1 / c['scale']:.1e} times ({100 * c['share']:.1f} % of the points 100 times or more), and a "
                     "conformal map shrinks a protrusion exponentially along it")
    return "; ".join(parts)


#: Share of the failing triangles with a stray corner from which a parameter hint is left out.
_STRAY_ALONE = 0.5

#: Share of the flipped triangles at a thin part from which a parameter hint is left out: no
#: parameter separates the sides of a part thinner than the sampling. Measured, with the
#: hint that was given: pymeshlab's cow cut open and subdivided (100 % thin; its retry with
#: k_nn=12 failed, and k_nn=16 folds 31 triangles against 8, then hinted
#: boundary_angle_deg=100), protrusions random 2k at k_nn=16 (100 %, 7 flipped, hinted
#: k_nn=20); camelhead (39 %) and protrusions at the default (59 %) keep their hints.
_THIN_ALONE = 0.75


def cause_advice(causes: dict, failed: list[str]) -> tuple[str, bool]:
    """Advice for the recognised causes, and whether it replaces a parameter hint.

    Returns
    -------
    advice : str
        "" without a recognised cause.
    alone : bool
        True when every failed check is explained by a cause no parameter changes (points
        far from all others, which skew every other fact too; a handle, which no map to
        the plane can have; a collapse, with nothing but
        degenerate triangles failing; stray points at half the failing triangles or more,
        or a thin part at three quarters of the flipped ones or more, with nothing but
        flipped and degenerate ones failing).
    """
    advice = []
    if "handle" in causes:
        advice.append("cut the surface open across each handle (a mug: across its handle) so that one piece with "
                      "no handle is left, or flatten the pieces separately")
    if "thin" in causes:
        advice.append("sample the thin part more densely, or flatten a mesh of the surface (--method scp)")
    if "stray" in causes:
        advice.append("remove the stray points off the surface (a scan's outliers) before flattening")
    if "hanging" in causes:
        advice.append("remove the parts that hang on by single points (a scan's loose flaps and strands)")
    if "noisy" in causes:
        advice.append("thin the points to a spacing several times their noise (e.g. pymeshlab's "
                      "generate_sampling_poisson_disk on the point cloud) or smooth them before flattening")
    if "collapse" in causes or "protrusion" in causes:
        advice.append("cut the shrunk protrusion off, or cut a seam along it, before flattening")
    if "isolated" in failed:
        advice.append("remove the points far from the rest (a scan's junk rows, such as 0 0 0) before flattening")
    only_folds = set(failed) <= {"flipped", "degenerate"}
    alone = ("isolated" in failed or "handle" in causes or ("collapse" in causes and set(failed) == {"degenerate"})
             or ("stray" in causes and causes["stray"]["share"] >= _STRAY_ALONE and only_folds)
             or ("thin" in causes and causes["thin"]["share"] >= _THIN_ALONE and only_folds))
    return "; ".join(advice), alone
