"""The check of a mesh method's map: flipped and collapsed triangles, an overlapping boundary.

A mesh map is judged on the mesh's own faces, so its facts are exact, not estimated as a
point set's are (:mod:`parambench.methods.pointset.selfcheck`): a triangle whose uv
orientation opposes the majority is a foldover, one whose uv area vanished against the
mean is collapsed (its texture is lost), a non-finite uv row is a failed solve. Valid
meshes get such maps: uniform, authalic or mean-value weights on irregular triangles
(``scp`` with ``weights=uniform`` on a 2k-vertex Delaunay disk with 30 % of its edges
flipped: 2 foldovers), ``lscm-igl``'s two pins, a mesh folded in 3D. They used to be
written with exit code 0; a map that fails this check now gets what a failed point-set
check gets: exit code 3 from ``flatten`` unless ``--force``, status ``suspect`` in a sweep.

A map with no flipped triangle can still overlap itself: a helical ribbon of 1.5 turns
(4,500 vertices) maps conformally (QC 1.0000, 0 flips) round 1.5 times, 66 % of its
triangles over others, from ``scp``, ``scp-igl``, ``lscm-igl``, ``dncp-opt`` and
``bff-mouette`` alike. Such a map's boundary crosses itself in uv (with no flips, a
boundary that does not cross itself bounds a map that does not overlap), so the
crossings of the boundary edges' images are counted too.
"""

from __future__ import annotations

import time

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from ..geometry2d import COLLAPSE_REL_TOL, crossing_segment_pairs, flipped_triangles, triangle_signed_areas
from .topology import interior_edges

__all__ = ["check_mesh_map", "boundary_crossings", "MESH_THRESHOLDS"]

#: Foldovers allowed, collapsed triangles allowed.
MESH_THRESHOLDS = {"max_flipped": 0, "max_collapsed": 0, "collapse_rel_tol": COLLAPSE_REL_TOL}

#: Vertex indices listed in a reason.
_EXAMPLES = 3


