"""Distortion metrics of a parameterization.

Everything is per triangle of an evaluation mesh (the surface's own faces, or for a point
set a Delaunay triangulation of the uv layout) and area-weighted with the 3D areas.

Public API: :func:`evaluate` (all metrics as a flat dict: QC, foldovers, area distortion,
the Beltrami coefficient, angle error and its histogram, flipped share), :func:`self_scored`
(a point-set map scored on its own uv triangulation, without ground truth),
:func:`per_face_qc` (for pictures), and the building blocks below. :func:`turning_number` is +1
for a counter-clockwise simple polygon, -1 for a clockwise one.

Nothing here imports the methods' numerics: loops, turning numbers and foldovers are the
evaluation's own (:mod:`parambench.bench.metrics.loops`, :mod:`parambench.bench.metrics.orientation`).
"""

from .alignment import exact_map_error, similarity_align
from .angles import ANGLE_HIST_EDGES_DEG, angle_differences_deg, angle_histogram, triangle_corner_angles
from .distortion import area_distortion, normalized_area_distortion, weighted_quantile
from .eval_mesh import uv_delaunay_faces
from .evaluate import METRIC_KEYS, evaluate
from .jacobian import beltrami_abs, jacobian_singular_values, per_face_qc, quasi_conformal, sigma_ratio_excess
from .loops import mesh_boundary_loops, signed_area_2d, turning_number
from .orientation import (count_collapsed, count_foldovers, flipped_mask, flipped_share, majority_orientation,
                          triangle_signed_areas)
from .selfmesh import SELFMESH_KEYS, points_in_loops, self_scored, uv_loop_faces

__all__ = [
    "evaluate",
    "METRIC_KEYS",
    "per_face_qc",
    "jacobian_singular_values",
    "quasi_conformal",
    "count_foldovers",
    "flipped_mask",
    "triangle_signed_areas",
    "mesh_boundary_loops",
    "count_collapsed",
    "majority_orientation",
    "area_distortion",
    "weighted_quantile",
    "turning_number",
    "signed_area_2d",
    "similarity_align",
    "exact_map_error",
    "uv_delaunay_faces",
    "beltrami_abs",
    "sigma_ratio_excess",
    "normalized_area_distortion",
    "flipped_share",
    "ANGLE_HIST_EDGES_DEG",
    "triangle_corner_angles",
    "angle_differences_deg",
    "angle_histogram",
    "SELFMESH_KEYS",
    "points_in_loops",
    "uv_loop_faces",
    "self_scored",
]
