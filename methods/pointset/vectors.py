"""Row-wise 3D vector helpers shared by the boundary steps: unit vectors, tangent-plane parts, distances from lines,
offsets that leave the tangent plane."""

from __future__ import annotations

import numpy as np

__all__ = ["unit_vectors", "in_plane", "distance_from_line", "off_sheet", "OFF_SHEET_SLOPE"]


def unit_vectors(vectors: np.ndarray) -> np.ndarray:
    """``vectors`` (..., 3) scaled to unit length; zero vectors stay zero (no division by zero).

    Parameters
    ----------
    vectors : (..., 3) numpy.ndarray of float64

    Returns
    -------
    (..., 3) numpy.ndarray of float64
    """
    return vectors / np.maximum(np.linalg.norm(vectors, axis=-1, keepdims=True), np.finfo(float).tiny)


def in_plane(vectors: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """``vectors`` (..., 3) without their components along the unit ``normals`` (broadcast against them).

    Parameters
    ----------
    vectors, normals : (..., 3) numpy.ndarray of float64
        ``normals`` of unit length.

    Returns
    -------
    (..., 3) numpy.ndarray of float64
    """
    return vectors - np.einsum("...i,...i->...", vectors, normals)[..., None] * normals


def distance_from_line(rel: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """Length of ``rel`` (..., 3) across the unit ``direction`` (broadcast against it).

    Parameters
    ----------
    rel : (..., 3) numpy.ndarray of float64
        Offsets from a point of the line.
    direction : (..., 3) numpy.ndarray of float64
        The line's unit direction.

    Returns
    -------
    (...,) numpy.ndarray of float64
        Length units.
    """
    return np.linalg.norm(rel - np.einsum("...i,...i->...", rel, direction)[..., None] * direction, axis=-1)


#: An offset that leaves a point's tangent plane at more than this slope (60 degrees: its
#: part along the normal over its length) reaches another sheet of the surface (a rolled
#: surface's next turn, straight across along the normal: 0.95-0.99 on the swiss roll),
#: not a neighbour along it. 30 degrees took noisy neighbours for other sheets (normal
#: noise of 0.5 spacings: rim recall 1.0 -> 0.97-0.99 on four generated surfaces; at 60
#: degrees 1.0 -> 0.993 and 0.996 on two).
OFF_SHEET_SLOPE = np.sin(np.deg2rad(60.0))


def off_sheet(offsets: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """Whether each offset from a point leaves its tangent plane at more than :data:`OFF_SHEET_SLOPE`.

    Projected on the tangent plane, a point of the next turn of a rolled surface lands
    among the point's own neighbours; the boundary steps that look beyond the geodesic
    balls (bridges over a sparse rim, loop crossings) must not take it for one.
    Along one sheet an offset of length d leaves the plane at about d / 2R (R the
    radius of curvature), so the test holds for offsets shorter than the radius.

    Parameters
    ----------
    offsets : (..., 3) numpy.ndarray of float64
    normals : (..., 3) numpy.ndarray of float64
        Unit normals, broadcast against ``offsets``.

    Returns
    -------
    (...,) numpy.ndarray of bool
    """
    across = np.abs(np.einsum("...i,...i->...", offsets, normals))
    return across > OFF_SHEET_SLOPE * np.linalg.norm(offsets, axis=-1)
