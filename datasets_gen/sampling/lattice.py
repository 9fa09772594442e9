"""Regular triangular lattices and the seeded jitter that turns them into "jittered" samplings."""

from __future__ import annotations

import numpy as np

__all__ = ["triangular_lattice", "jitter_in_disk"]

#: Row spacing of a triangular lattice with unit edge length.
ROW = np.sqrt(3.0) / 2.0


def triangular_lattice(lo: np.ndarray, hi: np.ndarray, h: float, *, origin=(0.0, 0.0),
                       angle: float = 0.0) -> np.ndarray:
    """Points of a triangular lattice (equilateral triangles of edge ``h``) covering a box.

    The lattice has a point at ``origin`` and rows along the direction ``angle``; even
    rows are offset by ``h / 2`` so that neighbouring rows form equilateral triangles.

    Parameters
    ----------
    lo, hi : (2,) array_like of float
        Corners of the box to cover.
    h : float
        Lattice spacing (edge length), > 0.
    origin : (2,) array_like of float
        A lattice point.
    angle : float
        Rotation of the lattice rows, radians.

    Returns
    -------
    (n, 2) numpy.ndarray of float64
        The lattice points inside the closed box ``lo <= x <= hi``.
    """
    lo, hi, origin = (np.asarray(a, dtype=float) for a in (lo, hi, origin))
    c, s = np.cos(angle), np.sin(angle)
    rot = np.array([[c, -s], [s, c]])
    corners = np.array([[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]]) - origin
    local = corners @ rot  # box corners in lattice coordinates (rot is orthogonal)
    j0, j1 = (int(np.floor(local[:, 1].min() / (ROW * h))) - 1, int(np.ceil(local[:, 1].max() / (ROW * h))) + 1)
    i0, i1 = (int(np.floor(local[:, 0].min() / h)) - 1, int(np.ceil(local[:, 0].max() / h)) + 1)
    jj, ii = np.meshgrid(np.arange(j0, j1 + 1), np.arange(i0, i1 + 1), indexing="ij")
    u = (ii + 0.5 * (jj % 2)) * h
    v = jj * (ROW * h)
    pts = np.column_stack([u.ravel(), v.ravel()]) @ rot.T + origin
    eps = 1e-12 * max(1.0, float(np.max(np.abs(hi - lo))))
    keep = np.all((pts >= lo - eps) & (pts <= hi + eps), axis=1)
    return pts[keep]


def jitter_in_disk(n: int, radius: float, rng: np.random.Generator) -> np.ndarray:
    """Displacements uniform in the disk of ``radius``.

    Returns
    -------
    (n, 2) numpy.ndarray of float64
    """
    r = radius * np.sqrt(rng.random(n))
    a = 2.0 * np.pi * rng.random(n)
    return np.column_stack([r * np.cos(a), r * np.sin(a)])
