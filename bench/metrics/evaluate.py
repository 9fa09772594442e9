"""All distortion metrics of one parameterization, as a flat JSON-ready dict."""

from __future__ import annotations

import numpy as np

from parambench.datasets_gen.errors import InvalidInputError

from ..schema import METRIC_KEYS

from ._inputs import check_mesh, check_uv
from .alignment import exact_map_error
from .angles import angle_differences_deg, angle_error_per_face, angle_histogram
from .distortion import area_distortion, normalized_area_distortion, weighted_quantile
from .eval_mesh import uv_delaunay_faces
from .jacobian import beltrami_abs, face_jacobian_sv, quasi_conformal, sigma_ratio_excess
from .loops import mesh_boundary_loops, turning_number
from .orientation import collapsed_mask, count_foldovers, flipped_share, majority_orientation

__all__ = ["evaluate", "METRIC_KEYS"]


def _check_loops(loops, n_points: int) -> list[np.ndarray]:
    out = []
    for i, loop in enumerate(loops):
        arr = np.asarray(loop)
        if arr.ndim != 1 or arr.dtype.kind not in "iu":
            raise InvalidInputError(f"boundary loop {i} must be a 1-D integer array of point indices, got {arr.dtype} {arr.shape}.")
        if arr.size and (arr.min() < 0 or arr.max() >= n_points):
            raise InvalidInputError(f"boundary loop {i} has indices outside [0, {n_points - 1}]; indices are 0-based.")
        out.append(arr.astype(np.int64))
    return out


def evaluate(points, faces, uv, *, exact_uv=None, boundary_loops=None, diameter=None) -> dict:
    """Measure the distortion of a map of a triangulated (or point-sampled) surface.

    Parameters
    ----------
    points : (N, 3) array_like of float64
    faces : (M, 3) array_like of int64 or None
        Evaluation mesh. None for a point set: :func:`uv_delaunay_faces` builds one.
    uv : (N, 2) array_like of float64
        The map, one row per point.
    exact_uv : (N, 2) array_like of float64, optional
        Known exact map; gives ``exact_error``.
    boundary_loops : list of (L_i,) array_like of int, optional
        Point indices of each boundary loop, outer first. Default: the loops of the
        evaluation mesh (longest first, :func:`parambench.bench.metrics.loops.mesh_boundary_loops`). For a point set pass the surface's own loops:
        the uv Delaunay mesh has extra small holes wherever the sampling is sparse or the
        map tears (uniform random samples of a disk give about one per 200 points), and
        loops through its non-manifold vertices can have turning number 0.
    diameter : float, optional
        Passed to :func:`exact_map_error` (default: bbox diagonal of ``exact_uv``).

    Returns
    -------
    dict
        JSON-serialisable values, keys :data:`METRIC_KEYS`:

        - ``qc_mean``, ``qc_p95``, ``qc_max``: 3D-area-weighted mean, weighted 95th
          percentile (inverted CDF) and maximum of ``s1/s2`` over the non-collapsed faces
          (flipped faces included: their QC measures their shape, the flip is in ``foldovers``).
        - ``foldovers`` (int), ``foldover_fraction`` (of ``n_eval_faces``): faces whose uv
          orientation opposes the majority.
        - ``collapsed`` (int): faces with zero uv area, left out of the QC and area numbers.
        - ``area_distortion``: see :func:`area_distortion`.
        - ``turning_numbers``: one float per loop, in loop order, multiplied by the majority
          orientation (+1/-1) so that a faithful map gives +1 for an outer loop and -1 for
          holes when the loops follow the face orientation, whether or not uv is mirrored.
        - ``exact_error``: :func:`exact_map_error` or None.
        - ``n_eval_faces`` (int).

        - ``mu_mean``, ``mu_sd``, ``mu_p95``: 3D-area-weighted mean, standard deviation
          and 95th percentile of the Beltrami coefficient's modulus
          ``|mu| = (s1 - s2) / (s1 + s2)`` (:func:`beltrami_abs`), over the same faces as QC.
        - ``area_distortion_normalized``: :func:`normalized_area_distortion` (mean
          ``|log|`` of the area ratio with both total areas normalised to 1).
        - ``sigma_ratio_max``: ``max(s1/s2 + s2/s1) - 2`` (:func:`sigma_ratio_excess`).
        - ``angle_error_mean``: 3D-area-weighted mean over faces of the mean
          ``|angle in uv - angle in 3D|`` over the face's three corners, in degrees.
        - ``flipped_share``: :func:`flipped_share`, ``min(p, 1 - p)``.
        - ``angle_hist``: list of int, counts of the signed corner-angle changes (degrees)
          of the non-collapsed faces over :data:`ANGLE_HIST_EDGES_DEG`.

        QC, Beltrami, angle and area values are None when every face collapsed.

    Raises
    ------
    InvalidInputError
        Bad shapes, NaN/inf in points or uv, indices out of range.
    DegenerateFacesError
        Faces with a repeated vertex or zero 3D area.
    """
    if faces is None:
        faces = uv_delaunay_faces(points, uv)
    pts, tri, uv = check_mesh(points, faces, uv)
    s1, s2, signed, area = face_jacobian_sv(pts, tri, uv)

    collapsed = collapsed_mask(signed)
    n_faces = int(tri.shape[0])
    foldovers = count_foldovers(signed)
    shape = _face_shape_metrics(pts, tri, uv, s1, s2, signed, area, ~collapsed)

    loops = mesh_boundary_loops(tri) if boundary_loops is None else _check_loops(boundary_loops, pts.shape[0])
    turning = _oriented_turning_numbers(uv, loops, majority_orientation(signed))

    exact_error = None
    if exact_uv is not None:
        exact_error = exact_map_error(uv, check_uv(exact_uv, pts.shape[0], name="exact_uv"), diameter)

    return {
        "qc_mean": shape["qc_mean"],
        "qc_p95": shape["qc_p95"],
        "qc_max": shape["qc_max"],
        "foldovers": foldovers,
        "foldover_fraction": foldovers / n_faces,
        "collapsed": int(collapsed.sum()),
        "area_distortion": shape["area_distortion"],
        "turning_numbers": turning,
        "exact_error": exact_error,
        "n_eval_faces": n_faces,
        "mu_mean": shape["mu_mean"],
        "mu_sd": shape["mu_sd"],
        "mu_p95": shape["mu_p95"],
        "area_distortion_normalized": shape["area_distortion_normalized"],
        "sigma_ratio_max": shape["sigma_ratio_max"],
        "angle_error_mean": shape["angle_error_mean"],
        "flipped_share": shape["flipped_share"],
        "angle_hist": shape["angle_hist"],
    }


