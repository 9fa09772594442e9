"""Stray points: points off the surface the rest of a point set samples (a scan's outliers).

A point off the surface joins the triangles around it to the surface below it, and the
map folds there (the self-check's "stray" cause, :mod:`.failure_causes`). It is told by
its offset from its neighbours' tangent planes: a point on the surface lies in them up to
curvature and noise. The offset taken is the second-smallest over the neighbours, in their
median spacing: a point of a thin part (an ear's two sides a spacing apart) lies in the
planes of the neighbours on its own side whatever those across the gap say, and the
second-smallest lets one neighbour be a fellow stray.

Measured on ``bump`` 10k (jittered, clean: the median point 0.001 spacings off, the
largest 0.07) with stray points added, plain PCA normals on 8 neighbours, three passes: 5
points at random in its bounding box all found; 100 there, 85 found (the other 15 lie
within about a spacing of the surface, where they are noise); 50 points lifted 1.9 grid
steps, 47 found (offsets 1.06-1.9: the 3 under ``STRAY_OFFSET`` do not fold the map); no
false one. Without strays added: none on any clean random or graded sampling of the
generated surfaces at 2k and 20k, nor on the scattered real meshes, pymeshlab's bunny, cow
and chameleon; one point on 8 of the 33 noisy 2k samplings tried (all random: 2 at normal
noise of 0.5 spacings, 6 at 1; the noise's tail); 2 of ``real/camelhead``'s 11,381 points (1.54 and 1.86 spacings, where its
sampling density jumps); 12 of the 85,849 points of pymeshlab's range scan ``face000``.
"""

from __future__ import annotations

import numpy as np

from parambench.datasets_gen.surface import core_box

from .neighbourhoods import knn_graph, local_spacing
from .normals import pca_normals
from .row_chunks import for_each_chunk

__all__ = ["STRAY_OFFSET", "STRAY_NOISE_FACTOR", "ISOLATED_BOX_SHARE", "offsets_off_surface", "stray_mask",
           "isolated_mask", "find_stray_points"]

#: Smallest offset from its neighbours' tangent planes, in their spacings, of a stray
#: point. Real meshes' largest offsets where their sampling density jumps: camelhead 1.86,
#: bunny10k 1.2, cortex-lh 1.17 (a spacing here is the neighbours' mean kNN distance).
STRAY_OFFSET = 1.5

#: ... and at least this many times the median point's offset, which grows with the noise
#: (about the noise's standard deviation at 8 neighbours).
STRAY_NOISE_FACTOR = 4.0

#: A point whose third-nearest neighbour lies farther than this share of the diagonal of
#: the points' core box (:func:`~parambench.datasets_gen.surface.core_box`) is far from the
#: surface the rest sample, wherever it lies: a junk row of a scan (``0 0 0`` in a
#: georeferenced file; 3.8e4 of the box there), which may even lie in the surface's own
#: plane, where no tangent-plane offset sees it. The third neighbour, so that two or three
#: junk rows side by side are found too, and groups of up to K of them cut off by that far
#: (:func:`isolated_mask`). Measured without junk rows: at most 0.046 on the
#: shipped meshes, 0.034-0.065 on random and graded samplings of the generated surfaces at
#: 2k points, 0.09-0.22 at 200 points. A first rule against the neighbours' own spacing
#: (50 times) also took for junk the sparse points beside a tight cluster of repeated
#: measurements or a patch sampled 100-10000 times more densely.
ISOLATED_BOX_SHARE = 0.5

#: Rows per chunk (bounded temporaries of (rows, K, 3)).
_CHUNK = 65536


def offsets_off_surface(points: np.ndarray, normals: np.ndarray, knn_indices: np.ndarray,
                        spacing: np.ndarray) -> np.ndarray:
    """Each point's second-smallest offset from its neighbours' tangent planes, in their median spacing.

    Parameters
    ----------
    points, normals : (N, 3) numpy.ndarray of float64
        Unit normals; their signs do not matter.
    knn_indices : (N, K) numpy.ndarray of int64, K >= 2
        Neighbours of each point; the point itself, where listed, is skipped.
    spacing : (N,) numpy.ndarray of float64
        Local spacing per point (> 0).

    Returns
    -------
    (N,) numpy.ndarray of float64
        The point's own normal and spacing are not used: a stray point's own are skewed
        by the surface below it.
    """
    out = np.empty(points.shape[0])

    def rows_of(rows: slice) -> None:
        own = np.arange(rows.start, rows.stop)
        nb = knn_indices[rows]
        d = points[rows][:, None, :] - points[nb]
        along = np.abs(np.einsum("vki,vki->vk", d, normals[nb]))
        along = np.where(nb == own[:, None], np.inf, along)
        out[rows] = np.partition(along, 1, axis=1)[:, 1] / np.median(spacing[nb], axis=1)

    for_each_chunk(rows_of, points.shape[0], _CHUNK)
    return out


