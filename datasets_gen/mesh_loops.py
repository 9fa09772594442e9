"""Boundary loops of a given (e.g. loaded) triangle mesh, oriented with its faces."""

from __future__ import annotations

import igl
import numpy as np

__all__ = ["mesh_boundary", "orient_loop_with_faces"]


def orient_loop_with_faces(loop: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Reverse a boundary loop if needed so it runs along its faces' directed edges.

    A loop that follows its faces' orientation is counter-clockwise as seen from the
    side the faces' normals point to when it is the outer boundary, clockwise around a hole.

    Parameters
    ----------
    loop : (L,) numpy.ndarray of int64, L >= 2
    faces : (m, 3) numpy.ndarray of int64

    Returns
    -------
    (L,) numpy.ndarray of int64
    """
    a, b = int(loop[0]), int(loop[1])
    f0, f1, f2 = faces[:, 0], faces[:, 1], faces[:, 2]
    forward = ((f0 == a) & (f1 == b)) | ((f1 == a) & (f2 == b)) | ((f2 == a) & (f0 == b))
    return loop if forward.any() else loop[::-1].copy()


def mesh_boundary(faces: np.ndarray, n_points: int) -> tuple[list[np.ndarray] | None, np.ndarray | None]:
    """Boundary loops (longest first, following the faces) and boundary mask of a mesh.

    Parameters
    ----------
    faces : (m, 3) numpy.ndarray of int64
    n_points : int

    Returns
    -------
    loops : list of (L_k,) numpy.ndarray of int64, or None
        Empty for a closed mesh; None when the mesh is not edge-manifold (loops undefined).
    mask : (n_points,) numpy.ndarray of bool, or None
    """
    if not igl.is_edge_manifold(faces)[0]:
        return None, None
    loops = [np.asarray(lp, dtype=np.int64) for lp in igl.boundary_loop_all(faces) if len(lp) > 1]
    loops = sorted((orient_loop_with_faces(lp, faces) for lp in loops), key=len, reverse=True)
    mask = np.zeros(n_points, dtype=bool)
    if loops:
        mask[np.concatenate(loops)] = True
    return loops, mask
