"""Which way a boundary loop runs: with the surface on its left, seen from the normals' side.

The front end walks its loops so, and the self-check's turning test expects it (an outer
loop turns +1 in a map that is not mirrored). Loops handed in from outside (a plugin's, a
generator's for ``boundary="given"``) may run either way: they are turned to match.
"""
from __future__ import annotations

import numpy as np

__all__ = ["surface_on_the_left"]


def surface_on_the_left(points: np.ndarray, normals: np.ndarray, loop: np.ndarray, knn_indices: np.ndarray
                        ) -> np.ndarray:
    """``loop`` walked so that the surface lies on its left, seen from the side ``normals`` point to.

    The front end's loops run so; loops handed in may run either way, and the turning
    check read correct maps with them as "loop 0 turns -1.00 (expected +1)" (a plugin
    without a front end; ``fbcp-pc`` with ``boundary="given"`` on every generated
    surface of the quick sweep).

    Parameters
    ----------
    points, normals : (N, 3) numpy.ndarray of float64
    loop : (L,) numpy.ndarray of int64
    knn_indices : (N, K) numpy.ndarray of int64

    Returns
    -------
    (L,) numpy.ndarray of int64
        ``loop`` or ``loop[::-1]`` (the majority of its points decides).
    """
    if loop.size < 3:
        return loop
    ahead = points[np.roll(loop, -1)] - points[np.roll(loop, 1)]
    inward = points[knn_indices[loop]].mean(axis=1) - points[loop]
    left = np.cross(normals[loop], ahead)
    return loop if np.sum(np.sign(np.einsum("ij,ij->i", inward, left))) >= 0 else loop[::-1]
