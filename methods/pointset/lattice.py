"""Whether a point set is a lattice: an elevation raster, a range image, a grid sampling.

Rasters and organised scans come as lattices: every point's neighbours in opposite pairs
(j and 2 i - j). Their maps are worth refining on the uv mesh (``ocp``'s ``refine``): the
uv triangulation of a lattice is the lattice's own regular mesh, and cotangent SCP on it
is nearer conformal than the point-set energies (measured, ``ocp`` against ``scp-igl``
on the true mesh, QC mean: matplotlib's jacksboro DEM 1.0076 -> 1.0016, grid-sampled bump
1.0016 -> 1.0001, the grid cylinder's distance from its exact map 1.7e-3 -> 2.5e-5 of the
diameter).
"""

from __future__ import annotations

import numpy as np

from .neighbourhoods import KnnGraph

__all__ = ["lattice_share", "is_lattice", "LATTICE_SHARE", "LATTICE_NEIGHBOURS", "MIRROR_TOL", "SAMPLE"]

#: The median share of mirrored neighbours from which the points are taken for a lattice.
#: Measured (8 neighbours, mirrors matched in the tangent plane): matplotlib's jacksboro
#: DEM (every fourth sample) and the generated grid samplings 1.0; the real triangle
#: meshes 0 (bump-domain, bunny10k), 0.25 (camelhead, meg-helmet, spot-top) and 0.5
#: (lilium, a regular remesh: near-hexagonal); jittered, random and graded samplings 0.
LATTICE_SHARE = 0.75
#: Neighbours the test looks at, nearest first: a square lattice's 8-ring, whose mirrors
#: are all in it. Beyond it the next ring comes in part, and on a rough raster not in
#: mirrored pairs: pymeshlab's 65 x 65 fractal terrain at height 0.3 is a lattice with 8
#: neighbours and was not with the 12 of ``ocp``'s retry, whose map then went unrefined.
LATTICE_NEIGHBOURS = 8
#: A mirror counts as a neighbour within this many nearest-neighbour distances.
MIRROR_TOL = 0.2
#: Points the test looks at (a seeded subsample: the test is a median).
SAMPLE = 4000


def lattice_share(points: np.ndarray, graph: KnnGraph, normals: np.ndarray,
                  rows: np.ndarray | None = None) -> np.ndarray:
    """Per point, the share of its nearest neighbours j whose mirror 2 i - j is another of them.

    Inside a lattice every neighbour's mirror is a neighbour at the same distance. The
    distance is measured in the point's tangent plane: on a raster of heights the mirror
    misses the lattice point along the normal by the heights' second difference.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    graph : KnnGraph
        K nearest neighbours, nearest first; the first :data:`LATTICE_NEIGHBOURS` are used.
    normals : (N, 3) numpy.ndarray of float64
        Unit normals (orientation does not matter).
    rows : (R,) numpy.ndarray of int64, optional
        Only these points (default: all).

    Returns
    -------
    (R,) numpy.ndarray of float64
        In [0, 1]; 1 inside a lattice, about 0.5 on its rim.
    """
    rows = np.arange(points.shape[0]) if rows is None else np.asarray(rows, dtype=np.int64)
    k = min(graph.k, LATTICE_NEIGHBOURS)
    near = points[graph.indices[rows, :k]]  # (R, k, 3)
    offsets = (2.0 * points[rows, None, None, :] - near[:, :, None, :]) - near[:, None, :, :]
    along = np.einsum("rjmi,ri->rjm", offsets, normals[rows])
    in_plane = np.sqrt(np.maximum(np.einsum("rjmi,rjmi->rjm", offsets, offsets) - along * along, 0.0))
    return (in_plane.min(axis=2) <= MIRROR_TOL * graph.distances[rows, :1]).mean(axis=1)


def is_lattice(points: np.ndarray, graph: KnnGraph, normals: np.ndarray, seed: int = 0) -> bool:
    """Whether the points are a lattice: the median :func:`lattice_share` of a seeded
    subsample of :data:`SAMPLE` points is at least :data:`LATTICE_SHARE`.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    graph : KnnGraph
    normals : (N, 3) numpy.ndarray of float64
    seed : int
        Seed of the subsample.

    Returns
    -------
    bool
    """
    n = points.shape[0]
    rows = np.arange(n) if n <= SAMPLE else np.sort(np.random.default_rng(seed).choice(n, SAMPLE, replace=False))
    return bool(rows.size and np.median(lattice_share(points, graph, normals, rows)) >= LATTICE_SHARE)
