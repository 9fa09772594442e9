"""Planar polygon geometry shared by solvers (turning-number penalty) and metrics."""

from __future__ import annotations

import numpy as np

__all__ = ["signed_area_2d", "turning_number"]


def signed_area_2d(polygon: np.ndarray) -> float:
    """Signed area of a closed 2D polygon (shoelace formula), positive if counter-clockwise.

    Parameters
    ----------
    polygon : (L, 2) numpy.ndarray of float64
        Vertices in order; the closing edge from the last to the first is implied.
    """
    x, y = polygon[:, 0], polygon[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def turning_number(polygon: np.ndarray) -> float:
    """Turning number of a closed 2D polygon: total signed exterior angle over 2 pi.

    +1 for a simple counter-clockwise polygon, -1 for a clockwise one, 2 for a boundary
    that winds twice (the "spinning" of Sec. 4.2). Zero-length edges are skipped.

    Parameters
    ----------
    polygon : (L, 2) numpy.ndarray of float64
        Vertices in order; the closing edge is implied.

    Returns
    -------
    float
        Exact to rounding error for a closed polygon (an integer up to ~1e-12).
    """
    edges = np.roll(polygon, -1, axis=0) - polygon
    keep = np.hypot(edges[:, 0], edges[:, 1]) > 0
    edges = edges[keep]
    if len(edges) < 2:
        return 0.0
    nxt = np.roll(edges, -1, axis=0)
    cross = edges[:, 0] * nxt[:, 1] - edges[:, 1] * nxt[:, 0]
    dot = np.einsum("ij,ij->i", edges, nxt)
    return float(np.arctan2(cross, dot).sum() / (2.0 * np.pi))
