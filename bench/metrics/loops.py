"""The judge's own boundary loops and turning numbers.

Written apart from the methods' versions (:mod:`parambench.datasets_gen.mesh_loops`,
:mod:`parambench.methods.geometry2d`) on purpose: the evaluation must not share code with what it
evaluates, or a bug in the methods' loops would also hide itself in the scores.
``tests/bench/test_metrics_independent.py`` compares the two on several inputs.
"""

from __future__ import annotations

import numpy as np

from .orientation import triangle_signed_areas

__all__ = ["mesh_boundary_loops", "turning_number", "signed_area_2d"]


def mesh_boundary_loops(faces: np.ndarray) -> list[np.ndarray]:
    """Boundary loops of a triangle mesh, longest first, each following its faces.

    A boundary edge is a directed face edge whose reverse belongs to no face; the loops
    chain these edges head to tail. Each loop starts at its smallest vertex index and
    equal lengths are ordered by that vertex, so the result does not depend on the face
    order. Where a vertex starts two boundary edges (two fans touching at a boundary
    vertex), the walk takes the lower-numbered one first; every boundary edge is used
    exactly once.

    Parameters
    ----------
    faces : (M, 3) numpy.ndarray of int
        Validated faces (indices in range).

    Returns
    -------
    list of (L_i,) numpy.ndarray of int64
        Empty for a closed mesh.
    """
    f = np.asarray(faces, dtype=np.int64)
    if f.size == 0:
        return []
    tail = f.ravel()
    head = np.roll(f, -1, axis=1).ravel()
    n = int(f.max()) + 1
    is_boundary = ~np.isin(tail * n + head, head * n + tail)
    order = np.lexsort((head[is_boundary], tail[is_boundary]))
    tails, heads = tail[is_boundary][order], head[is_boundary][order]
    first_out = np.searchsorted(tails, np.arange(n + 1))
    used = np.zeros(tails.size, dtype=bool)
    loops = []
    # Boundaries hold ~sqrt(N) edges, so a plain walk costs nothing next to the metrics.
    for start in range(tails.size):
        if used[start]:
            continue
        loop, edge = [], start
        while edge is not None and not used[edge]:
            used[edge] = True
            loop.append(tails[edge])
            v = heads[edge]
            free = [e for e in range(first_out[v], first_out[v + 1]) if not used[e]]
            edge = free[0] if free else None
        loops.append(np.asarray(loop, dtype=np.int64))
    loops = [np.roll(lp, -int(np.argmin(lp))) for lp in loops]
    return sorted(loops, key=lambda lp: (-lp.size, int(lp[0])))


def turning_number(polygon: np.ndarray) -> float:
    """Turning number of a closed 2D polygon: the change of its edge direction over 2 pi.

    +1 for a simple counter-clockwise polygon, -1 for a clockwise one, 2 for a boundary
    that winds twice. Zero-length edges are skipped.

    Parameters
    ----------
    polygon : (L, 2) array_like of float64
        Vertices in order; the closing edge is implied.

    Returns
    -------
    float
        An integer up to rounding error (~1e-12); 0.0 for fewer than two edges.
    """
    p = np.asarray(polygon, dtype=np.float64)
    edges = np.diff(np.vstack([p, p[:1]]), axis=0)
    edges = edges[np.any(edges != 0.0, axis=1)]
    if edges.shape[0] < 2:
        return 0.0
    heading = np.arctan2(edges[:, 1], edges[:, 0])
    # each turn, from one edge's heading to the next, wrapped into [-pi, pi)
    turn = np.mod(np.diff(np.append(heading, heading[0])) + np.pi, 2.0 * np.pi) - np.pi
    return float(turn.sum() / (2.0 * np.pi))


def signed_area_2d(polygon: np.ndarray) -> float:
    """Signed area of a closed 2D polygon, positive if counter-clockwise.

    The sum of the signed areas of the fan of triangles from its first vertex
    (:func:`parambench.bench.metrics.orientation.triangle_signed_areas`).

    Parameters
    ----------
    polygon : (L, 2) array_like of float64
        Vertices in order; the closing edge is implied.

    Returns
    -------
    float
    """
    p = np.asarray(polygon, dtype=np.float64)
    k = np.arange(1, p.shape[0] - 1)
    fan = np.column_stack([np.zeros_like(k), k, k + 1])
    return float(triangle_signed_areas(p, fan).sum())
