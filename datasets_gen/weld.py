"""Weld a mesh's coincident vertices (``parambench flatten --weld``).

Patch-based exports store a surface as pieces whose shared rims are separate, coincident
vertices: the npm package ``teapot`` is 32 Bezier patches of 32 faces, joined by 456 such
vertices, and every mesh method refuses it as 32 components. Welding joins them into the
surface they describe. It never runs unasked: a mesh cut along a seam on purpose (a
texture atlas's charts) stores its seam the same way, and welding would glue the cut.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from .repair import compact
from .surface import Surface, duplicate_tolerance, find_duplicate_points

__all__ = ["weld_coincident", "weld_summary"]


def weld_coincident(surface: Surface) -> tuple[Surface, dict]:
    """``surface`` with each group of coincident vertices merged into its first.

    Parameters
    ----------
    surface : Surface
        A mesh; a point set is returned as it is (the point-set methods merge coincident
        points themselves).

    Returns
    -------
    welded : Surface
        Vertices renumbered (the output holds these, not the input's); faces that lost a
        corner to the weld (two corners merged) dropped; ``params["welded"]`` holds the
        facts.
    facts : dict
        ``vertices_merged`` (vertices that became another), ``faces_dropped`` and
        ``tolerance`` (length unit of the points: :func:`~parambench.datasets_gen.surface.duplicate_tolerance`).
    """
    points = np.asarray(surface.points, dtype=np.float64)
    facts = {"vertices_merged": 0, "faces_dropped": 0, "tolerance": float(duplicate_tolerance(points))}
    if surface.faces is None:
        return surface, facts
    pairs = find_duplicate_points(points, tol=facts["tolerance"])
    if not pairs.size:
        return surface, facts
    n = len(points)
    graph = sp.coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, group = connected_components(graph, directed=False)
    first = np.full(group.max() + 1, n, dtype=np.int64)
    np.minimum.at(first, group, np.arange(n))
    faces = first[group][np.asarray(surface.faces, dtype=np.int64)]
    collapsed = (faces[:, 0] == faces[:, 1]) | (faces[:, 1] == faces[:, 2]) | (faces[:, 0] == faces[:, 2])
    v, f = compact(points, faces[~collapsed])
    facts.update(vertices_merged=int(n - np.unique(group).size), faces_dropped=int(collapsed.sum()))
    return Surface(points=v, faces=f, name=surface.name, params={**surface.params, "welded": facts}), facts


def weld_summary(facts: dict) -> str:
    """One line saying what :func:`weld_coincident` merged and dropped."""
    dropped = f", dropped {facts['faces_dropped']} face(s) the weld collapsed" if facts["faces_dropped"] else ""
    return (f"welded: merged {facts['vertices_merged']} coincident vertices (within {facts['tolerance']:.3g})"
            f"{dropped}")
