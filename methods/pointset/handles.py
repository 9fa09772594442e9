"""Handles of the surface a point set samples, counted on the triangles its neighbourhoods agree on.

A surface with a handle (a mug, a torus cut open, a cortex with a topological defect) has
no one-to-one map to the plane, whatever the method or its parameters; a point-set map of
it folds, and the self-check's parameter hints ("try k_nn=16") send the user in a circle.
The points say so themselves: the Delaunay one-ring of each point among its ``HANDLE_K``
nearest neighbours on its tangent plane
(:func:`~parambench.methods.pointset.local_delaunay.local_delaunay_rings`) proposes
triangles, and a triangle all three of whose corners' rings hold it is kept. Those form a
surface mesh of the points with small holes where the rings disagree (every edge in at most
two triangles: a triangle held by all its corners' rings is the Delaunay triangle of each);
its vertices joined only at a corner are split, so that its Euler characteristic chi and
its boundary loops b count as on a manifold, and ``genus = (2 - b - chi) / 2`` on its
largest connected piece. Spurious holes add to b and take from chi alike, so they leave
the genus alone.

Measured (16 neighbours; ``/tmp/s50/g/evalall.py`` in the fiftieth session's notes): genus 0
on all 85 inputs of the real-data benchmark (real meshes as bare points, random and graded
samplings at 2k and 20k, normal noise of 0.5 spacings, scattered real meshes, bunny and
pymeshlab cuts, terrains, LiDAR ground), the piece holding 75-100 % of the points on every
clean one (``real/cortex-lh`` 3 %: its rings disagree almost everywhere) and 1-25 % under
noise of 0.5 spacings; genus 1 on a torus with one or two disks cut out, random points,
2k, 5k and 20k, clean and at normal noise of 0.25 spacings (12 of 12, the piece holding
all the points). Only a piece holding at least ``MIN_SHARE`` of the points is judged.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from parambench.datasets_gen.errors import InvalidInputError

from .local_delaunay import local_delaunay_rings
from .neighbourhoods import knn_graph

__all__ = ["HANDLE_K", "MIN_SHARE", "MAX_POINTS", "agreed_triangles", "handle_count", "handle_cause", "handle_note"]

#: Candidates per point for its tangent-plane Delaunay one-ring: with 8, random samplings'
#: rings miss Delaunay neighbours and agree on triangles covering 1-14 % of the points; with
#: 16, 75-100 %.
HANDLE_K = 16

#: Share of the points the largest piece of agreed triangles must hold to be judged.
MIN_SHARE = 0.5

#: Most points the count is made for (it runs only where a map failed, or no loop closed;
#: random bump points, 2 cores: 1.2 s at 100k, 3.7 s at 300k).
MAX_POINTS = 300_000


def agreed_triangles(points: np.ndarray, normals: np.ndarray, k: int = HANDLE_K) -> np.ndarray:
    """The triangles that all three corners' tangent-plane Delaunay one-rings hold.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
        Distinct points.
    normals : (N, 3) numpy.ndarray of float64
        Unit normals (their signs do not matter).
    k : int
        Nearest neighbours each one-ring is built from.

    Returns
    -------
    (F, 3) numpy.ndarray of int64
        Point indices, each row sorted ascending.

    Raises
    ------
    InvalidInputError
        More than ``2_000_000`` points (a triangle's int64 key would overflow).
    """
    if points.shape[0] > 2_000_000:
        raise InvalidInputError(f"agreed_triangles takes at most 2,000,000 points, got {points.shape[0]}.")
    rings = local_delaunay_rings(points, normals, knn_graph(points, k).indices)
    centre = np.repeat(np.arange(points.shape[0], dtype=np.int64), rings.shape[1])
    pairs = rings.reshape(-1, 2)
    real = pairs[:, 0] >= 0
    proposed = np.sort(np.column_stack([centre[real], pairs[real]]), axis=1)
    n = np.int64(points.shape[0])  # one int64 key per triangle (n**3 fits below 2M points): 1-D unique is fast
    keys, held_by = np.unique((proposed[:, 0] * n + proposed[:, 1]) * n + proposed[:, 2], return_counts=True)
    keys = keys[held_by == 3]
    return np.column_stack([keys // (n * n), (keys // n) % n, keys % n])


def handle_count(faces: np.ndarray, n_points: int) -> dict:
    """Genus, boundary loops and size of the largest connected piece of a triangle mesh.

    Parameters
    ----------
    faces : (F, 3) numpy.ndarray of int64
        Triangles whose edges lie in at most two of them (orientation not needed).
    n_points : int
        Number of points the indices refer to.

    Returns
    -------
    dict
        ``genus`` (int), ``boundary_loops`` (int) and ``share`` (float: the piece's
        points over ``n_points``), of the piece with the most triangles; genus 0 and share
        0 without triangles.
    """
    n_faces = len(faces)
    if n_faces == 0:
        return {"genus": 0, "boundary_loops": 0, "share": 0.0}
    edges = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)  # row 3f + j: edge j of face f
    size = np.int64(n_points)
    keys, edge_of, uses = np.unique(edges[:, 0] * size + edges[:, 1], return_inverse=True, return_counts=True)
    unique_edges = np.column_stack([keys // size, keys % size])
    edge_of = edge_of.ravel()
    by_edge = np.argsort(edge_of, kind="stable")
    first = np.searchsorted(edge_of[by_edge], np.arange(len(unique_edges)))
    face_of = np.repeat(np.arange(n_faces), 3)
    inner = np.flatnonzero(uses == 2)
    f1, f2 = face_of[by_edge[first[inner]]], face_of[by_edge[first[inner] + 1]]
    # Corners (face, vertex) joined across shared edges: one vertex per fan, so pinches split.
    a, b = unique_edges[inner, 0], unique_edges[inner, 1]
    links = sp.coo_matrix((np.ones(2 * len(inner)), (np.r_[_corner(faces, f1, a), _corner(faces, f1, b)],
                                                      np.r_[_corner(faces, f2, a), _corner(faces, f2, b)])),
                          shape=(3 * n_faces, 3 * n_faces))
    n_split, vertex_of_corner = connected_components(links, directed=False)
    _, piece = connected_components(sp.coo_matrix((np.ones(len(inner)), (f1, f2)), shape=(n_faces, n_faces)),
                                    directed=False)
    largest = int(np.argmax(np.bincount(piece)))
    in_piece = piece == largest
    corners = vertex_of_corner.reshape(n_faces, 3)[in_piece]
    # Boundary edges on the split vertices; each loop is one connected chain of them.
    rim = np.flatnonzero(uses == 1)
    rim_face = face_of[by_edge[first[rim]]]
    rim = rim[in_piece[rim_face]]
    rim_face = face_of[by_edge[first[rim]]]
    ends = np.column_stack([vertex_of_corner[_corner(faces, rim_face, unique_edges[rim, k])] for k in (0, 1)])
    n_loops = 0
    if len(rim):
        _, chain = connected_components(sp.coo_matrix((np.ones(len(rim)), (ends[:, 0], ends[:, 1])),
                                                      shape=(n_split, n_split)), directed=False)
        n_loops = len(np.unique(chain[ends[:, 0]]))
    n_v = len(np.unique(corners))
    n_e = len(np.unique(edge_of.reshape(n_faces, 3)[in_piece]))
    chi = n_v - n_e + int(in_piece.sum())
    return {"genus": int(round((2 - n_loops - chi) / 2)), "boundary_loops": n_loops,
            "share": float(len(np.unique(faces[in_piece]))) / n_points}


def handle_cause(points: np.ndarray, normals: np.ndarray) -> dict | None:
    """The self-check's "handle" cause: ``{"genus", "share"}`` where the points sample a surface with handles.

    None where the agreed triangles' largest piece shows none, holds under ``MIN_SHARE``
    of the points (noise or an irregular sampling: no verdict), or there are more than
    ``MAX_POINTS`` points or fewer than ``HANDLE_K + 1``.

    Counted once per checked run (:func:`~parambench.methods.base.retry_memo`): the
    retries' checks judge the same points, and the count is a fact of the points (up to
    3.7 s at 300k), not of a run's parameters.
    """
    n = points.shape[0]
    if n > MAX_POINTS or n <= HANDLE_K:
        return None
    from ..base import retry_memo  # the run's memo; imported here, as the base imports this package

    memo = retry_memo()
    key = ("handle-count", id(points), points.shape)
    count = memo.get(key) if memo is not None else None
    if count is None:
        count = handle_count(agreed_triangles(points, normals), n)
        if memo is not None:
            memo[key] = count
    if count["genus"] < 1 or count["share"] < MIN_SHARE:
        return None
    return {"genus": count["genus"], "share": round(count["share"], 3)}


def handle_note(points: np.ndarray, normals: np.ndarray) -> str:
    """A sentence for a NoBoundaryError where the points sample a surface with handles ("" otherwise).

    A closed torus, or one whose opening no loop closed round, read as "a closed surface:
    cut it open"; one cut does not make a surface with handles a disk.
    """
    cause = handle_cause(points, normals)
    if cause is None:
        return ""
    return (f"The points sample a surface with {cause['genus']} handle(s) (the triangles their neighbourhoods agree "
            f"on, over {100 * cause['share']:.0f} % of the points, have genus {cause['genus']}): besides an opening, "
            "it needs a cut across each handle before any map lays it flat.")


def _corner(faces: np.ndarray, face: np.ndarray, vertex: np.ndarray) -> np.ndarray:
    """Corner ids ``3 * face + j`` of ``vertex`` in each ``face`` (it must be one of its corners)."""
    return 3 * face + np.argmax(faces[face] == vertex[:, None], axis=1)
