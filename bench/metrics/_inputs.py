"""Input checks shared by the metric functions (one place, so every entry point agrees)."""

from __future__ import annotations

from typing import Any

import numpy as np

from parambench.datasets_gen.errors import InvalidInputError
from parambench.datasets_gen.surface import validate_faces, validate_points

__all__ = ["check_uv", "check_mesh"]


def check_uv(uv: Any, n_points: int | None = None, *, name: str = "uv") -> np.ndarray:
    """Check a planar map and return it as float64.

    Parameters
    ----------
    uv : (N, 2) array_like of float
    n_points : int, optional
        Required N (the number of surface points).
    name : str
        Used in error messages.

    Returns
    -------
    (N, 2) numpy.ndarray of float64, C-contiguous.

    Raises
    ------
    InvalidInputError
        Wrong shape or dtype, a row count that does not match the points, NaN or inf.
    """
    arr = np.asarray(uv)
    if arr.dtype.kind not in "fiu":
        raise InvalidInputError(f"{name} must be a numeric array, got dtype {arr.dtype}.")
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise InvalidInputError(f"{name} must have shape (N, 2), got {arr.shape}; pass one (u, v) row per point.")
    if n_points is not None and arr.shape[0] != n_points:
        raise InvalidInputError(
            f"{name} has {arr.shape[0]} rows but the surface has {n_points} points; pass one row per point, in input order."
        )
    arr = np.ascontiguousarray(arr, dtype=np.float64)
    bad = ~np.isfinite(arr).all(axis=1)
    if bad.any():
        raise InvalidInputError(
            f"{name} has {int(bad.sum())} row(s) with NaN or infinite coordinates (first: row {int(np.flatnonzero(bad)[0])}); "
            "the method did not place those points, so record the run as a failure instead of measuring it."
        )
    return arr


def check_mesh(points: Any, faces: Any, uv: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Check an evaluation mesh and its map.

    Parameters
    ----------
    points : (N, 3) array_like of float
    faces : (M, 3) array_like of int
    uv : (N, 2) array_like of float

    Returns
    -------
    points : (N, 3) float64, faces : (M, 3) int64, uv : (N, 2) float64

    Raises
    ------
    InvalidInputError
        Bad shapes or dtypes, NaN/inf, face indices out of range.
    DegenerateFacesError
        Faces repeating a vertex or with zero 3D area (their Jacobian is undefined).
    """
    # A single triangle is a legitimate evaluation mesh, hence min_points=3.
    pts = validate_points(points, min_points=3)
    tri = validate_faces(faces, pts.shape[0], pts)
    return pts, tri, check_uv(uv, pts.shape[0])
