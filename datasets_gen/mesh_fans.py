"""Half-edges and the fans of faces around each vertex: the one definition.

The mesh methods' manifold checks (:mod:`parambench.methods.mesh.topology`) and the
repair of files from other tools (:mod:`parambench.datasets_gen.repair`) both need to
know which faces around a vertex form one fan; they take it from here, so a repaired
mesh passes the check that refused it.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import breadth_first_order, connected_components

__all__ = ["HalfEdges", "half_edges", "corner_fans", "split_fans", "orientation_signs"]


class HalfEdges(NamedTuple):
    """Per half-edge ``3 f + k`` (corner ``3 f + k`` is vertex ``faces[f, k]`` in face f): its
    start corner (= its index), end corner and undirected-edge id; the half-edges ordered by
    edge id (stable), and each edge's number of half-edges."""

    start: np.ndarray
    end: np.ndarray
    edge_id: np.ndarray
    order: np.ndarray
    counts: np.ndarray

    def pairs(self) -> tuple[np.ndarray, np.ndarray]:
        """The two half-edges (h1, h2) of each edge on exactly two faces, h1 the earlier."""
        ptr = np.concatenate([[0], np.cumsum(self.counts)])
        two = np.flatnonzero(self.counts == 2)
        return self.order[ptr[two]], self.order[ptr[two] + 1]


def half_edges(faces: np.ndarray) -> HalfEdges:
    """The half-edges of ``faces`` (one sort of their undirected keys serves every check).

    Parameters
    ----------
    faces : (M, 3) numpy.ndarray of int64

    Returns
    -------
    HalfEdges
    """
    m = faces.shape[0]
    start = np.arange(3 * m)
    end = (3 * np.arange(m)[:, None] + (np.arange(3) + 1) % 3).ravel()
    flat = faces.ravel()
    lo, hi = np.minimum(flat[start], flat[end]), np.maximum(flat[start], flat[end])
    # one int64 per undirected edge: a 1-D sort is several times faster than unique(axis=0)
    key = lo * (int(flat.max()) + 1) + hi if m else lo
    order = np.argsort(key, kind="stable")
    ordered = key[order]
    new_edge = np.concatenate([[True], ordered[1:] != ordered[:-1]]) if m else np.zeros(0, dtype=bool)
    edge_id = np.empty(3 * m, dtype=np.int64)
    edge_id[order] = np.cumsum(new_edge) - 1
    return HalfEdges(start, end, edge_id, order, np.bincount(edge_id))


def corner_fans(faces: np.ndarray, he: HalfEdges | None = None, unlinked: np.ndarray | None = None) -> np.ndarray:
    """The fan each corner belongs to: faces at a vertex linked through its edges on two faces.

    Two faces sharing an edge at a vertex are in one fan there, whichever way each is
    wound (a file's mis-wound face still continues its neighbours). Edges on three or more
    faces link nothing.

    Parameters
    ----------
    faces : (M, 3) numpy.ndarray of int64
    he : HalfEdges, optional
        ``half_edges(faces)``, when already computed.
    unlinked : (E2,) numpy.ndarray of bool, optional
        Per edge on two faces (in ``he.pairs()`` order): True where the edge links
        nothing, as if cut.

    Returns
    -------
    (3 M,) numpy.ndarray of int64
        A label per corner (``3 f + k``); corners of one vertex with the same label are
        one fan. Labels are not numbered per vertex.
    """
    flat = faces.ravel()
    he = half_edges(faces) if he is None else he
    start, end = he.start, he.end
    h1, h2 = he.pairs()
    if unlinked is not None:
        h1, h2 = h1[~unlinked], h2[~unlinked]
    # link the corners of the two faces that sit at the same vertex, at both ends of the edge
    same_way = flat[start[h2]] == flat[start[h1]]
    i = np.concatenate([start[h1], end[h1]])
    j = np.concatenate([np.where(same_way, start[h2], end[h2]), np.where(same_way, end[h2], start[h2])])
    graph = sp.coo_matrix((np.ones(i.size), (i, j)), shape=(flat.size, flat.size))
    return connected_components(graph, directed=False)[1].astype(np.int64)


