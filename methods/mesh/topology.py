"""Topology of triangle meshes: manifold and disk checks (boundary loops: :mod:`parambench.datasets_gen.mesh_loops`)."""

from __future__ import annotations

import igl
import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from parambench.datasets_gen.errors import DisconnectedError, NotADiskError, repairable
# Half-edges and fans live below the methods, where the repair of input files uses them too.
from parambench.datasets_gen.mesh_fans import HalfEdges as _HalfEdges
from parambench.datasets_gen.mesh_fans import corner_fans
from parambench.datasets_gen.mesh_fans import half_edges as _half_edges
# The one definition of a mesh's loops lives below the methods, where the readers use it too.
from parambench.datasets_gen.mesh_loops import boundary_loops
from parambench.datasets_gen.mesh_pieces import disconnected_mesh_error, face_pieces

__all__ = [
    "boundary_loops",
    "duplicate_faces",
    "interior_edges",
    "non_manifold_edges",
    "non_manifold_vertices",
    "coherent_flips",
    "require_manifold",
    "require_oriented",
    "require_no_handles",
    "require_disk",
    "require_connected_disk_like",
]

#: How many offending indices an error message lists.
_EXAMPLES = 3


def duplicate_faces(faces: np.ndarray) -> np.ndarray:
    """Faces over the same three vertices as an earlier face (either orientation).

    Parameters
    ----------
    faces : (M, 3) numpy.ndarray of int64

    Returns
    -------
    (D, 2) numpy.ndarray of int64
        Rows ``(repeat, first)``: a face index and the index of the earlier face it
        repeats, in increasing ``repeat`` order.
    """
    key = np.sort(faces, axis=1)
    # lexsort is stable: within a run of equal keys the earliest face comes first
    order = np.lexsort((key[:, 2], key[:, 1], key[:, 0]))
    ordered = key[order]
    same = np.all(ordered[1:] == ordered[:-1], axis=1)
    run_start = np.maximum.accumulate(np.where(np.concatenate([[True], ~same]), np.arange(order.size), 0))
    repeat, first = order[1:][same], order[run_start[1:][same]]
    by_repeat = np.argsort(repeat)
    return np.column_stack([repeat[by_repeat], first[by_repeat]]).astype(np.int64)