#: The keys of :func:`_face_shape_metrics`, all None when every face collapsed.
_SHAPE_KEYS = ("qc_mean", "qc_p95", "qc_max", "area_distortion", "mu_mean", "mu_sd", "mu_p95",
              "area_distortion_normalized", "sigma_ratio_max", "angle_error_mean", "flipped_share", "angle_hist")


def _face_shape_metrics(pts: np.ndarray, tri: np.ndarray, uv: np.ndarray, s1: np.ndarray, s2: np.ndarray,
                       signed: np.ndarray, area: np.ndarray, live: np.ndarray) -> dict:
    """QC, Beltrami, area and angle distortion over the non-collapsed faces, weighted by 3D area.

    Parameters
    ----------
    pts : (N, 3) numpy.ndarray of float64
    tri : (M, 3) numpy.ndarray of int64
    uv : (N, 2) numpy.ndarray of float64
    s1, s2 : (M,) numpy.ndarray of float64
        Singular values of each face's Jacobian, s1 >= s2 (:func:`face_jacobian_sv`).
    signed : (M,) numpy.ndarray of float64
        Signed uv areas (the orientation of each face).
    area : (M,) numpy.ndarray of float64
        3D face areas, the weights.
    live : (M,) numpy.ndarray of bool
        Faces with non-zero uv area; the others are left out.

    Returns
    -------
    dict
        The :data:`_SHAPE_KEYS` as in :func:`evaluate`; every value None when no face is live.
        ``area_distortion_normalized`` and ``flipped_share`` use all faces, as the
        functions they come from handle collapsed faces themselves.
    """
    if not live.any():
        return dict.fromkeys(_SHAPE_KEYS)
    qc = quasi_conformal(s1[live], s2[live])
    w = area[live]
    mu = beltrami_abs(s1[live], s2[live])
    mu_mean = float(np.average(mu, weights=w))
    diff = angle_differences_deg(pts, tri[live], uv)
    return {
        "qc_mean": float(np.average(qc, weights=w)),
        "qc_p95": weighted_quantile(qc, w, 0.95),
        "qc_max": float(qc.max()),
        "area_distortion": area_distortion(s1[live], s2[live], w),
        "mu_mean": mu_mean,
        "mu_sd": float(np.sqrt(np.average((mu - mu_mean) ** 2, weights=w))),
        "mu_p95": weighted_quantile(mu, w, 0.95),
        "area_distortion_normalized": normalized_area_distortion(s1, s2, area),
        "sigma_ratio_max": float(sigma_ratio_excess(s1[live], s2[live]).max()),
        "angle_error_mean": float(np.average(angle_error_per_face(diff), weights=w)),
        "flipped_share": flipped_share(signed),
        "angle_hist": angle_histogram(diff).tolist(),
    }


def _oriented_turning_numbers(uv: np.ndarray, loops: list[np.ndarray], orient: int) -> list[float]:
    """Turning number of each loop's uv image, times the map's majority orientation (+1 or -1).

    Parameters
    ----------
    uv : (N, 2) numpy.ndarray of float64
    loops : list of (L_i,) numpy.ndarray of int64
    orient : int
        :func:`majority_orientation` of the faces, so a mirrored map gives the same numbers.

    Returns
    -------
    list of float
        One per loop, in loop order.
    """
    return [float(orient * turning_number(uv[loop])) for loop in loops]
