"""Keep the largest connected piece of a surface and repair its mesh (``parambench flatten --repair``).

Scans and files from other tools rarely hold one clean manifold piece. pymeshlab's
sample range scan of a face (``tests/sample_meshes/rangemaps/face000.ply``, 85,849
vertices, 166,259 faces) has 17 face-connected pieces (the largest 161,609 faces; the
others are specks of 9 to 4,168 faces) and 6 non-manifold vertices; as bare points its
8-nearest-neighbour graph has 7 components. Every method refuses such input, with the
pymeshlab filter that fixes it named in the message. This module applies those fixes
when the user asks for them: it never runs unasked, because dropping pieces is a
decision about the data.

For a mesh: the largest piece by face count (faces joined through shared vertices), then
pymeshlab's duplicate-face removal, on each edge of more than two faces the two faces that
continue each other across it kept (a fin or a folded flap dropped), pymeshlab's
non-manifold edge repair for what is left (faces removed), the fans of faces meeting
at one vertex split into copies of it (:func:`.mesh_fans.split_fans`), unreferenced-vertex removal and
coherent re-orientation of the faces (the minority winding of a piece reversed; where no
winding is coherent, the faces on the edges that cross the twist dropped first), then the
largest piece again (a split vertex can disconnect what it joined). pymeshlab
sees the arrays parambench's own reader validated, never the file. For a point set: the
largest component of the symmetrised k-nearest-neighbour graph, the graph the point-set
front end builds (its ``k_nn``).

The result is a new surface: its rows are the kept (and split) vertices, not the input's.
"""

from __future__ import annotations

import numpy as np

from .knn_pieces import comparable_pieces, disconnected_error, knn_labels
from .mesh_fans import half_edges, orientation_signs, split_fans
from .mesh_pieces import disconnected_mesh_error, face_pieces
from .surface import Surface

__all__ = ["repair_surface", "repair_summary", "largest_piece", "compact"]


def largest_piece(faces: np.ndarray, n_vertices: int) -> tuple[np.ndarray, int]:
    """Faces of the largest vertex-connected piece (by face count) and the number of pieces."""
    label, sizes = face_pieces(faces, n_vertices)
    return (faces, 1) if sizes.size == 1 else (faces[label == 0], int(sizes.size))