def interior_edges(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Edges shared by exactly two faces, with the corners opposite them.

    Parameters
    ----------
    faces : (M, 3) numpy.ndarray of int64
        Consistently oriented triangles.

    Returns
    -------
    half_edges : (E, 2) numpy.ndarray of int64
        ``(a, b)``: the edge as it runs in its first face (``b -> a`` in the second).
    faces : (E, 2) numpy.ndarray of int64
        The two faces, the one holding ``a -> b`` first.
    opposite : (E, 2) numpy.ndarray of int64
        The vertex of each face that is not on the edge.
    """
    m = faces.shape[0]
    if m == 0:
        empty = np.empty((0, 2), dtype=np.int64)
        return empty, empty, empty
    flat = faces.ravel()
    he = _half_edges(faces)
    end = he.end
    first, second = he.pairs()
    third = (3 * (first // 3) + (first % 3 + 2) % 3, 3 * (second // 3) + (second % 3 + 2) % 3)
    return (np.column_stack([flat[first], flat[end[first]]]).astype(np.int64),
            np.column_stack([first // 3, second // 3]).astype(np.int64),
            np.column_stack([flat[third[0]], flat[third[1]]]).astype(np.int64))


def non_manifold_edges(faces: np.ndarray, half_edges: _HalfEdges | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Edges shared by more than two faces.

    Parameters
    ----------
    faces : (M, 3) numpy.ndarray of int64
    half_edges : optional
        ``_half_edges(faces)``, when already computed.

    Returns
    -------
    edges : (E, 2) numpy.ndarray of int64
        Vertex pairs ``i < j``, sorted.
    counts : (E,) numpy.ndarray of int64
        Number of faces on each.
    """
    flat = faces.ravel()
    start, end, edge_id, _, counts = _half_edges(faces) if half_edges is None else half_edges
    bad = np.flatnonzero(counts > 2)
    # one half-edge per bad edge gives its vertices
    first = np.full(counts.size, -1, dtype=np.int64)
    first[edge_id[::-1]] = start[::-1]
    h = first[bad]
    edges = np.sort(np.column_stack([flat[h], flat[end[h]]]), axis=1)
    return edges.astype(np.int64), counts[bad].astype(np.int64)


def non_manifold_vertices(faces: np.ndarray, n_vertices: int, half_edges: _HalfEdges | None = None) -> np.ndarray:
    """Vertices whose faces form more than one fan (e.g. two cones touching at a tip: a bowtie).

    Faces around a vertex belong to one fan when they are linked through edges at that
    vertex shared by exactly two faces. Call on an edge-manifold mesh (see
    :func:`non_manifold_edges`); edges on three or more faces link nothing here.

    Parameters
    ----------
    faces : (M, 3) numpy.ndarray of int64
    n_vertices : int
    half_edges : optional
        ``_half_edges(faces)``, when already computed.

    Returns
    -------
    (K,) numpy.ndarray of int64
        Sorted vertex indices.
    """
    flat = faces.ravel()
    fan = corner_fans(faces, half_edges)
    vertex_fan = np.unique(flat * np.int64(fan.max() + 1) + fan)
    fans_per_vertex = np.bincount(vertex_fan // (fan.max() + 1), minlength=n_vertices)
    return np.flatnonzero(fans_per_vertex > 1).astype(np.int64)


def coherent_flips(faces: np.ndarray, half_edges: _HalfEdges | None = None) -> tuple[np.ndarray | None, int]:
    """Faces to reverse so that every interior edge runs opposite ways in its two faces.

    Two faces on an edge are wound alike when they run it in opposite directions. Faces
    are linked through edges shared by exactly two faces; in each face-connected piece the
    orientation held by more faces is kept. A piece where no choice works (a Moebius band:
    going round it brings a face back reversed) is not orientable.

    Parameters
    ----------
    faces : (M, 3) numpy.ndarray of int64
        Call on an edge-manifold mesh (:func:`non_manifold_edges`).
    half_edges : optional
        ``_half_edges(faces)``, when already computed.

    Returns
    -------
    flips : (M,) numpy.ndarray of bool, or None
        True at the faces wound against the orientation kept; None when the mesh is not
        orientable.
    n_conflicts : int
        Interior edges that both of their faces run the same way.
    """
    m = faces.shape[0]
    if m == 0:
        return np.zeros(0, dtype=bool), 0
    flat = faces.ravel()
    he = _half_edges(faces) if half_edges is None else half_edges
    h1, h2 = he.pairs()
    alike = flat[he.start[h1]] == flat[he.start[h2]]  # both faces run the edge the same way
    if not alike.any():  # coherent as given: no graph to build
        return np.zeros(m, dtype=bool), 0
    f1, f2 = h1 // 3, h2 // 3
    # The orientation double cover: node f is face f as given, node f + m face f reversed.
    # A conflicting edge joins each face to the other's reversal.
    g2 = np.where(alike, f2 + m, f2)
    i = np.concatenate([f1, f1 + m])
    j = np.concatenate([g2, np.where(alike, f2, f2 + m)])
    graph = sp.coo_matrix((np.ones(i.size), (i, j)), shape=(2 * m, 2 * m))
    _, label = connected_components(graph, directed=False)
    as_given, reversed_ = label[:m], label[m:]
    n_conflicts = int(alike.sum())
    if np.any(as_given == reversed_):
        return None, n_conflicts
    size = np.bincount(as_given, minlength=label.max() + 1)
    flips = (size[as_given] < size[reversed_]) | ((size[as_given] == size[reversed_]) & (as_given > reversed_))
    return flips, n_conflicts


def _examples(items) -> str:
    shown = ", ".join(str(x) for x in items[:_EXAMPLES])
    return shown + (", ..." if len(items) > _EXAMPLES else "")


def require_manifold(faces: np.ndarray, n_vertices: int) -> None:
    """Raise unless the mesh has no duplicate faces, non-manifold edges or non-manifold vertices.

    Parameters
    ----------
    faces : (M, 3) numpy.ndarray of int64
    n_vertices : int

    Raises
    ------
    NotADiskError
        With how many offenders there are, the first few indices and a repair to apply.
    """
    dup = duplicate_faces(faces)
    if dup.size:
        pairs = [f"face {int(r)} = face {int(f)}" for r, f in dup]
        raise repairable(NotADiskError(
            f"the mesh has {len(dup)} duplicate face(s) over the same three vertices ({_examples(pairs)}); "
            "remove them (pymeshlab meshing_remove_duplicate_faces) or use --points-only."
        ))
    half_edges = _half_edges(faces)
    edges, counts = non_manifold_edges(faces, half_edges)
    if edges.size:
        shown = [f"{int(a)}-{int(b)} on {int(c)} faces" for (a, b), c in zip(edges, counts)]
        raise repairable(NotADiskError(
            f"the mesh has {len(edges)} non-manifold edge(s) shared by more than two faces (vertices {_examples(shown)}); "
            "repair them (pymeshlab meshing_repair_non_manifold_edges) or use --points-only."
        ))
    require_oriented(faces, half_edges)
    verts = non_manifold_vertices(faces, n_vertices, half_edges)
    if verts.size:
        raise repairable(NotADiskError(
            f"the mesh has {verts.size} non-manifold vertex/vertices where separate fans of faces meet "
            f"(vertex {_examples(verts.tolist())}); repair them (pymeshlab meshing_repair_non_manifold_vertices) "
            "or use --points-only."
        ))


def require_oriented(faces: np.ndarray, half_edges: _HalfEdges | None = None) -> None:
    """Raise unless the faces are wound coherently (see :func:`coherent_flips`).

    Files merged from tools that wind faces differently, or with faces reversed by hand,
    break every boundary walk and cotangent solve downstream: the maps came out distorted
    or folded with no error (a grid with 40 faces reversed: QC 1.7e12 from ``scp``, 74
    flipped triangles from ``scp-igl``).

    Raises
    ------
    NotADiskError
        The surface is not orientable (no map to the plane keeps its faces' orientation),
        or some faces are wound against their neighbours (repairable: ``--repair``
        reverses them).
    """
    flips, n_conflicts = coherent_flips(faces, half_edges)
    if flips is None:
        raise NotADiskError(
            f"the surface is not orientable ({n_conflicts} edge(s) where going round it brings a face back reversed, "
            "as on a Moebius band); no map to the plane keeps its faces' orientation, and its points alone map no "
            "better: cut it so that it becomes orientable (a Moebius band cut once across is a disk).")
    if n_conflicts:
        shown = [f"face {int(f)} (vertices {', '.join(str(int(v)) for v in faces[f])})"
                 for f in np.flatnonzero(flips)[:_EXAMPLES]]
        raise repairable(NotADiskError(
            f"{int(flips.sum())} face(s) are wound against their neighbours ({n_conflicts} edge(s) run the same way "
            f"in both of their faces; {_examples(shown)}; 0-based, polygons split into triangles); reverse them "
            "(pymeshlab meshing_re_orient_faces_coherently) or use --points-only."), "reverse them")


def require_no_handles(faces: np.ndarray, n_loops: int) -> None:
    """Raise when a connected mesh with ``n_loops`` boundary loops has a handle.

    A connected orientable surface with b boundary loops has Euler characteristic
    2 - 2g - b; a planar domain (a disk with holes) has genus g = 0. A handle cannot be
    laid flat without a cut: the maps of a torus with a hole folded (scp: "N triangles
    flipped", with advice about weights and triangle shapes that could not help).

    Parameters
    ----------
    faces : (M, 3) numpy.ndarray of int64
        Every vertex referenced, one component.
    n_loops : int

    Raises
    ------
    NotADiskError
    """
    chi = int(igl.euler_characteristic(faces))
    genus = (2 - n_loops - chi) // 2
    if genus > 0:
        raise NotADiskError(
            f"the mesh has {genus} handle(s) (Euler characteristic {chi} with {n_loops} boundary loop(s): genus "
            f"{genus}); a handle cannot be laid flat without a cut: cut each handle open along a closed curve "
            "around it (a seam), so that the surface becomes a disk with holes.")


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
        Duplicate faces, non-manifold edges or vertices (:func:`require_manifold`), a closed surface, a
        handle (:func:`require_no_handles`), or (``allow_holes=False``) more than one boundary loop.
    """
    n = points.shape[0]
    require_manifold(faces, n)
    used = np.zeros(n, dtype=bool)
    used[faces.ravel()] = True
    if not used.all():
        raise repairable(DisconnectedError(
            f"{int((~used).sum())} vertex/vertices belong to no face; remove unreferenced vertices "
            "(pymeshlab meshing_remove_unreferenced_vertices) or use --points-only."
        ))
    label, sizes = face_pieces(faces, n)
    if sizes.size > 1:
        raise disconnected_mesh_error(points, faces, label, sizes)
    loops = boundary_loops(faces)
    if not loops:
        raise NotADiskError("the mesh is closed (no boundary loop); cut it open along a seam before flattening.")
    require_no_handles(faces, len(loops))
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
