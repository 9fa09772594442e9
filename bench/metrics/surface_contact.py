"""Where a surface comes nearer itself than its sampling resolves: facts of a case, not metrics of a method.

A point-only method sees positions. Two situations put points nearer another part of the
surface than the sampling can tell apart, and the benchmark reports them beside the
method's figures, measured against the mesh:

* :func:`misplaced_by_noise`: normal noise carried a point past the middle of a narrow gap
  (a fold's sheets), so it lies nearer the other part than the place it was sampled from.
  Its position is all a method sees, so none can place it on its own part: any map puts it
  among the other part's points, and on the ground-truth mesh, whose faces join it to its
  own part, its triangles stretch across the map and fold. "0 foldovers" is then out of
  reach of every point-only method.
* :func:`touching_points`: the surface itself touches (closed lips, the folds of a cortex):
  points with a point of another part of the surface nearer than half their own edge
  length. Their Euclidean neighbourhoods mix the two parts; only the normals can still
  separate them, where the parts meet face to face.

"Another part" means farther than ``far`` mean edge lengths along the mesh's edges.
"""

from __future__ import annotations

import igl
import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import dijkstra
from scipy.spatial import cKDTree

__all__ = ["FAR_SPACINGS", "TOUCH_SPACINGS", "misplaced_by_noise", "touching_points"]

#: Farther than this many mean edge lengths along the mesh's edges is another part of the
#: surface: not a point's own neighbourhood, which normal noise only moves along the normal.
FAR_SPACINGS = 3.0

#: A point touches another part of the surface when one of its points is nearer than this
#: share of the point's mean edge length.
TOUCH_SPACINGS = 0.5

#: Candidates per point examined by :func:`touching_points` (nearest first).
_TOUCH_CANDIDATES = 16

#: Source vertices per batch of the bounded shortest-path search (a dense batch x N array).
_BATCH = 512


def _mesh_edges(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unique undirected edges (E, 2) and their lengths (E,)."""
    edges = np.unique(np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1),
                      axis=0)
    return edges, np.linalg.norm(vertices[edges[:, 0]] - vertices[edges[:, 1]], axis=1)


def _far_along_mesh(n: int, edges: np.ndarray, lengths: np.ndarray, targets: np.ndarray, reach: float) -> np.ndarray:
    """(N, T) bool: target ``targets[i, t]`` lies farther than ``reach`` from vertex i along the edges."""
    graph = sp.coo_matrix((lengths, (edges[:, 0], edges[:, 1])), shape=(n, n)).tocsr()
    far = np.empty(targets.shape, dtype=bool)
    for start in range(0, n, _BATCH):
        rows = np.arange(start, min(start + _BATCH, n))
        dist = dijkstra(graph, directed=False, indices=rows, limit=reach)
        far[rows] = np.isinf(np.take_along_axis(dist, targets[rows], axis=1))
    return far


def _checked(far: float, clean) -> tuple[np.ndarray, np.ndarray]:
    if clean.faces is None:
        raise ValueError("the surface needs its faces (a mesh or a generated surface).")
    if not far > 0:
        raise ValueError(f"far={far} must be positive.")
    return clean.points, np.asarray(clean.faces, dtype=np.int64)


def misplaced_by_noise(noisy, clean, far: float = FAR_SPACINGS) -> np.ndarray:
    """The points of ``noisy`` nearer another part of the clean surface than their own.

    Parameters
    ----------
    noisy : parambench.datasets_gen.surface.Surface
        A surface with normal noise: point i is vertex i of ``clean`` moved off it.
    clean : parambench.datasets_gen.surface.Surface
        The same surface without noise, with ``faces`` (for a generated surface, the same
        generator call with ``noise=0``).
    far : float
        In mean edge lengths of ``clean``'s mesh, > 0.

    Returns
    -------
    (N,) numpy.ndarray of bool
        True where the closest point of ``clean``'s mesh to noisy point i lies on a face
        none of whose corners is within ``far`` mean edge lengths of vertex i along the
        mesh's edges.

    Raises
    ------
    ValueError
        The surfaces differ in their number of points, ``clean`` has no faces, or ``far``
        is not positive.
    """
    vertices, faces = _checked(far, clean)
    if noisy.points.shape != vertices.shape:
        raise ValueError(f"the surfaces are not one sampling with and without noise: {len(noisy.points)} against "
                         f"{len(vertices)} points.")
    _, closest_face, _ = igl.point_mesh_squared_distance(noisy.points, vertices, faces)
    edges, lengths = _mesh_edges(vertices, faces)
    far_corners = _far_along_mesh(len(vertices), edges, lengths, faces[closest_face], far * float(lengths.mean()))
    return far_corners.all(axis=1)


def touching_points(surface, far: float = FAR_SPACINGS, touch: float = TOUCH_SPACINGS) -> np.ndarray:
    """The vertices of a mesh with a vertex of another part of the surface within ``touch`` of their edge length.

    Parameters
    ----------
    surface : parambench.datasets_gen.surface.Surface
        A mesh (``faces`` given).
    far : float
        In mean edge lengths of the mesh, > 0: what counts as another part.
    touch : float
        In the vertex's own mean edge length, > 0.

    Returns
    -------
    (N,) numpy.ndarray of bool
        True where one of the vertex's nearest vertices (Euclidean, at most
        ``_TOUCH_CANDIDATES``) lies nearer than ``touch`` times the vertex's mean edge
        length and farther than ``far`` mean edge lengths along the mesh's edges.

    Raises
    ------
    ValueError
        No faces, or ``far`` or ``touch`` not positive.
    """
    vertices, faces = _checked(far, surface)
    if not touch > 0:
        raise ValueError(f"touch={touch} must be positive.")
    edges, lengths = _mesh_edges(vertices, faces)
    n = len(vertices)
    ring = np.bincount(edges.ravel(), np.repeat(lengths, 2), minlength=n)
    degree = np.bincount(edges.ravel(), minlength=n)
    ring = np.divide(ring, degree, out=np.zeros(n), where=degree > 0)  # unreferenced: never touching
    k = min(_TOUCH_CANDIDATES, n - 1)
    dist, near = cKDTree(vertices).query(vertices, k=k + 1)
    dist, near = dist[:, 1:], near[:, 1:]
    close = dist < touch * ring[:, None]
    far_along = _far_along_mesh(n, edges, lengths, near, far * float(lengths.mean()))
    return (close & far_along).any(axis=1)
