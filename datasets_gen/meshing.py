"""Ground-truth triangle meshes over generated samples: Delaunay in a chart, then checks.

The mesh is the constrained Delaunay triangulation of the points in the shape's meshing
chart, bounded by the planted boundary chords, with the holes removed. Faces are oriented
counter-clockwise in the chart, which preserves orientation, so they are counter-clockwise
seen from the normals' side. Boundary loops come from the mesh and are checked against the
planted boundary points.
"""

from __future__ import annotations

import numpy as np
from igl.triangle import triangulate

from .errors import TopologyError
from .surface import counter_clockwise

__all__ = ["delaunay_in_chart", "ordered_loops"]


def delaunay_in_chart(chart: np.ndarray, segments: np.ndarray, hole_seeds: np.ndarray) -> np.ndarray:
    """Constrained Delaunay triangulation of chart points inside the boundary segments.

    Uses Shewchuk's Triangle (``igl.triangle``): exact predicates, so near-coincident
    points (a fingertip squeezed by a conformal chart, or random samples) are handled
    robustly, and ~20x faster than qhull at a million points. No point is added.

    Parameters
    ----------
    chart : (n, 2) numpy.ndarray of float64
        Points in the meshing chart.
    segments : (s, 2) numpy.ndarray of int64
        Boundary chords (outer curve and holes), which become mesh edges.
    hole_seeds : (k, 2) numpy.ndarray of float64
        One chart point inside each hole (triangles reachable from it are removed).

    Returns
    -------
    (m, 3) numpy.ndarray of int64
        Counter-clockwise in the chart.

    Raises
    ------
    TopologyError
        Triangle added or moved points (a generator bug).
    """
    vertices, faces, *_ = triangulate(np.ascontiguousarray(chart, dtype=np.float64),
                                      np.ascontiguousarray(segments, dtype=np.int64),
                                      np.ascontiguousarray(np.reshape(hole_seeds, (-1, 2)), dtype=np.float64),
                                      flags="pQ")
    if vertices.shape != chart.shape or not np.array_equal(vertices, chart):
        raise TopologyError("internal error: the triangulator changed the points; please report this "
                            "with the dataset name and seed.")
    return np.ascontiguousarray(counter_clockwise(chart, np.asarray(faces, dtype=np.int64)))


def ordered_loops(faces: np.ndarray, labels: np.ndarray, chart: np.ndarray) -> list[np.ndarray]:
    """The mesh's boundary loops, one per planted curve, oriented with the faces.

    Boundary half-edges are the faces' directed edges between two planted boundary points
    whose reverse is no face edge; each planted point must have exactly one outgoing and
    one incoming boundary half-edge. Every other vertex must be interior, i.e. its face
    angles in the chart sum to 2 pi (a vectorised check over all faces).

    Parameters
    ----------
    faces : (m, 3) numpy.ndarray of int64
        Counter-clockwise in the chart.
    labels : (n,) numpy.ndarray of int64
        Curve index (0 outer, 1.. holes) of each planted boundary point, -1 for interior points.
    chart : (n, 2) numpy.ndarray of float64
        The meshing chart.

    Returns
    -------
    list of (L_k,) numpy.ndarray of int64
        One loop per curve in label order, each following the faces' orientation
        (outer counter-clockwise, holes clockwise) and starting at its smallest index.

    Raises
    ------
    TopologyError
        The mesh boundary differs from the planted boundary (a generator bug).
    """
    n = len(labels)
    planted = labels >= 0
    _require_interior_angle_sums(faces, chart, ~planted)
    tail, head = faces.ravel(), np.roll(faces, -1, axis=1).ravel()
    on_curve = planted[tail] & planted[head]
    tail, head = tail[on_curve], head[on_curve]
    key, reverse = tail * n + head, head * n + tail
    boundary = ~np.isin(key, reverse)
    tail, head = tail[boundary], head[boundary]
    out_deg = np.bincount(tail, minlength=n)
    in_deg = np.bincount(head, minlength=n)
    if np.any(out_deg[planted] != 1) or np.any(in_deg[planted] != 1):
        raise TopologyError("internal error: a planted boundary point is not on exactly one boundary loop; "
                            "please report this with the dataset name and seed.")
    nxt = np.full(n, -1, dtype=np.int64)
    nxt[tail] = head
    loops: dict[int, np.ndarray] = {}
    visited = np.zeros(n, dtype=bool)
    # Walking a loop visits O(sqrt(N)) boundary points once each; no vectorised form needed.
    for start in np.flatnonzero(planted):
        if visited[start]:
            continue
        loop = [int(start)]
        visited[start] = True
        v = int(nxt[start])
        while v != start:
            loop.append(v)
            visited[v] = True
            v = int(nxt[v])
        loop = np.asarray(loop, dtype=np.int64)
        label = np.unique(labels[loop])
        if len(label) != 1 or int(label[0]) in loops:
            raise TopologyError("internal error: a boundary loop mixes or repeats planted curves; please report this.")
        loops[int(label[0])] = np.roll(loop, -int(np.argmin(loop)))
    return [loops[k] for k in range(len(loops))]


def _require_interior_angle_sums(faces: np.ndarray, chart: np.ndarray, interior: np.ndarray) -> None:
    """Raise unless the chart angles around every interior vertex sum to 2 pi."""
    p = chart[faces]
    total = np.zeros(len(chart))
    for k in range(3):
        u = p[:, (k + 1) % 3] - p[:, k]
        v = p[:, (k + 2) % 3] - p[:, k]
        angle = np.arctan2(np.abs(u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]), np.einsum("ij,ij->i", u, v))
        total += np.bincount(faces[:, k], weights=angle, minlength=len(chart))
    bad = interior & (np.abs(total - 2.0 * np.pi) > 1e-6)
    if bad.any():
        raise TopologyError(f"internal error: {int(bad.sum())} interior point(s) lie on a hole of the generated "
                            "mesh; please report this with the dataset name and seed.")
