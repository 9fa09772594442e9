"""Row-wise 3D vector helpers shared by the boundary steps: unit vectors, tangent-plane parts, distances from lines."""

from __future__ import annotations

import numpy as np

__all__ = ["unit_vectors", "in_plane", "distance_from_line"]


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
