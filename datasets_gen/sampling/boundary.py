"""Points on the boundary curves, and removal of interior points that crowd them.

Boundary points are placed at equal arc length along each curve, measured either in the
parameter domain (for the lattice samplings, to match the lattice) or on the surface (for
the area-uniform samplings). Rectangle corners are always boundary points.

Interior points too close to the boundary are removed in the meshing chart, where the
Delaunay triangulation runs: a point inside the disk of radius 0.6 x chord length around a
boundary chord's midpoint (or within 0.45 x the local spacing of a boundary point) goes.
This keeps every boundary chord a Gabriel edge (its diametral disk is empty), so it is an
edge of the Delaunay mesh and the true boundary is exactly the mesh boundary.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

__all__ = ["place_boundary", "curve_length", "near_boundary", "CHORD_CLEARANCE", "VERTEX_CLEARANCE"]

CHORD_CLEARANCE = 0.6
VERTEX_CLEARANCE = 0.45
#: Fewest points on a closed curve made of one segment (a circle), and per rectangle side.
MIN_CIRCLE_POINTS = 8
MIN_SIDE_INTERVALS = 2


def _arc_table(shape, segment, metric: str, m: int, sizing=None) -> tuple[np.ndarray, np.ndarray]:
    """Curve parameters t (m,) and cumulative arc length s (m,), divided by the sizing if given."""
    t = np.linspace(0.0, 1.0, m)
    x = segment(t)
    y = shape.lift(x)[0] if metric == "3d" else x
    ds = np.linalg.norm(np.diff(y, axis=0), axis=1)
    if sizing is not None:
        ds = ds / sizing(0.5 * (x[1:] + x[:-1]))
    return t, np.concatenate([[0.0], np.cumsum(ds)])


def curve_length(shape, metric: str, m: int = 4097, sizing=None) -> float:
    """Total length of all boundary curves, in parameter ("param") or surface ("3d") units.

    With a ``sizing`` (a callable giving the relative spacing sigma at (n, 2) parameter
    points), the length is the integral of ds / sigma: the number of points at unit spacing.
    """
    return float(sum(_arc_table(shape, seg, metric, m, sizing)[1][-1]
                     for curve in shape.domain.curves() for seg in curve))


def place_boundary(shape, h: float, metric: str, *, jitter: float = 0.0,
                   rng: np.random.Generator | None = None, sizing=None) -> list[np.ndarray]:
    """Boundary points of every curve at spacing ~``h`` (``h * sigma(x)`` with a sizing).

    Parameters
    ----------
    shape : Shape
    h : float
        Target spacing, in the units of ``metric``.
    metric : {"param", "3d"}
        Measure arc length in the parameter domain or on the surface.
    jitter : float
        Uniform random shift of each non-corner point along the curve, as a fraction of
        the spacing (0.25 keeps the order and a spacing of at least half the mean).
    rng : numpy.random.Generator
        Required when ``jitter > 0``.
    sizing : callable, optional
        Relative spacing sigma at (n, 2) parameter points, (n,) values > 0: the local
        spacing is ``h * sigma`` (points at equal steps of the integral of ds / sigma).

    Returns
    -------
    list of (L_k, 2) numpy.ndarray of float64
        Parameter points per curve (outer first, then holes), in order along the curve.
    """
    loops = []
    for curve in shape.domain.curves():
        closed_single = len(curve) == 1
        parts = []
        for seg in curve:
            t, s = _arc_table(shape, seg, metric, 257, sizing)
            m = int(max(1025, 16 * s[-1] / h + 1))
            t, s = _arc_table(shape, seg, metric, m, sizing)
            n = max(MIN_CIRCLE_POINTS if closed_single else MIN_SIDE_INTERVALS, round(s[-1] / h))
            step = s[-1] / n
            k = np.arange(n, dtype=float)
            if jitter > 0:
                shift = rng.uniform(-jitter, jitter, n)
                if not closed_single:
                    shift[0] = 0.0  # corners stay put
                k = k + shift
            parts.append(seg(np.interp(np.mod(k * step, s[-1]), s, t)))
        loops.append(np.concatenate(parts))
    return loops


def near_boundary(points: np.ndarray, loops: list[np.ndarray]) -> np.ndarray:
    """Which points crowd a boundary chord or boundary point (see the module docstring).

    Parameters
    ----------
    points : (n, 2) numpy.ndarray of float64
        Interior points, in the meshing chart.
    loops : list of (L_k, 2) numpy.ndarray of float64
        Boundary points per closed curve, in order, in the same chart.

    Returns
    -------
    (n,) numpy.ndarray of bool
        True for points to remove.
    """
    if len(points) == 0:
        return np.zeros(0, dtype=bool)
    centers, radii = [], []
    for loop in loops:
        nxt = np.roll(loop, -1, axis=0)
        length = np.linalg.norm(nxt - loop, axis=1)
        centers += [0.5 * (loop + nxt), loop]
        radii += [CHORD_CLEARANCE * length, VERTEX_CLEARANCE * 0.5 * (length + np.roll(length, 1))]
    centers, radii = np.concatenate(centers), np.concatenate(radii)
    tree = cKDTree(centers)
    # Most points are far from every boundary: a bounded nearest query rules them out fast.
    first, _ = tree.query(points, k=1, distance_upper_bound=float(radii.max()))
    close = np.flatnonzero(np.isfinite(first))
    crowd = np.zeros(len(points), dtype=bool)
    if len(close):
        k = min(8, len(centers))
        dist, idx = tree.query(points[close], k=k)
        if k == 1:
            dist, idx = dist[:, None], idx[:, None]
        crowd[close] = np.any(dist < radii[idx], axis=1)
    return crowd
