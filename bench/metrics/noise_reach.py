"""Which noisy points lie nearer another part of the surface than their own: a ceiling, not a metric of a method.

Normal noise moves each point of a generated surface off it. Where two parts of the
surface come within a few spacings of each other (a fold's sheets, lips), the noise can
carry a point past the middle of the gap: it then lies nearer the other part than the
place it was sampled from. Its position is all a point-only method sees, so none can tell
it belongs to its own part, and any map puts it among the other part's points. On the
ground-truth mesh, whose faces join it to its own part, its triangles then stretch across
the map and fold. So "0 foldovers" is out of reach of every point-only method on a noisy
sample with such points; :func:`misplaced_by_noise` counts them.
"""

from __future__ import annotations

import igl
import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import dijkstra

__all__ = ["FAR_SPACINGS", "misplaced_by_noise"]

#: A point counts as misplaced when the closest point of the clean surface lies more than
#: this many mean edge lengths from its own vertex along the clean mesh's edges: not its own
#: neighbourhood, which the noise only moves along the normal, but another part of the surface.
FAR_SPACINGS = 3.0

#: Source vertices per batch of the bounded shortest-path search (a dense batch x N array).
_BATCH = 512


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
    if clean.faces is None:
        raise ValueError("the clean surface needs its faces (a mesh or a generated surface).")
    if noisy.points.shape != clean.points.shape:
        raise ValueError(f"the surfaces are not one sampling with and without noise: {len(noisy.points)} against "
                         f"{len(clean.points)} points.")
    if not far > 0:
        raise ValueError(f"far={far} must be positive.")
    vertices, faces = clean.points, np.asarray(clean.faces, dtype=np.int64)
    _, closest_face, _ = igl.point_mesh_squared_distance(noisy.points, vertices, faces)
    edges = np.unique(np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1), axis=0)
    lengths = np.linalg.norm(vertices[edges[:, 0]] - vertices[edges[:, 1]], axis=1)
    reach = far * float(lengths.mean())
    n = len(vertices)
    graph = sp.coo_matrix((lengths, (edges[:, 0], edges[:, 1])), shape=(n, n)).tocsr()
    corners = faces[closest_face]
    misplaced = np.empty(n, dtype=bool)
    for start in range(0, n, _BATCH):
        rows = np.arange(start, min(start + _BATCH, n))
        dist = dijkstra(graph, directed=False, indices=rows, limit=reach)
        misplaced[rows] = np.isinf(np.take_along_axis(dist, corners[rows], axis=1)).all(axis=1)
    return misplaced
