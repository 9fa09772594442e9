"""Pieces of a triangle mesh (faces joined through shared vertices), and the error for several.

Shared by the mesh methods' checks (:mod:`parambench.methods.mesh.topology`), which refuse a
mesh in pieces, and by ``flatten --repair`` (:mod:`parambench.datasets_gen.repair`), which
keeps the largest: both judge whether "the largest" is a repair at all
(:func:`~parambench.datasets_gen.knn_pieces.comparable_pieces`, as for point sets) and
whether the pieces are patches of one surface stored unwelded. The Utah teapot of the npm
package ``teapot`` is 32 Bezier patches of 32 faces each, their shared rims stored as 263
coincident vertices: keeping "the largest piece" kept 32 of its 992 faces and flattened
them, exit 0.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from .errors import DisconnectedError, repairable
from .knn_pieces import comparable_pieces
from .mesh_fans import half_edges, split_fans
from .surface import duplicate_tolerance

__all__ = ["face_pieces", "coincident_across_pieces", "disconnected_mesh_error", "largest_piece_topology"]


def face_pieces(faces: np.ndarray, n_vertices: int) -> tuple[np.ndarray, np.ndarray]:
    """Piece of each face (faces sharing a vertex are one piece) and each piece's face count.

    Parameters
    ----------
    faces : (M, 3) numpy.ndarray of int64
    n_vertices : int

    Returns
    -------
    label : (M,) numpy.ndarray of int64
        Pieces numbered by decreasing face count (0: the largest).
    sizes : (P,) numpy.ndarray of int64
        Faces per piece, largest first.
    """
    # through the vertices' graph (3 M edges), not the faces' (about 12 M neighbours)
    graph = sp.coo_matrix((np.ones(faces.size), (faces.ravel(), np.roll(faces, 1, axis=1).ravel())),
                          shape=(n_vertices, n_vertices))
    label = connected_components(graph, directed=False)[1][faces[:, 0]] if len(faces) else np.zeros(0, np.int64)
    _, label = np.unique(label, return_inverse=True)
    counts = np.bincount(label)
    rank = np.empty(counts.size, dtype=np.int64)
    rank[np.argsort(-counts, kind="stable")] = np.arange(counts.size)
    return rank[label], np.sort(counts)[::-1].astype(np.int64)


def coincident_across_pieces(points: np.ndarray, faces: np.ndarray, label: np.ndarray) -> int:
    """Vertices at the position of a vertex of another piece (patches stored unwelded).

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    faces : (M, 3) numpy.ndarray of int64
    label : (M,) numpy.ndarray of int64
        :func:`face_pieces`'s labels.

    Returns
    -------
    int
        Within :func:`~parambench.datasets_gen.surface.duplicate_tolerance`.
    """
    vertex_piece = np.full(len(points), -1, dtype=np.int64)
    vertex_piece[faces.ravel()] = np.repeat(label, 3)
    used = np.flatnonzero(vertex_piece >= 0)
    pairs = cKDTree(points[used]).query_pairs(duplicate_tolerance(points[used]), output_type="ndarray")
    across = pairs[vertex_piece[used[pairs[:, 0]]] != vertex_piece[used[pairs[:, 1]]]]
    return int(np.unique(across).size)


def disconnected_mesh_error(points: np.ndarray, faces: np.ndarray, label: np.ndarray,
                            sizes: np.ndarray) -> DisconnectedError:
    """The error for a mesh in several pieces.

    It names the pieces' face counts, says when they meet at coincident vertices (weld
    them if they are one surface) and, unless the pieces are comparable (keeping the
    largest would drop about as much as it keeps), offers ``--repair``.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    faces : (M, 3) numpy.ndarray of int64
    label, sizes : numpy.ndarray of int64
        :func:`face_pieces` of ``faces`` (at least two pieces).

    Returns
    -------
    DisconnectedError
        Marked repairable (:func:`~parambench.datasets_gen.errors.repairable`) unless the
        pieces are comparable.
    """
    shown = ", ".join(str(int(s)) for s in sizes[:8]) + (", ..." if sizes.size > 8 else "")
    touching = coincident_across_pieces(points, faces, label)
    each = "flatten each component separately (pymeshlab generate_splitting_by_connected_components)"
    if touching:
        each = (f"they meet at {touching} coincident vertices (patches stored unwelded): if they are one surface, "
                f"weld them (pass --weld, or pymeshlab meshing_merge_close_vertices) and flatten that; else {each}")
    comparable = comparable_pieces(sizes)
    keep = (f"; keeping the largest would drop {int(sizes.sum() - sizes[0])} of {int(sizes.sum())} faces"
            if comparable else "")
    exc = DisconnectedError(f"the mesh has {sizes.size} connected components ({shown} faces); {each}{keep}.")
    return exc if comparable else repairable(exc)


def largest_piece_topology(faces: np.ndarray, n_vertices: int) -> dict:
    """Boundary loops and genus of the largest piece: whether its faces mesh an open surface.

    For pointing a user from a failed point-set map back to a file's faces only where a
    mesh method could map them (a closed bust with handles would fail there too).

    Parameters
    ----------
    faces : (M, 3) numpy.ndarray of int64
    n_vertices : int

    Returns
    -------
    dict
        ``boundary_loops`` (int: components of the edges on one face, once every fan at a
        pinched vertex has its own copy) and ``genus`` (int, from the Euler characteristic
        of that split piece; None unless it is edge-manifold and wound alike, where the count would mislead: pymeshfix's planar_mesh.ply, an open sheet
        with a twisted flap, came out as genus 1).
    """
    label, _ = face_pieces(faces, n_vertices)
    # pinched vertices split first: each would lower the Euler characteristic by one
    # (a decimated scan's two pinches read as a handle)
    piece, _ = split_fans(faces[label == 0], n_vertices)
    he = half_edges(piece)
    flat = piece.ravel()
    first = np.full(he.counts.size, -1, dtype=np.int64)
    first[he.edge_id[::-1]] = he.start[::-1]  # one half-edge per edge
    rim = first[he.counts == 1]
    a, b = flat[rim], flat[he.end[rim]]
    if rim.size:
        used, inverse = np.unique(np.r_[a, b], return_inverse=True)
        graph = sp.coo_matrix((np.ones(rim.size), (inverse[:rim.size], inverse[rim.size:])), shape=(used.size,) * 2)
        n_loops = int(connected_components(graph, directed=False)[0])
    else:
        n_loops = 0
    euler = np.unique(flat).size - he.counts.size + len(piece)
    h1, h2 = he.pairs()
    oriented_manifold = bool((he.counts <= 2).all() and not (flat[he.start[h1]] == flat[he.start[h2]]).any())
    genus = max(0, (2 - n_loops - int(euler)) // 2) if oriented_manifold else None
    return {"boundary_loops": n_loops, "genus": genus}