def check_mesh_map(points: np.ndarray, faces: np.ndarray, uv: np.ndarray) -> dict:
    """Flipped, collapsed and non-finite triangles of a mesh map.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
        The mesh's vertices (for the 3D folds named in the reason).
    faces : (M, 3) numpy.ndarray of int64
        Its triangles, coherently wound.
    uv : (N, 2) numpy.ndarray of float64
        The map.

    Returns
    -------
    dict
        ``passed`` (bool), ``failed`` (list of ``"flipped"``, ``"degenerate"``,
        ``"boundary-crossing"``),
        ``reason`` (one line, empty when passed), ``n_triangles``, ``n_flipped``
        (orientation against the majority: a mirror image is no flip),
        ``n_degenerate`` (|uv area| at most ``COLLAPSE_REL_TOL`` of the mean, or a corner
        with a non-finite uv), ``n_nonfinite`` (uv rows), ``flipped_faces`` (the first
        few indices), ``n_folded_3d`` (flipped faces whose 3D normal turns more than 90
        degrees from a neighbour's across an edge: the mesh folds there itself),
        ``n_boundary_crossings`` (pairs of boundary edges whose images cross; 0 when a
        uv is not finite), ``n_crossings_of_holes`` (those pairs not of the rim, the longest
        loop, with itself at edges apart in 3D: a hole's free image that drifted), ``thresholds``, ``seconds``, ``kind`` = ``"mesh"``.
    """
    start = time.perf_counter()
    uv = np.asarray(uv, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    finite_rows = np.isfinite(uv).all(axis=1)
    finite_faces = finite_rows[faces].all(axis=1)
    safe = np.where(finite_rows[:, None], uv, 0.0)
    flipped = flipped_triangles(safe, faces) & finite_faces
    area = np.abs(triangle_signed_areas(safe, faces))
    collapsed = ~finite_faces | (area <= COLLAPSE_REL_TOL * area[finite_faces].mean() if finite_faces.any() else True)
    flipped_idx = np.flatnonzero(flipped)
    facts = {"kind": "mesh", "n_triangles": int(len(faces)), "n_flipped": int(flipped_idx.size),
             "n_degenerate": int(collapsed.sum()), "n_nonfinite": int((~finite_rows).sum()),
             "flipped_faces": flipped_idx[:_EXAMPLES].tolist(),
             "n_folded_3d": int(_folded_in_3d(points, faces, flipped_idx).sum()),
             **_crossing_facts(points, uv, faces, finite_rows.all())}
    failed = []
    if facts["n_flipped"] > MESH_THRESHOLDS["max_flipped"]:
        failed.append("flipped")
    if facts["n_degenerate"] > MESH_THRESHOLDS["max_collapsed"]:
        failed.append("degenerate")
    if facts["n_boundary_crossings"]:
        failed.append("boundary-crossing")
    facts.update(passed=not failed, failed=failed, reason=_reason(facts, faces), thresholds=dict(MESH_THRESHOLDS),
                 seconds=round(time.perf_counter() - start, 4))
    return facts


def boundary_crossings(uv: np.ndarray, faces: np.ndarray) -> int:
    """Pairs of boundary edges (edges of one face) whose uv images cross properly.

    Parameters
    ----------
    uv : (N, 2) numpy.ndarray of float64
        Finite.
    faces : (M, 3) numpy.ndarray of int64

    Returns
    -------
    int
    """
    return len(_crossing_pairs(uv, faces)[1])


def _crossing_pairs(uv: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The boundary edges ((B, 2) vertex pairs) and the pairs of them ((P, 2) rows) whose images cross."""
    edges = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    unique, count = np.unique(edges, axis=0, return_counts=True)
    rim = unique[count == 1]
    return rim, crossing_segment_pairs(uv, rim)


def _crossing_facts(points: np.ndarray, uv: np.ndarray, faces: np.ndarray, finite: bool) -> dict:
    """``n_boundary_crossings``; ``n_crossings_of_holes``: those of a hole, or of edges that
    touch in 3D (a loop through both copies of a split pinch).

    A hole's image over another hole or over the rim, or over itself (turned inside out:
    pymeshfix's Stanford bunny, repaired, 26 crossings of its small holes), is a free
    boundary the map let drift, and so is a loop's image crossing itself where the loop
    touches itself on the surface (pymeshfix's planar_mesh, repaired: 2 such crossings);
    filling the hole helps. The rim (the longest loop) crossing itself where its edges lie
    apart on the surface is a surface that winds round (a helical strip): only a cut helps.
    """
    if not finite:
        return {"n_boundary_crossings": 0, "n_crossings_of_holes": 0}
    rim, pairs = _crossing_pairs(uv, faces)
    if not len(pairs):
        return {"n_boundary_crossings": 0, "n_crossings_of_holes": 0}
    used, ends = np.unique(rim, return_inverse=True)
    ends = ends.reshape(rim.shape)
    graph = sp.coo_matrix((np.ones(len(rim)), (ends[:, 0], ends[:, 1])), shape=(used.size, used.size))
    loop = connected_components(graph, directed=False)[1][ends[:, 0]]
    outer = np.bincount(loop).argmax()  # the longest loop (most edges): the rim
    first, second = loop[pairs[:, 0]], loop[pairs[:, 1]]
    a, b = rim[pairs[:, 0]], rim[pairs[:, 1]]
    gap = np.linalg.norm(points[a][:, :, None, :] - points[b][:, None, :, :], axis=-1).min(axis=(1, 2))
    touching = gap <= 1e-6 * np.linalg.norm(np.ptp(points, axis=0))
    of_holes = (first != second) | (first != outer) | touching
    return {"n_boundary_crossings": int(len(pairs)), "n_crossings_of_holes": int(of_holes.sum())}


def _folded_in_3d(points: np.ndarray, faces: np.ndarray, which: np.ndarray) -> np.ndarray:
    """Of the faces ``which``, those whose normal is more than 90 degrees from a neighbour's across an edge."""
    if which.size == 0:
        return np.zeros(0, dtype=bool)
    p = points[faces]
    normal = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    _, pairs, _ = interior_edges(faces)
    folds = pairs[np.einsum("ij,ij->i", normal[pairs[:, 0]], normal[pairs[:, 1]]) < 0]
    at_fold = np.zeros(len(faces), dtype=bool)
    at_fold[folds.ravel()] = True
    return at_fold[which]


def _reason(facts: dict, faces: np.ndarray) -> str:
    parts = []
    if facts["n_flipped"]:
        shown = ", ".join(f"face {f} (vertices {', '.join(str(int(v)) for v in faces[f])})"
                          for f in facts["flipped_faces"])
        more = ", ..." if facts["n_flipped"] > len(facts["flipped_faces"]) else ""
        folded = (f"; {facts['n_folded_3d']} of them where the mesh itself folds back (a neighbour's normal more "
                  "than 90 degrees from theirs)" if facts["n_folded_3d"] else "")
        parts.append(f"{facts['n_flipped']} of {facts['n_triangles']} triangles flipped in uv ({shown}{more}{folded})")
    if facts["n_degenerate"]:
        nonfinite = f", {facts['n_nonfinite']} vertex/vertices with a non-finite uv" if facts["n_nonfinite"] else ""
        parts.append(f"{facts['n_degenerate']} triangle(s) collapsed to zero uv area{nonfinite}")
    if facts["n_boundary_crossings"]:
        parts.append(f"the boundary's image crosses itself in {facts['n_boundary_crossings']} place(s) (the map "
                     "overlaps itself)")
    return "; ".join(parts)