def stray_mask(offsets: np.ndarray) -> np.ndarray:
    """(N,) bool: offsets above ``STRAY_OFFSET`` and ``STRAY_NOISE_FACTOR`` times their median."""
    return offsets > max(STRAY_OFFSET, STRAY_NOISE_FACTOR * float(np.median(offsets)))


def isolated_mask(points: np.ndarray, knn_indices: np.ndarray) -> np.ndarray:
    """(N,) bool: points far from the surface the rest sample (``ISOLATED_BOX_SHARE`` of the core box's diagonal).

    A point is isolated when its third-nearest neighbour is that far, or when it belongs to
    a group of at most K points (joined by neighbour edges shorter than that) that the rest
    lie that far from: four to eight junk rows together have each other as their nearest
    neighbours, and reach the surface only by their longest neighbour edges (more than K
    such points make a piece of the neighbour graph of their own, refused as several
    components before any map is made).

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
        Distinct points.
    knn_indices : (N, K) numpy.ndarray of int64
        Nearest neighbours of each point (the point itself, where listed, is skipped).

    Returns
    -------
    (N,) numpy.ndarray of bool
    """
    lo, hi = core_box(points)
    limit = ISOLATED_BOX_SHARE * float(np.linalg.norm(hi - lo))
    n, k = knn_indices.shape
    out = np.zeros(n, dtype=bool)
    if limit <= 0.0 or k == 0:
        return out
    rank = min(2, k - 1)
    long_edge = np.zeros(n, dtype=bool)

    def rows_of(rows: slice) -> None:
        d = np.linalg.norm(points[knn_indices[rows]] - points[rows, None, :], axis=2)
        d[d == 0.0] = np.inf  # the point itself
        out[rows] = np.partition(d, rank, axis=1)[:, rank] > limit
        long_edge[rows] = ((d > limit) & np.isfinite(d)).any(axis=1)

    for_each_chunk(rows_of, n, _CHUNK)
    if long_edge.any():  # a group cut off by long edges has one on every member
        out |= _small_far_groups(points, knn_indices, limit)
    return out


def _small_far_groups(points: np.ndarray, knn_indices: np.ndarray, limit: float) -> np.ndarray:
    """(N,) bool: members of groups of at most K points joined by neighbour edges up to ``limit``, not the largest."""
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import connected_components

    n, k = knn_indices.shape
    rows = np.repeat(np.arange(n), k)
    cols = knn_indices.ravel()
    short = (cols >= 0) & (np.linalg.norm(points[rows] - points[np.maximum(cols, 0)], axis=1) <= limit)
    graph = csr_matrix((np.ones(int(short.sum())), (rows[short], cols[short])), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    size = np.bincount(label)
    small = size <= k
    small[np.argmax(size)] = False
    return small[label]


def find_stray_points(points: np.ndarray, k_nn: int = 8, passes: int = 3) -> np.ndarray:
    """The stray points of a point set, found from its positions alone: off their neighbours'
    tangent planes (:func:`stray_mask`) or far from every other point (:func:`isolated_mask`).

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
        Distinct, finite points, N > ``k_nn``.
    k_nn : int
        Neighbours per point for the normals, the spacing and the offsets.
    passes : int
        Searches, each on the points the previous ones kept (strays next to each other
        tilt each other's planes: the second pass finds the ones the first one hid).

    Returns
    -------
    (N,) numpy.ndarray of bool
    """
    stray = np.zeros(points.shape[0], dtype=bool)
    for _ in range(max(1, int(passes))):
        kept = np.flatnonzero(~stray)
        sub = points[kept]
        graph = knn_graph(sub, min(int(k_nn), sub.shape[0] - 1))
        normals = pca_normals(sub, np.column_stack([np.arange(sub.shape[0]), graph.indices]))
        found = (stray_mask(offsets_off_surface(sub, normals, graph.indices, local_spacing(graph)))
                 | isolated_mask(sub, graph.indices))
        if not found.any():
            break
        stray[kept[found]] = True
    return stray
