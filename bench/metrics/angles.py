"""Angle distortion: corner angles in uv against the same corners in 3D, and their histogram."""

from __future__ import annotations

import numpy as np

# The bins are part of the stored column's meaning, so the results schema owns them.
from ..schema import ANGLE_HIST_EDGES_DEG

__all__ = ["ANGLE_HIST_EDGES_DEG", "triangle_corner_angles", "angle_differences_deg", "angle_error_per_face",
           "angle_histogram"]


def triangle_corner_angles(coords: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Interior angle at every corner of every triangle, in 2D or 3D.

    Parameters
    ----------
    coords : (N, 2) or (N, 3) numpy.ndarray of float64
    faces : (M, 3) numpy.ndarray of int64

    Returns
    -------
    (M, 3) numpy.ndarray of float64
        ``angles[f, c]`` is the angle at vertex ``faces[f, c]`` in radians, in [0, pi]
        (unsigned: a flipped uv triangle has the same angles as its mirror image).
    """
    p = coords[faces]                                   # (M, 3 corners, d)
    e_next = np.roll(p, -1, axis=1) - p
    e_prev = np.roll(p, 1, axis=1) - p
    if coords.shape[1] == 2:
        cross = np.abs(e_next[..., 0] * e_prev[..., 1] - e_next[..., 1] * e_prev[..., 0])
    else:
        cross = np.linalg.norm(np.cross(e_next, e_prev), axis=2)
    dot = np.einsum("fck,fck->fc", e_next, e_prev)
    # atan2 stays accurate near 0 and pi, where arccos of the cosine loses digits.
    return np.arctan2(cross, dot)


def angle_differences_deg(points: np.ndarray, faces: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Signed corner-angle change of the map, uv angle minus 3D angle, in degrees.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    faces : (M, 3) numpy.ndarray of int64
    uv : (N, 2) numpy.ndarray of float64
        Inputs are assumed checked (see :func:`parambench.bench.metrics._inputs.check_mesh`).

    Returns
    -------
    (M, 3) numpy.ndarray of float64
        Each row sums to 0 up to rounding (both triangles' angles sum to 180 degrees).
    """
    return np.degrees(triangle_corner_angles(uv, faces) - triangle_corner_angles(points, faces))


def angle_error_per_face(diff_deg: np.ndarray) -> np.ndarray:
    """Mean absolute corner-angle change of each triangle, in degrees.

    Parameters
    ----------
    diff_deg : (M, 3) numpy.ndarray of float64
        From :func:`angle_differences_deg`.

    Returns
    -------
    (M,) numpy.ndarray of float64
    """
    return np.abs(diff_deg).mean(axis=1)


def angle_histogram(diff_deg: np.ndarray, edges: np.ndarray = ANGLE_HIST_EDGES_DEG) -> np.ndarray:
    """Counts of corner-angle changes over fixed bins, outliers in the end bins.

    Parameters
    ----------
    diff_deg : array_like of float64
        Signed angle changes in degrees (any shape; NaN entries are skipped).
    edges : (B + 1,) numpy.ndarray of float64
        Increasing bin edges.

    Returns
    -------
    (B,) numpy.ndarray of int64
        Sums to the number of finite entries of ``diff_deg``.
    """
    d = np.asarray(diff_deg, dtype=np.float64).ravel()
    d = d[np.isfinite(d)]
    # Clipping into the outer bins keeps the total equal to the number of corners, so a
    # histogram that seems to "lose" corners cannot hide a badly distorted map.
    counts, _ = np.histogram(np.clip(d, edges[0], edges[-1]), bins=edges)
    return counts.astype(np.int64)