def compact(points: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Drop vertices no face uses, renumbering the faces."""
    used = np.unique(faces)
    new = np.full(len(points), -1, dtype=np.int64)
    new[used] = np.arange(used.size)
    return points[used], new[faces]


def _repair_mesh(points: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, dict]:
    import pymeshlab

    label, sizes = face_pieces(faces, len(points))
    if comparable_pieces(sizes):
        raise disconnected_mesh_error(points, faces, label, sizes)
    piece, n_pieces = faces[label == 0], int(sizes.size)
    kept_faces = len(piece)
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=np.asarray(points, dtype=np.float64),
                               face_matrix=np.asarray(piece, dtype=np.int32)))
    ms.meshing_remove_duplicate_faces()
    # Before pymeshlab's own repair, which removes faces on a non-manifold edge in file order
    # (it took a grid's face instead of the fin standing on it): keep on each such edge the
    # two faces that continue each other across it.
    mesh = ms.current_mesh()
    v_now, f_now = np.asarray(mesh.vertex_matrix(), dtype=np.float64), np.asarray(mesh.face_matrix(), dtype=np.int64)
    fins = _fin_faces(v_now, f_now)
    if fins.any():
        ms.clear()
        ms.add_mesh(pymeshlab.Mesh(vertex_matrix=v_now, face_matrix=f_now[~fins].astype(np.int32)))
    ms.meshing_repair_non_manifold_edges()
    # Our own split, not pymeshlab's meshing_repair_non_manifold_vertices: that one left 55
    # of the 81 pinched vertices of the npm package snowden's bust (mis-wound faces beside
    # them), and the methods then refused the "repaired" mesh.
    mesh = ms.current_mesh()
    v_now = np.asarray(mesh.vertex_matrix(), dtype=np.float64)
    f_now, source = split_fans(np.asarray(mesh.face_matrix(), dtype=np.int64), len(v_now))
    n_split = len(source) - len(v_now)
    v_now, f_now = compact(v_now[source], f_now)
    ms.clear()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=v_now, face_matrix=f_now.astype(np.int32)))
    n_faces = len(f_now)
    before = np.asarray(ms.current_mesh().face_matrix(), dtype=np.int64)
    # Faces wound against their neighbours (files merged from tools that wind differently,
    # or a duplicate face kept in its reversed copy); a non-orientable piece stays as it is
    # and the methods refuse it.
    ms.meshing_re_orient_faces_coherently()
    mesh = ms.current_mesh()
    v = np.asarray(mesh.vertex_matrix(), dtype=np.float64)
    f = np.asarray(mesh.face_matrix(), dtype=np.int64)
    # pymeshlab leaves a non-orientable piece (a Moebius band) half re-oriented: not a repair.
    orientable = _runs_each_edge_once(f)
    n_reversed = _reversed_faces(before, f) if len(f) == n_faces and orientable else 0
    n_twist = 0
    if not orientable:
        v, f, n_twist, n_reversed = _drop_twist(v_now, before)
        orientable = _runs_each_edge_once(f)
    f, n_after = largest_piece(f, len(v))
    v, f = compact(v, f)
    facts = {"kind": "mesh", "pieces": n_pieces, "pieces_after_repair": n_after,
             "points_in": int(len(points)), "faces_in": int(len(faces)), "points_out": int(len(v)),
             "faces_out": int(len(f)), "faces_removed_in_repair": int(kept_faces - len(f)),
             "vertices_split": int(n_split), "faces_reversed": int(n_reversed), "orientable": bool(orientable),
             "faces_dropped_to_orient": int(n_twist)}
    return v, f, facts


def _drop_twist(points: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, int, int]:
    """Drop the faces on the edges where a mesh's faces cannot be wound alike, and wind the rest.

    pymeshfix's example ``planar_mesh.ply`` (a sheet with 16 small holes) has a twisted flap: 2
    edges whose faces run them the same way however the rest is wound, and every method
    refused it as a Moebius band. Without the 4 faces on those edges (a hole, as where
    faces on a non-manifold edge are dropped) it is orientable. Cutting the edges open
    instead (a slit) gave a hole of zero area, whose free boundary crossed itself in uv
    and which no patch fills. Vertices where the drop pinches two fans together are
    split (:func:`.mesh_fans.split_fans`); where the rest is still not orientable, nothing
    is dropped.

    Returns
    -------
    points, faces : numpy.ndarray
        The mesh less those faces, wound alike where it became orientable.
    n_dropped : int
        Faces dropped.
    n_reversed : int
        Faces reversed.
    """
    he = half_edges(faces)
    _, conflict = orientation_signs(faces, he)
    h1, h2 = he.pairs()
    drop = np.zeros(len(faces), dtype=bool)
    drop[h1[conflict] // 3] = drop[h2[conflict] // 3] = True
    kept, source = split_fans(faces[~drop], len(points))
    sign, still = orientation_signs(kept)
    if still.any():
        return points, faces, 0, 0
    kept[sign < 0] = kept[sign < 0, ::-1]
    return points[source], kept, int(drop.sum()), int((sign < 0).sum())


def _fin_faces(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(M,) bool: the faces to drop so that each edge on more than two faces keeps two.

    On such an edge, the two faces kept are those whose third corners lie most nearly
    opposite each other seen along the edge (the surface continuing across it); the others
    (a fin standing on the surface, a flap folded back onto it) are dropped.
    """
    drop = np.zeros(len(faces), dtype=bool)
    corners = np.stack([faces, np.roll(faces, -1, axis=1), np.roll(faces, -2, axis=1)], axis=-1).reshape(-1, 3)
    lo, hi = np.minimum(corners[:, 0], corners[:, 1]), np.maximum(corners[:, 0], corners[:, 1])
    _, edge, counts = np.unique(lo * (int(faces.max()) + 1) + hi, return_inverse=True, return_counts=True)
    order = np.argsort(edge.ravel(), kind="stable")  # the corners of each edge next to each other
    start = np.concatenate([[0], np.cumsum(counts)])
    for e in np.flatnonzero(counts > 2):
        rows = order[start[e]:start[e + 1]]
        a, b, c = (points[corners[rows, k]] for k in range(3))
        axis = (b - a)[0] / np.linalg.norm((b - a)[0])
        wing = (c - a) - np.outer((c - a) @ axis, axis)
        wing /= np.maximum(np.linalg.norm(wing, axis=1, keepdims=True), np.finfo(float).tiny)
        facing = wing @ wing.T
        np.fill_diagonal(facing, np.inf)
        i, j = np.unravel_index(np.argmin(facing), facing.shape)  # the most nearly opposite pair
        others = np.setdiff1d(np.arange(rows.size), [i, j])
        drop[rows[others] // 3] = True
    return drop


def _runs_each_edge_once(faces: np.ndarray) -> bool:
    """Whether no directed edge appears in two faces (the faces are wound alike across every edge)."""
    directed = np.stack([faces, np.roll(faces, -1, axis=1)], axis=-1).reshape(-1, 2)
    return len(np.unique(directed, axis=0)) == len(directed)


def _reversed_faces(before: np.ndarray, after: np.ndarray) -> int:
    """Faces (row for row) whose winding changed: the same vertices in the other cyclic order.

    Only the minority of a piece counts: reversing a whole piece changes no map.
    """
    same = np.all(np.sort(before, axis=1) == np.sort(after, axis=1), axis=1)
    cyclic = np.zeros(len(before), dtype=bool)
    for shift in range(3):
        cyclic |= np.all(np.roll(before, shift, axis=1) == after, axis=1)
    flipped = same & ~cyclic
    return int(min(flipped.sum(), (same & cyclic).sum()))


def _largest_knn_component(points: np.ndarray, k_nn: int) -> tuple[np.ndarray, int]:
    """Indices of the largest piece of the symmetrised kNN graph, and the number of pieces.

    Raises :class:`~parambench.datasets_gen.errors.DisconnectedError` when pieces of
    comparable size make "the largest" no repair (:func:`.knn_pieces.comparable_pieces`).
    """
    label = knn_labels(points, k_nn)
    counts = np.bincount(label)
    sizes = np.sort(counts)[::-1]
    if comparable_pieces(sizes):
        raise disconnected_error(sizes, k_nn, points)
    return np.flatnonzero(label == np.argmax(counts)), int(counts.size)


def repair_surface(surface: Surface, k_nn: int = 8) -> tuple[Surface, dict]:
    """The largest connected piece of ``surface``, its mesh repaired.

    Parameters
    ----------
    surface : Surface
        A mesh (faces) or a point set.
    k_nn : int
        Neighbours per point of the graph whose components a point set is split into
        (the point-set front end's ``k_nn``).

    Returns
    -------
    repaired : Surface
        Same name and ``params`` (plus ``repaired``: the facts); a point set keeps its
        normals and gets ``params["input_rows"]`` ((R,) int64: the input row of each point
        kept), a mesh drops them (its vertices are renumbered and split).
    facts : dict
        ``kind`` ("mesh" or "points"), ``pieces`` (components found), ``points_in``,
        ``points_out``; for meshes also ``faces_in``, ``faces_out``,
        ``faces_removed_in_repair``, ``vertices_split``, ``pieces_after_repair``,
        ``faces_reversed`` (faces whose winding the re-orientation changed),
        ``faces_dropped_to_orient`` (faces on the edges of a twisted flap, dropped so that
        the rest can be wound alike; among ``faces_removed_in_repair``), ``orientable``
        (False when no winding of the faces is coherent even then).

    Raises
    ------
    InvalidInputError, DegenerateFacesError, TooFewPointsError
        The repaired surface fails :class:`Surface`'s validation (e.g. too few points left).
    DisconnectedError
        A point set or mesh in pieces of comparable size (the second largest at least
        half the largest): keeping one would drop about as much as it keeps.
    """
    points = np.asarray(surface.points, dtype=np.float64)
    if surface.faces is not None:
        v, f, facts = _repair_mesh(points, np.asarray(surface.faces, dtype=np.int64))
        params = {**surface.params, "repaired": facts}
        return Surface(points=v, faces=f, name=surface.name, params=params), facts
    keep, n_comp = _largest_knn_component(points, k_nn)
    facts = {"kind": "points", "pieces": n_comp, "k_nn": int(k_nn), "points_in": int(len(points)),
             "points_out": int(keep.size)}
    normals = None if surface.normals is None else surface.normals[keep]
    rows = surface.params.get("input_rows")  # the reader may have dropped rows already
    rows = keep if rows is None else np.asarray(rows, dtype=np.int64)[keep]
    return Surface(points=points[keep], normals=normals, name=surface.name,
                   params={**surface.params, "repaired": facts, "input_rows": rows}), facts


def repair_summary(facts: dict) -> str:
    """One line saying what :func:`repair_surface` kept, dropped and split."""
    if facts["kind"] == "points":
        return (f"repaired: kept the largest of {facts['pieces']} piece(s) of the {facts['k_nn']}-nearest-neighbour "
                f"graph, {facts['points_out']} of {facts['points_in']} points")
    return (f"repaired: kept the largest of {facts['pieces']} piece(s), {facts['faces_out']} of {facts['faces_in']} "
            f"faces and {facts['points_out']} of {facts['points_in']} vertices; "
            f"{facts['vertices_split']} vertex copies from splitting non-manifold vertices, "
            f"{facts['faces_removed_in_repair']} face(s) of that piece removed (duplicates, non-manifold edges, "
            "pieces the split cut off)"
            + (f", {facts['faces_dropped_to_orient']} of them on a twisted flap that no winding of the faces "
               "could hold (a Moebius-like twist)" if facts.get("faces_dropped_to_orient") else "")
            + (f", {facts['faces_reversed']} face(s) reversed to match their neighbours' winding"
               if facts.get("faces_reversed") else "")
            + ("; its faces cannot all be wound alike (a non-orientable surface)"
               if facts.get("orientable") is False else "")
            + (f", {facts['pieces_after_repair']} pieces after the split (the largest kept)"
               if facts["pieces_after_repair"] > 1 else ""))
