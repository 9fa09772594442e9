"""Topology of triangle meshes: disk checks and ordered boundary loops."""

from __future__ import annotations

import igl
import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from datasets_gen.errors import DisconnectedError, NotADiskError

__all__ = ["boundary_loops", "require_disk", "require_connected_disk_like"]


def boundary_loops(faces: np.ndarray) -> list[np.ndarray]:
    """All boundary loops of a manifold mesh, longest first.

    Loops follow the faces' orientation (a counter-clockwise face order gives a
    counter-clockwise outer loop and clockwise holes in a faithful flattening).

    Parameters
    ----------
    faces : (M, 3) numpy.ndarray of int64

    Returns
    -------
    list of (L_i,) numpy.ndarray of int64
    """
    loops = igl.boundary_loop_all(np.ascontiguousarray(faces, dtype=np.int64))
    loops = [np.asarray(loop, dtype=np.int64) for loop in loops if len(loop) > 0]
    return sorted(loops, key=len, reverse=True)


def _component_count(faces: np.ndarray, n_vertices: int) -> tuple[int, np.ndarray]:
    i = np.repeat(faces, 2, axis=1).ravel()
    j = np.roll(faces, -1, axis=1).repeat(2, axis=1).ravel()
    adj = sp.coo_matrix((np.ones(i.size), (i, j)), shape=(n_vertices, n_vertices))
    return connected_components(adj, directed=False)


def require_connected_disk_like(points: np.ndarray, faces: np.ndarray, *, allow_holes: bool = True) -> list[np.ndarray]:
    """Check a mesh is one manifold component with boundary; return its boundary loops.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    faces : (M, 3) numpy.ndarray of int64
    allow_holes : bool
        When False, exactly one boundary loop is required (a topological disk).

    Returns
    -------
    list of (L_i,) numpy.ndarray of int64
        Boundary loops, the longest (outer) first.

    Raises
    ------
    DisconnectedError
        Unreferenced vertices or several components.
    NotADiskError
        Non-manifold edges or vertices, a closed surface, or (``allow_holes=False``)
        more than one boundary loop or Euler characteristic != 1.
    """
    n = points.shape[0]
    used = np.zeros(n, dtype=bool)
    used[faces.ravel()] = True
    if not used.all():
        raise DisconnectedError(
            f"{int((~used).sum())} vertex/vertices belong to no face; remove unreferenced vertices "
            "(pymeshlab meshing_remove_unreferenced_vertices) or use --points-only."
        )
    n_comp, _ = _component_count(faces, n)
    if n_comp > 1:
        raise DisconnectedError(
            f"the mesh has {n_comp} connected components; flatten each component separately "
            "(pymeshlab generate_splitting_by_connected_components)."
        )
    if not igl.is_edge_manifold(faces):
        raise NotADiskError("the mesh has non-manifold edges (more than two faces on an edge); repair it first "
                            "(pymeshlab meshing_repair_non_manifold_edges).")
    vm = np.asarray(igl.is_vertex_manifold(faces)).ravel()
    if not np.all(vm):
        raise NotADiskError(f"the mesh has {int((~vm.astype(bool)).sum())} non-manifold vertices; repair them first "
                            "(pymeshlab meshing_repair_non_manifold_vertices).")
    loops = boundary_loops(faces)
    if not loops:
        raise NotADiskError("the mesh is closed (no boundary loop); cut it open along a seam before flattening.")
    if not allow_holes:
        chi = int(igl.euler_characteristic(faces))
        if len(loops) != 1 or chi != 1:
            raise NotADiskError(
                f"the mesh is not a topological disk (boundary loops: {len(loops)}, Euler characteristic: {chi}); "
                "this method needs exactly one boundary loop."
            )
    return loops


def require_disk(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Check a mesh is a topological disk and return its single boundary loop.

    Raises
    ------
    DisconnectedError, NotADiskError
        See :func:`require_connected_disk_like`.
    """
    return require_connected_disk_like(points, faces, allow_holes=False)[0]
