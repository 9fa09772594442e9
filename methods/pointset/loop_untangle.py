"""Local self-crossings of boundary loops removed by 2-opt moves in the tangent plane.

On points scattered at random over a surface, two boundary points are often much closer
to each other than to their loop neighbours. The walk, and the points put back into it
afterwards, can then visit such a pair in the wrong order: the loop runs a -> b -> c -> d
with edge ab crossing edge cd, a curl a few spacings wide. A curl adds a full turn to
the loop's turning number, so ocp's line search (which looks for the k at which every
loop turns once) finds no regular map for any k. Measured on lilium, 20k points
scattered over the mesh: one curl of three points within 0.4 spacings of each other
turned the 595-point loop twice in the reference parameterization itself, and ocp
raised ConvergenceError at every k up to 7.5e3.

A crossing of edges ``(p_i, p_i+1)`` and ``(p_i+k, p_i+k+1)`` with ``k`` small is undone by
reversing ``p_i+1 .. p_i+k`` (a 2-opt move): the two edges become ``(p_i, p_i+k)`` and
``(p_i+1, p_i+k+1)``, which do not cross and are shorter together. Edges are compared in
the tangent plane of ``p_i+1``: a curl spans a few spacings, where the plane is a good
chart, while a crossing of far-apart parts of a loop says the surface is not resolved
and is not for this step to hide. Two guards keep the chart honest where the loop bends
out of the plane within a few steps (around the crease of ``fold``, whose two sheets'
rims project onto each other): the four ends' normals must lie within
:data:`MAX_NORMAL_ANGLE_DEG` of the chart's, and a move must also shorten the loop in 3D.
Without them, 16 moves on ``fold`` (jittered, 5k points) broke a loop that ocp mapped.
"""

from __future__ import annotations

import numpy as np

from ..geometry2d import segments_cross
from .normals import tangent_frames

__all__ = ["MAX_OFFSET", "MAX_NORMAL_ANGLE_DEG", "local_crossings", "untangle_loop", "untangle_loops"]

#: Largest ``k``: edges up to this many steps apart along the loop are compared.
MAX_OFFSET = 6

#: Largest angle, in degrees, between the chart's normal and those of the four edge ends.
MAX_NORMAL_ANGLE_DEG = 45.0

#: Rounds of moves per loop; each round undoes every crossing found that touches no other.
_MAX_ROUNDS = 20


def local_crossings(points: np.ndarray, normals: np.ndarray, loop: np.ndarray,
                    max_offset: int = MAX_OFFSET) -> np.ndarray:
    """Pairs of loop edges up to ``max_offset`` steps apart that cross in the tangent plane.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    normals : (N, 3) numpy.ndarray of float64
        Unit normals.
    loop : (L,) numpy.ndarray of int64
        Point indices in walking order (closed: the last connects to the first).
    max_offset : int
        Largest ``k``.

    Returns
    -------
    (C, 2) numpy.ndarray of int64
        Rows ``(i, k)``: edge ``(loop[i], loop[i+1])`` properly crosses edge
        ``(loop[i+k], loop[i+k+1])`` (positions modulo L), in the tangent plane of
        ``loop[i+1]``, where the four ends' normals lie within
        :data:`MAX_NORMAL_ANGLE_DEG` of that plane's; sorted by ``k``, then ``i``.
    """
    size = loop.size
    found = []
    if size < 4:
        return np.empty((0, 2), dtype=np.int64)
    pos = np.arange(size)
    centre = loop[(pos + 1) % size]
    e1, e2 = tangent_frames(normals[centre])
    origin = points[centre]

    def chart(at: np.ndarray) -> np.ndarray:
        d = points[loop[at % size]] - origin
        return np.stack([np.einsum("ij,ij->i", d, e1), np.einsum("ij,ij->i", d, e2)], axis=1)

    a0, a1 = chart(pos), chart(pos + 1)
    centre_normals = normals[centre]
    min_cos = np.cos(np.deg2rad(MAX_NORMAL_ANGLE_DEG))

    def flat(at: np.ndarray) -> np.ndarray:
        return np.einsum("ij,ij->i", normals[loop[at % size]], centre_normals) >= min_cos

    flat_a = flat(pos) & flat(pos + 1)
    # The edge size - 1 steps ahead shares a point with edge i.
    for k in range(2, min(max_offset, size - 2) + 1):
        b0, b1 = chart(pos + k), chart(pos + k + 1)
        crosses = segments_cross(a0, a1, b0, b1) & flat_a & flat(pos + k) & flat(pos + k + 1)
        hits = np.flatnonzero(crosses)
        found.append(np.stack([hits, np.full(hits.size, k)], axis=1))
    return np.concatenate(found).astype(np.int64)


def _shortens(points: np.ndarray, run: np.ndarray) -> bool:
    """True when reversing ``run[1:-1]`` shortens the run's end edges in 3D."""
    p = points[run[[0, 1, -2, -1]]]
    before = np.linalg.norm(p[1] - p[0]) + np.linalg.norm(p[3] - p[2])
    after = np.linalg.norm(p[2] - p[0]) + np.linalg.norm(p[3] - p[1])
    return bool(after < before)


def untangle_loop(points: np.ndarray, normals: np.ndarray, loop: np.ndarray,
                  max_offset: int = MAX_OFFSET) -> tuple[np.ndarray, int]:
    """The loop with its local crossings undone by 2-opt moves.

    Parameters
    ----------
    points, normals : (N, 3) numpy.ndarray of float64
    loop : (L,) numpy.ndarray of int64
    max_offset : int
        See :func:`local_crossings`.

    Returns
    -------
    loop : (L,) numpy.ndarray of int64
        The same points; only the order inside each curl changes (a curl across the
        loop's start may move the start).
    n_moves : int
        Moves made. Crossings can remain: those whose move would not shorten the loop
        in 3D, and any ``_MAX_ROUNDS`` rounds do not clear; each move shortens the loop,
        so the rounds cannot cycle.
    """
    loop = np.asarray(loop, dtype=np.int64).copy()
    size, moves = loop.size, 0
    for _ in range(_MAX_ROUNDS):
        crossings = local_crossings(points, normals, loop, max_offset)
        if crossings.size == 0:
            break
        busy = np.zeros(size, dtype=bool)
        moved = moves
        for i, k in crossings:
            span = (i + np.arange(k + 2)) % size  # the two edges' ends and what lies between
            if busy[span].any():
                continue  # touches a move of this round: checked again in the next
            if not _shortens(points, loop[span]):
                continue  # a crossing of the chart only, not of the surface
            busy[span] = True
            inner = span[1:-1]
            loop[inner] = loop[inner[::-1]]
            moves += 1
        if moves == moved:
            break  # only crossings no move may undo are left
    return loop, moves


def untangle_loops(points: np.ndarray, normals: np.ndarray, loops: list[np.ndarray],
                   max_offset: int = MAX_OFFSET) -> tuple[list[np.ndarray], int]:
    """:func:`untangle_loop` on every loop.

    Returns
    -------
    loops : list of (L_i,) numpy.ndarray of int64
    n_moves : int
        Moves made over all loops.
    """
    out, total = [], 0
    for loop in loops:
        fixed, moves = untangle_loop(points, normals, loop, max_offset)
        out.append(fixed)
        total += moves
    return out, total
