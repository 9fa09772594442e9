"""Distortion metrics of a parameterization.

Everything is per triangle of an evaluation mesh (the surface's own faces, or for a point
set a Delaunay triangulation of the uv layout) and area-weighted with the 3D areas.

Public API: :func:`evaluate` (all metrics as a flat dict), :func:`per_face_qc` (for
pictures), and the building blocks below. :func:`turning_number` (re-exported from
:mod:`methods.geometry2d`) is +1 for a counter-clockwise simple polygon, -1 for a
clockwise one.
"""

from methods.geometry2d import signed_area_2d, turning_number

from .alignment import exact_map_error, similarity_align
from .distortion import area_distortion, weighted_quantile
from .eval_mesh import uv_delaunay_faces
from .evaluate import METRIC_KEYS, evaluate
from .jacobian import jacobian_singular_values, per_face_qc, quasi_conformal
from .orientation import count_collapsed, count_foldovers, majority_orientation

__all__ = [
    "evaluate",
    "METRIC_KEYS",
    "per_face_qc",
    "jacobian_singular_values",
    "quasi_conformal",
    "count_foldovers",
    "count_collapsed",
    "majority_orientation",
    "area_distortion",
    "weighted_quantile",
    "turning_number",
    "signed_area_2d",
    "similarity_align",
    "exact_map_error",
    "uv_delaunay_faces",
]