def split_fans(faces: np.ndarray, n_vertices: int, unlinked: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Give every fan after the first at a vertex a copy of that vertex of its own.

    Where separate fans of faces meet at one vertex (two cones touching at their tips, a
    scan's sheets pinched together), no disk map exists; split there, each fan is a
    surface of its own at that point, as the cut a user would make.

    Parameters
    ----------
    faces : (M, 3) numpy.ndarray of int64
        Edge-manifold faces (edges on three or more faces are left joined).
    n_vertices : int
    unlinked : (E2,) numpy.ndarray of bool, optional
        Edges to cut (see :func:`corner_fans`): a vertex where they break its fan is split
        too, so that a path of such edges becomes a slit.

    Returns
    -------
    faces : (M, 3) numpy.ndarray of int64
        The faces, the corners of each extra fan renumbered to a new vertex
        ``n_vertices, n_vertices + 1, ...``.
    source : (V',) numpy.ndarray of int64
        The input vertex of each output vertex (``arange(n_vertices)`` followed by the
        copies' originals): ``points[source]`` are the output points.
    """
    faces = np.asarray(faces, dtype=np.int64)
    flat = faces.ravel()
    fan = corner_fans(faces, unlinked=unlinked)
    # (vertex, fan) pairs in vertex order; a vertex's first pair keeps its index
    base = np.int64(fan.max() + 1 if fan.size else 1)
    pair, corner_pair = np.unique(flat * base + fan, return_inverse=True)
    pair_vertex = pair // base
    extra = np.concatenate([[False], pair_vertex[1:] == pair_vertex[:-1]]) if pair.size else np.zeros(0, bool)
    new_index = pair_vertex.copy()
    new_index[extra] = n_vertices + np.arange(int(extra.sum()))
    source = np.concatenate([np.arange(n_vertices, dtype=np.int64), pair_vertex[extra]])
    return new_index[corner_pair.ravel()].reshape(faces.shape), source


def orientation_signs(faces: np.ndarray, he: HalfEdges | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Wind the faces alike along a spanning forest of the face graph; the edges that disagree.

    Faces are linked through edges on exactly two faces. Along a breadth-first spanning
    tree of each piece, a face keeps its parent's winding (reversed where the two run
    their edge the same way). On an orientable piece every edge then agrees; on a
    non-orientable one (a Moebius band, a scan's twisted flap) the edges that still
    disagree cross the twist: cut there, the piece is orientable.

    Parameters
    ----------
    faces : (M, 3) numpy.ndarray of int64
    he : HalfEdges, optional
        ``half_edges(faces)``, when already computed.

    Returns
    -------
    sign : (M,) numpy.ndarray of int64
        +1 to keep a face as given, -1 to reverse it; in each piece the winding of more
        faces is kept.
    conflict : (E2,) numpy.ndarray of bool
        Per edge on two faces (``he.pairs()`` order): still run the same way by both
        faces after the reversals.
    """
    m = faces.shape[0]
    flat = faces.ravel()
    he = half_edges(faces) if he is None else he
    h1, h2 = he.pairs()
    f1, f2 = h1 // 3, h2 // 3
    alike = flat[he.start[h1]] == flat[he.start[h2]]  # both run the edge the same way
    # a virtual root m joined to one face of each piece: one search covers the forest
    n_pieces, piece = connected_components(
        sp.coo_matrix((np.ones(f1.size), (f1, f2)), shape=(m, m)), directed=False)
    seeds = np.unique(piece, return_index=True)[1]
    # one edge per pair of faces (two faces sharing two edges would sum their steps)
    once = np.unique(np.minimum(f1, f2) * np.int64(m) + np.maximum(f1, f2), return_index=True)[1]
    step = np.where(alike[once], 2.0, 1.0)  # 2: the child reverses its parent's winding
    graph = sp.coo_matrix((np.r_[step, np.ones(n_pieces)],
                           (np.r_[f1[once], np.full(n_pieces, m)], np.r_[f2[once], seeds])),
                          shape=(m + 1, m + 1)).tocsr()
    graph = graph.maximum(graph.T)
    _, parent = breadth_first_order(graph, m, directed=False, return_predecessors=True)
    parent = parent[:m]
    # winding relative to the root by pointer jumping: log(depth) vectorised passes
    flip = np.where(parent == m, 1, np.asarray(graph[np.arange(m), np.maximum(parent, 0)]).ravel().astype(np.int64))
    sign = np.where(flip == 2, -1, 1)
    up = np.where(parent == m, -1, parent)
    while (up >= 0).any():
        has = up >= 0
        sign[has] *= sign[up[has]]
        up = np.where(has, up[np.maximum(up, 0)], -1)
    # keep the winding of more faces in each piece
    reversed_share = np.bincount(piece, weights=(sign < 0).astype(float), minlength=n_pieces)
    sign *= np.where(reversed_share > 0.5 * np.bincount(piece, minlength=n_pieces), -1, 1)[piece]
    conflict = alike == (sign[f1] == sign[f2])
    return sign, conflict
