"""Ground-truth triangle meshes over generated samples: Delaunay in a chart, then checks.

The mesh is the Delaunay triangulation of the points in the shape's meshing chart, minus
triangles whose parameter-domain centroid falls outside the domain (inside a hole). Faces
are oriented counter-clockwise in the chart, which preserves orientation, so they are
counter-clockwise seen from the normals' side. Boundary loops come from the mesh and are
checked against the planted boundary points.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import Delaunay

from .domains import Domain
from .errors import TopologyError

__all__ = ["delaunay_in_chart", "ordered_loops"]


def delaunay_in_chart(chart: np.ndarray, param: np.ndarray, domain: Domain) -> np.ndarray:
    """Delaunay triangles of the chart points that lie in the domain, counter-clockwise.

    Parameters
    ----------
    chart : (n, 2) numpy.ndarray of float64
        Points in the meshing chart.
    param : (n, 2) numpy.ndarray of float64
        The same points in the parameter domain (for the inside test).
    domain : Domain

    Returns
    -------
    (m, 3) numpy.ndarray of int64
    """
    order = _row_snake_order(chart)  # qhull runs ~2x faster on spatially coherent input
    faces = order[Delaunay(chart[order]).simplices].astype(np.int64)
    faces = faces[domain.contains(param[faces].mean(axis=1))]
    a, b, c = chart[faces[:, 0]], chart[faces[:, 1]], chart[faces[:, 2]]
    area2 = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    flip = area2 < 0
    faces[flip] = faces[flip][:, [0, 2, 1]]
    return np.ascontiguousarray(faces)


def _row_snake_order(x: np.ndarray) -> np.ndarray:
    """A permutation visiting the points row by row of a coarse grid, alternating direction."""
    cells = max(1, int(np.sqrt(len(x)) / 4))
    lo, span = x.min(axis=0), max(float(np.ptp(x, axis=0).max()), np.finfo(float).tiny)
    ij = np.minimum(((x - lo) / span * cells).astype(np.int64), cells - 1)
    key = ij[:, 1] * cells + np.where(ij[:, 1] % 2 == 0, ij[:, 0], cells - 1 - ij[:, 0])
    return np.argsort(key, kind="stable")


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
