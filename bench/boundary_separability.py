"""Can a point-only test tell a small hole from a gap of the sampling? Measured against the mesh.

A diagnostic, not a detector: it needs a surface with its mesh (faces, true boundary
loops) to label what it measures. Two measurements:

* :func:`face_regularity`: how irregular the sampling is, as quantiles of the mesh faces'
  circumradius over the local spacing (each point's mean kNN distance averaged once over
  its neighbours, the field of the boundary's loop-spacing rule; the smallest of a face's
  corners). On a Delaunay-like mesh a face's circumcircle is (nearly) empty, so this is the
  distribution of empty circles a hole must stand out from.
* :func:`empty_clusters`: the triangles of each point's tangent-plane Delaunay one-ring
  (:func:`parambench.methods.pointset.local_delaunay.local_delaunay_rings` on the 16 nearest
  neighbours, the rings detector's candidates) whose circumradius exceeds ``threshold``
  local spacings, joined into clusters through shared edges. A cluster holding a triangle
  that is no mesh face and has all three corners on one true loop lies over that hole;
  every other cluster is a gap of the sampling. A hole can be found by emptiness alone at
  that threshold only when its cluster is larger than every gap cluster.

Found with it on ``real/bunny10k`` (see ``bench/MEASUREMENTS.md``): its mesh faces are
as irregular as a uniform random sampling (circumradius / local spacing q90 0.98, q99
1.82; random 1.08, 1.45; jittered 0.64, 0.73), and at every threshold from 0.7 to 1.0 the
largest gap cluster of its interior is larger (triangles and area) than the clusters
over its three narrow holes. Run ``python -m parambench.bench.boundary_separability
real/bunny10k``.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from parambench.datasets_gen.surface import circumradii
from parambench.methods.pointset.boundary_rings import _circumradius_area, ring_candidates
from parambench.methods.pointset.local_delaunay import local_delaunay_rings
from parambench.methods.pointset.neighbourhoods import knn_graph, local_spacing

__all__ = ["spacing_around", "face_regularity", "ring_triangles", "hole_triangles", "empty_clusters", "main"]

#: Neighbours of each one-ring's candidates and the slope limit (the rings detector's defaults).
_RING_K = 16
_MAX_SLOPE = 0.8


def spacing_around(points: np.ndarray, boundary: np.ndarray | None = None) -> np.ndarray:
    """Each point's mean 8-NN distance averaged once over its neighbours (the front end's ``h_around``).

    With ``boundary`` (the true boundary vertices), points on it or next to it take the
    mean over their kNN that are neither, as the front end does for ocp's area terms: a
    boundary point's own kNN fill half a disc and overstate its spacing, which would make
    the empty triangles over a hole look smaller than they are (the measurement then
    favours the holes, so a hole that still does not stand out cannot be found this way).
    """
    graph = knn_graph(points, 8)
    h = local_spacing(graph, passes=1)
    if boundary is None:
        return h
    near = boundary | boundary[graph.indices].any(axis=1)
    src = ~near[graph.indices]
    fill = np.where(src, h[graph.indices], 0.0).sum(axis=1) / np.maximum(src.sum(axis=1), 1)
    return np.where(near & src.any(axis=1), fill, h)


def face_regularity(points: np.ndarray, faces: np.ndarray, quantiles=(0.5, 0.9, 0.99)) -> dict:
    """Quantiles of the mesh faces' circumradius over the smallest local spacing of their corners.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    faces : (F, 3) numpy.ndarray of int64
    quantiles : sequence of float

    Returns
    -------
    dict
        ``{"q50": ..., "q90": ..., ...}`` (keys from the quantiles in percent).
    """
    rel = circumradii(points, faces) / spacing_around(points)[faces].min(axis=1)
    return {f"q{100 * q:g}": float(np.quantile(rel, q)) for q in quantiles}


def ring_triangles(points: np.ndarray, normals: np.ndarray, k: int = _RING_K) -> np.ndarray:
    """The distinct triangles of all tangent-plane Delaunay one-rings, corners sorted, (T, 3)."""
    rings = local_delaunay_rings(points, normals, ring_candidates(points, normals, k, _MAX_SLOPE))
    has = rings[..., 0] >= 0
    centre = np.broadcast_to(np.arange(points.shape[0])[:, None], has.shape)
    key = np.sort(np.stack([centre[has], rings[..., 0][has], rings[..., 1][has]], axis=1), axis=1)
    return np.unique(key, axis=0)


def hole_triangles(tri: np.ndarray, faces: np.ndarray, loops) -> np.ndarray:
    """(T,) int: the true loop a triangle lies over (no mesh face, all corners on it), else -1."""
    n = int(max(tri.max(), faces.max())) + 1
    on = np.full(n, -1, dtype=np.int64)
    for j, loop in enumerate(loops):
        on[np.asarray(loop)] = j
    face_key = np.sort(faces, axis=1) @ np.array([n * n, n, 1], dtype=np.int64)
    is_face = np.isin(tri @ np.array([n * n, n, 1], dtype=np.int64), face_key)
    same = (on[tri[:, 0]] >= 0) & (on[tri[:, 0]] == on[tri[:, 1]]) & (on[tri[:, 1]] == on[tri[:, 2]])
    return np.where(same & ~is_face, on[tri[:, 0]], -1)


def empty_clusters(points: np.ndarray, normals: np.ndarray, faces: np.ndarray, loops, threshold: float,
                   tri: np.ndarray | None = None) -> dict:
    """Clusters of large one-ring triangles, split into those over true holes and sampling gaps.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    normals : (N, 3) numpy.ndarray of float64
        Oriented unit normals (e.g. the front end's).
    faces : (F, 3) numpy.ndarray of int64
        The true mesh (labels only).
    loops : list of array_like of int
        The true boundary loops (labels only).
    threshold : float
        Circumradius (on the corners' mean tangent plane) over the smallest local spacing
        of the corners above which a triangle counts as empty; near the true boundary the
        spacing is taken from interior neighbours (:func:`spacing_around`).
    tri : (T, 3) numpy.ndarray of int64, optional
        :func:`ring_triangles`, when already computed.

    Returns
    -------
    dict
        ``holes``: per true loop, ``[triangles, area]`` of its largest cluster (area in
        squared local spacings; ``[0, 0.0]`` when none); ``largest_gap``: the same for
        the largest cluster over no hole; ``gaps_larger``: per loop, how many gap
        clusters have more area than that loop's largest cluster.
    """
    if tri is None:
        tri = ring_triangles(points, normals)
    radius, area = _circumradius_area(points, tri, normals)
    on_loop = np.zeros(points.shape[0], dtype=bool)
    on_loop[np.concatenate([np.asarray(loop) for loop in loops])] = True
    h = spacing_around(points, on_loop)[tri].min(axis=1)
    big = np.flatnonzero(radius / h > threshold)
    over = hole_triangles(tri, faces, loops)[big]
    empty = {"holes": [[0, 0.0] for _ in loops], "largest_gap": [0, 0.0], "gaps_larger": [0 for _ in loops]}
    if big.size == 0:
        return empty
    edges = np.sort(np.concatenate([tri[big][:, [0, 1]], tri[big][:, [1, 2]], tri[big][:, [0, 2]]]), axis=1)
    _, edge_id = np.unique(edges, axis=0, return_inverse=True)
    owner = np.tile(np.arange(big.size), 3)
    inc = sp.csr_matrix((np.ones(owner.size), (owner, edge_id.reshape(-1))), shape=(big.size, int(edge_id.max()) + 1))
    n_clusters, label = connected_components(inc @ inc.T, directed=False)
    count = np.bincount(label, minlength=n_clusters)
    cluster_area = np.bincount(label, weights=area[big] / h[big] ** 2, minlength=n_clusters)
    # A cluster is over hole j when any of its triangles is; a gap cluster over none.
    gap = np.ones(n_clusters, dtype=bool)
    for j in range(len(loops)):
        mine = np.unique(label[over == j])
        gap[mine] = False
        if mine.size:
            best = mine[np.argmax(cluster_area[mine])]
            empty["holes"][j] = [int(count[best]), float(cluster_area[best])]
    if gap.any():
        best = np.flatnonzero(gap)[np.argmax(cluster_area[gap])]
        empty["largest_gap"] = [int(count[best]), float(cluster_area[best])]
    empty["gaps_larger"] = [int(np.count_nonzero(cluster_area[gap] > a)) for _, a in empty["holes"]]
    return empty


def main(argv=None) -> int:
    """Print the regularity and, per threshold, the clusters of a dataset as JSON lines.

    Arguments: dataset name (default ``real/bunny10k``), then for a generated surface its
    point count and sampling (e.g. ``slit 20000 random``).
    """
    import json
    import sys

    from parambench.datasets_gen.registry import make_surface
    from parambench.methods.pointset.frontend import build_frontend

    args = sys.argv[1:] if argv is None else list(argv)
    name = args[0] if args else "real/bunny10k"
    surface = (make_surface(name, int(args[1]), sampling=args[2] if len(args) > 2 else "jittered", seed=0)
               if len(args) > 1 else make_surface(name))
    front = build_frontend(surface.method_input(False).points)
    found = front.boundary_mask
    print(json.dumps({"face_regularity": face_regularity(surface.points, surface.faces),
                      "loop_sizes": [len(loop) for loop in surface.boundary_loops],
                      "detected_share": [float(found[np.asarray(loop)].mean()) for loop in surface.boundary_loops]}))
    tri = ring_triangles(surface.points, front.normals)
    for threshold in (0.7, 0.8, 0.9, 1.0):
        out = empty_clusters(surface.points, front.normals, surface.faces, surface.boundary_loops, threshold, tri)
        print(json.dumps({"threshold": threshold, **out}), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
