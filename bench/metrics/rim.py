"""Boundary detection scored against a mesh's rim curve, for points that do not lie on it.

Points scattered over a surface (a scan; :func:`parambench.datasets_gen.scattered.scatter_on_mesh`)
have no point on the rim, so "recall and precision of the boundary vertices" has no
vertex set to count. What a detected loop should do there is run along the rim: every
stretch of the rim near some detected point, every detected point near the rim. "Near" is
``RIM_RADIUS_SPACINGS`` mean spacings, the radius within which the self-check counts a
boundary candidate as covered by a loop (``parambench.methods.pointset.selfcheck.COVER_RADIUS``).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

__all__ = ["RIM_RADIUS_SPACINGS", "rim_samples", "rim_recall_precision"]

#: Distance (in mean nearest-neighbour spacings of the points) within which a detected
#: point counts as on the rim and a stretch of rim as found.
RIM_RADIUS_SPACINGS = 3.0


def rim_samples(vertices: np.ndarray, loops: list[np.ndarray], step: float) -> np.ndarray:
    """Points along a mesh's boundary loops (closed polylines), at most ``step`` apart.

    Parameters
    ----------
    vertices : (V, 3) numpy.ndarray of float64
    loops : list of (L_i,) numpy.ndarray of int
        The mesh's boundary loops.
    step : float
        Largest distance between consecutive samples, > 0.

    Returns
    -------
    (S, 3) numpy.ndarray of float64
        Every loop vertex and evenly spaced points on every loop edge.
    """
    out = []
    for loop in loops:
        start = vertices[np.asarray(loop, dtype=np.int64)]
        end = np.roll(start, -1, axis=0)
        pieces = np.maximum(1, np.ceil(np.linalg.norm(end - start, axis=1) / step)).astype(np.int64)
        edge = np.repeat(np.arange(start.shape[0]), pieces)
        # position of each sample along its edge: 0, 1/k, ..., (k-1)/k
        t = (np.arange(edge.size) - np.repeat(np.cumsum(pieces) - pieces, pieces)) / pieces[edge]
        out.append(start[edge] + t[:, None] * (end[edge] - start[edge]))
    return np.concatenate(out) if out else np.empty((0, 3))


def rim_recall_precision(points: np.ndarray, detected: np.ndarray, rim_vertices: np.ndarray,
                         rim_loops: list[np.ndarray], spacing: float,
                         radius_spacings: float = RIM_RADIUS_SPACINGS) -> tuple[float, float | None]:
    """Share of the rim near a detected point, and share of detected points near the rim.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    detected : (N,) numpy.ndarray of bool
        The detector's boundary points.
    rim_vertices : (V, 3) numpy.ndarray of float64
        The mesh the points were drawn from.
    rim_loops : list of (L_i,) numpy.ndarray of int
        Its boundary loops.
    spacing : float
        The points' mean nearest-neighbour distance (the unit of the radius).
    radius_spacings : float

    Returns
    -------
    recall : float
        Share of rim samples (a quarter spacing apart) within the radius of a detected
        point; 0.0 when nothing was detected.
    precision : float or None
        Share of detected points within the radius of the rim; None when nothing was
        detected.
    """
    radius = radius_spacings * spacing
    rim = rim_samples(rim_vertices, rim_loops, 0.25 * spacing)
    found = np.asarray(points)[np.asarray(detected, dtype=bool)]
    if found.shape[0] == 0:
        return 0.0, None
    recall = float(np.mean(cKDTree(found).query(rim)[0] <= radius))
    precision = float(np.mean(cKDTree(rim).query(found)[0] <= radius))
    return recall, precision
