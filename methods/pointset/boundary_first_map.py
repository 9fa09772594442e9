"""A first map of a disk-like point set from its boundary: the loop unrolled, the inside harmonic.

The loop is laid out in the plane with its 3D edge lengths and, at each loop point, the
turn it makes in that point's tangent plane (the geodesic curvature a flattening keeps
where the boundary keeps its length); the turns are shifted, in proportion to each
point's share of the loop's length, to add up to one full turn (the Gauss curvature
inside, which no flattening keeps, is spread along the loop), and the polygon is closed by
spreading its gap over the edges by length. The other points then solve the point
Laplacian's Dirichlet problem with the loop fixed there. This is Sawhney and Crane's
boundary-first flattening with the boundary's scale factor held at 0, on points.

It needs no eigenvector and no k, and it does not care how long the surface is: on a
developable strip it is the unrolling itself, up to the Laplacian's error. The spectral
first maps fail there: the SDP pair of a strip 4-5 times longer than wide takes the long
direction twice (the second eigenvector is the first one's overtone), and the point
energies' k searches find no regular map. Measured on scikit-learn's swiss roll and
S-curve (``make_swiss_roll``, ``make_s_curve``: uniform random points, none placed on
the rim), this first map is 7e-4 to 3e-3 of the diameter from the exact unrolling and
its uv triangulation is a mesh of the surface (0 or 1 triangle reversed against the
exact unrolling, of 3,700-39,000); ``ocp``'s refinement on that mesh then gives maps
1e-5 to 2e-4 of the diameter off (bench/MEASUREMENTS.md, forty-fourth session).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from parambench.datasets_gen.errors import SolverError

from ..spectral.sparse_eigen import SparseFactor

__all__ = ["unrolled_loop", "boundary_first_map", "harmonic_extension"]


def unrolled_loop(points: np.ndarray, normals: np.ndarray, loop: np.ndarray) -> np.ndarray:
    """A closed plane polygon with the loop's edge lengths and tangent-plane turns.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    normals : (N, 3) numpy.ndarray of float64
        Unit normals, about which the loop turns counter-clockwise (an outer loop as the
        front end orients it; a surface larger than a hemisphere turns less than nothing
        there, so the direction is not read off the turns).
    loop : (L,) numpy.ndarray of int64
        Point indices in order, L >= 3; the loop closes from the last back to the first.

    Returns
    -------
    (L, 2) numpy.ndarray of float64
        The polygon's corners, in loop order, starting at the origin.

    Raises
    ------
    SolverError
        The loop has an edge of zero length.
    """
    q, n = points[loop], normals[loop]
    out_edges = np.roll(q, -1, axis=0) - q
    lengths = np.linalg.norm(out_edges, axis=1)
    if not np.all(lengths > 0.0):
        raise SolverError("a boundary loop repeats a point: it cannot be unrolled.")

    def in_plane(vectors):
        return vectors - np.einsum("ij,ij->i", vectors, n)[:, None] * n

    before, after = in_plane(np.roll(out_edges, 1, axis=0)), in_plane(out_edges)
    turns = np.arctan2(np.einsum("ij,ij->i", np.cross(before, after), n), np.einsum("ij,ij->i", before, after))
    share = 0.5 * (lengths + np.roll(lengths, 1))
    turns += (2.0 * np.pi - turns.sum()) * share / share.sum()
    edges = lengths * np.exp(1j * np.cumsum(turns))
    edges -= edges.sum() * lengths / lengths.sum()  # close the polygon
    corners = np.concatenate([[0.0], np.cumsum(edges)[:-1]])
    return np.column_stack([corners.real, corners.imag])


def boundary_first_map(points: np.ndarray, normals: np.ndarray, loop: np.ndarray,
                       laplacian: sp.spmatrix) -> np.ndarray:
    """The loop unrolled (:func:`unrolled_loop`), every other point harmonic inside it.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    normals : (N, 3) numpy.ndarray of float64
        Consistently oriented unit normals.
    loop : (L,) numpy.ndarray of int64
        The boundary loop, counter-clockwise about the normals (the surface's only one:
        holes would be left free).
    laplacian : (N, N) scipy.sparse matrix of float64
        A point Laplacian whose rows sum to zero (e.g. ``I - W^tan``).

    Returns
    -------
    (N, 2) numpy.ndarray of float64

    Raises
    ------
    SolverError
        From :func:`unrolled_loop`, or the Laplacian's block off the loop is singular (a
        part of the points not connected to the loop).
    """
    loop = np.asarray(loop, dtype=np.int64)
    return harmonic_extension(laplacian, loop, unrolled_loop(points, normals, loop))


def harmonic_extension(laplacian: sp.spmatrix, fixed: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Values on every point: ``values`` at ``fixed``, ``L u = 0`` on the rest's rows.

    Parameters
    ----------
    laplacian : (N, N) scipy.sparse matrix of float64
    fixed : (F,) numpy.ndarray of int64
        Distinct point indices.
    values : (F, D) numpy.ndarray of float64

    Returns
    -------
    (N, D) numpy.ndarray of float64

    Raises
    ------
    SolverError
        The block of the free points is singular (a part of the points not connected to
        the fixed ones).
    """
    lap = sp.csr_matrix(laplacian)
    out = np.zeros((lap.shape[0], values.shape[1]))
    out[fixed] = values
    free = np.ones(lap.shape[0], dtype=bool)
    free[fixed] = False
    rows = lap[free]
    out[free] = SparseFactor(rows[:, free].tocsc()).solve(-(rows[:, fixed] @ values))
    return out
