"""Neighbourhoods that stay on the surface across narrow gaps (lips, slits, folds).

Where two parts of a surface come within a few spacings of each other, a point's
Euclidean K nearest neighbours include points of the other part: every later stage
(normals, DEM fronts, weights, boundary) then bridges the gap. A neighbour across a gap
lies off the point's tangent plane (along the normal), while a neighbour on the surface
lies in it up to curvature and noise. So candidates (more than K Euclidean neighbours)
are kept only while their offset from the tangent plane, fitted on the nearest few
neighbours (which lie on the point's own sheet), is small against the in-plane distance
or within the noise level measured over the whole set; the K nearest kept candidates
form the graph. Normals are refitted on the kept neighbours and the test is repeated once.

:func:`pruned_knn_graph` (``neighbours="pruned"``) instead drops single edges by a test
symmetric in their two ends: an edge is dropped when each end lies off the other's
tangent plane on the side of facing (or back-to-back) sheets, or when the two ends'
normals, oriented along the already pruned graph, point against each other.

:func:`gap_aware_knn_graph` (``neighbours="auto"``, the default) cuts edges only where
it finds a gap: when some edge the pruning drops joins points that are more than
:data:`GAP_HOPS` hops apart along the pruned graph. An edge dropped on curvature or noise
(fingertips, a noisy plane) has a detour of 2-4 hops; an edge across a gap does not.
Elsewhere the graph is the Euclidean one, so surfaces without gaps are unchanged. Where
a gap is found, the pruning runs again with poorly fitted normals borrowed from the
best-fitted neighbour, and only its dropped edges without such a detour are cut.
"""

from __future__ import annotations

from pathlib import Path

import numba
import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from ..numba_cache import configure_numba_cache
from .neighbourhoods import KnnGraph, far_along_graph, knn_graph, symmetric_adjacency
from .normals import _dot3, consistent_signs, pca_fit, pca_normals
from .row_chunks import for_each_chunk

__all__ = ["surface_knn_graph", "pruned_knn_graph", "gap_aware_knn_graph", "gap_suspected", "graph_without_edges",
           "CANDIDATE_FACTOR", "MAX_SLOPE", "FACING_TOL", "GAP_HOPS", "BORROW_RATIO"]

# On-disk kernel cache where one is writable, none otherwise (see parambench.methods.numba_cache).
_CACHE, _ = configure_numba_cache(Path(__file__).resolve().parent)

#: Euclidean candidates examined per point, in units of K.
CANDIDATE_FACTOR = 2

#: Largest slope |offset along normal| / |offset in plane| of a neighbour on the surface
#: (tan 35 degrees: curvature radius >= ~1.4 neighbour distances).
MAX_SLOPE = np.tan(np.deg2rad(35.0))

#: Plane fits use this many nearest neighbours (the point's own sheet even across a gap
#: of two spacings).
_FIT_K = 6

#: Offsets up to this many robust standard deviations of all offsets count as noise.
_NOISE_SIGMAS = 3.0


def _keep_mask(points, cand, normals, noise_level):
    d = points[cand] - points[:, None, :]
    along = np.abs(np.einsum("nki,ni->nk", d, normals))
    in_plane = np.sqrt(np.maximum(np.einsum("nki,nki->nk", d, d) - along**2, 0.0))
    return along <= np.maximum(MAX_SLOPE * in_plane, noise_level)


#: Rows per batch of :func:`_noise_level`.
_NOISE_CHUNK = 65536


def _noise_level(points, cand, normals):
    # Robust scale of the out-of-plane offsets of the nearest neighbours: curvature and
    # noise, not gaps (a gap affects few points).
    near = cand[:, :_FIT_K]
    along = np.empty(near.shape)

    def batch(sl: slice) -> None:  # row batches on worker threads: the same per-row einsum
        d = points[near[sl]] - points[sl, None, :]
        along[sl] = np.abs(np.einsum("nki,ni->nk", d, normals[sl]))

    for_each_chunk(batch, points.shape[0], _NOISE_CHUNK)
    return _NOISE_SIGMAS * 1.4826 * float(np.median(along))


def _first_kept(cand, dist, keep, k):
    # Stable sort puts kept candidates first, each group in distance order; rows with
    # fewer than k kept candidates are filled with their nearest rejected ones (they
    # cannot be told apart from the surface at this sampling).
    order = np.argsort(~keep, axis=1, kind="stable")[:, :k]
    idx = np.take_along_axis(cand, order, axis=1)
    dst = np.take_along_axis(dist, order, axis=1)
    resort = np.argsort(dst, axis=1, kind="stable")
    return np.take_along_axis(idx, resort, axis=1), np.take_along_axis(dst, resort, axis=1)


def surface_knn_graph(points: np.ndarray, k: int = 8) -> tuple[KnnGraph, dict]:
    """K neighbours per point taken along the surface, not across narrow gaps.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
        Validated, duplicate-free points, N > k.
    k : int
        Neighbours per point.

    Returns
    -------
    graph : KnnGraph
        Rows nearest first, self excluded.
    diagnostics : dict
        ``n_points_with_rejected`` (points where a Euclidean K-nearest neighbour was
        replaced), ``noise_level`` (offset tolerance, length units).
    """
    n = points.shape[0]
    m = min(n - 1, CANDIDATE_FACTOR * k)
    dist, idx = cKDTree(points).query(points, k=m + 1, workers=-1)
    cand = np.ascontiguousarray(idx[:, 1:], dtype=np.int64)
    dist = np.ascontiguousarray(dist[:, 1:], dtype=np.float64)
    normals = pca_normals(points, cand[:, :min(_FIT_K, m)])
    noise = _noise_level(points, cand, normals)
    keep = _keep_mask(points, cand, normals, noise)
    sel, _ = _first_kept(cand, dist, keep, k)
    normals = pca_normals(points, sel)
    keep = _keep_mask(points, cand, normals, noise)
    sel, sel_dist = _first_kept(cand, dist, keep, k)
    replaced = np.any(~keep[:, :k], axis=1)
    graph = KnnGraph(indices=np.ascontiguousarray(sel), distances=np.ascontiguousarray(sel_dist),
                     mean_spacing=float(sel_dist.mean()))
    return graph, {"n_points_with_rejected": int(replaced.sum()), "noise_level": noise}


# --------------------------------------------------------------------------------------
# Consistency-pruned kNN graph (neighbours="pruned")
# --------------------------------------------------------------------------------------

#: Smallest |offset from the tangent plane| / |edge| of both ends for which an edge whose
#: ends see each other on opposite sides counts as crossing a gap (see ``_crossing``).
FACING_TOL = 0.2

#: Edges whose ends' normals, oriented along the pruned graph, have a smaller cosine are
#: dropped as joining facing sheets.
ORIENT_COS = 0.0

#: Candidate pools tried for rows left with fewer than K kept neighbours, in units of K.
_WIDER_POOLS = (4, 8)


def _crossing(points, normals, rows, cols, tol, noise=0.0):
    """Edges i-j that cross a gap between two sheets (symmetric in i and j, sign-free).

    With a = (p_j - p_i) . n_i / |p_j - p_i| and b = (p_i - p_j) . n_j / |p_j - p_i|,
    the product ``a b (n_i . n_j)`` does not depend on the normals' signs. Along a smooth
    surface, for chords shorter than the radius of curvature, a and b have the same sign
    (both ends lie below, or both above, each other's tangent plane: convex, concave and
    saddle chords alike) and ``n_i . n_j > 0`` for consistently oriented normals, so the
    product is >= 0. Across a gap between two
    sheets that face each other (or lie back to back) each end lies in front of (or
    behind) the other's plane with opposite normals, and the product is < 0. An edge is
    taken as crossing when the product is negative and both offsets exceed ``tol`` times
    the edge length and ``noise`` (offsets within a flat sheet are noise).
    """
    d = points[cols] - points[rows]
    length = np.sqrt(np.einsum("...i,...i->...", d, d))
    a = np.einsum("...i,...i->...", d, normals[rows]) / length
    b = -np.einsum("...i,...i->...", d, normals[cols]) / length
    dot = np.einsum("...i,...i->...", normals[rows], normals[cols])
    return (a * b * dot < 0) & (np.minimum(np.abs(a), np.abs(b)) > np.maximum(tol, noise / length))


def _off_plane(points, normals, rows, cols):
    # The smaller of the two ends' offsets from each other's tangent plane (length units).
    d = points[cols] - points[rows]
    return np.minimum(np.abs(np.einsum("...i,...i->...", d, normals[rows])),
                      np.abs(np.einsum("...i,...i->...", d, normals[cols])))


def _select_kept(cand, dist, keep, k):
    # Kept candidates first, nearest first; the count of kept ones per row.
    order = np.argsort(~keep, axis=1, kind="stable")[:, :k]
    return (np.take_along_axis(cand, order, axis=1), np.take_along_axis(dist, order, axis=1),
            np.minimum(keep.sum(axis=1), k))


def _fitted_normals(points, indices, borrow):
    # PCA normals; with ``borrow``, a point whose fit predicts an error more than
    # ``borrow`` times that of the best fit among its neighbours takes that fit's normal.
    if borrow is None:
        return pca_normals(points, indices)
    normals, _, error = pca_fit(points, indices)
    own_and_nbrs = np.concatenate([np.arange(points.shape[0])[:, None], indices], axis=1)
    best = np.take_along_axis(own_and_nbrs, np.argmin(error[own_and_nbrs], axis=1)[:, None], axis=1)[:, 0]
    return np.where((error > borrow * error[best])[:, None], normals[best], normals)


def pruned_knn_graph(points: np.ndarray, k: int = 8, *, fit_k: int = 6, tol: float = FACING_TOL,
                     passes: int = 2, orient_passes: int = 2, orient_cos: float = ORIENT_COS,
                     borrow: float | None = None) -> tuple[KnnGraph, dict]:
    """K nearest neighbours per point, leaving out edges that cross a gap between two sheets.

    Each point's ``2 K`` Euclidean nearest are the candidates. Normals are first fitted
    on the ``fit_k`` nearest (few enough to lie mostly on the point's own sheet); an
    edge is then dropped when its two ends lie on opposite sides of each other's
    tangent planes as facing (or back-to-back) sheets do (:func:`_crossing`, a test
    symmetric in the two ends and free of the normals' signs, so the symmetrised graph
    does not bring a dropped edge back). The K nearest kept candidates form the graph;
    normals are refitted on them and the test is repeated (``passes`` in all). Then, for
    ``orient_passes`` rounds, the normals are oriented along the pruned graph (the sign
    rule of :func:`parambench.methods.pointset.normals.consistent_signs`) and edges whose ends'
    oriented normals have a cosine below ``orient_cos`` are dropped too (sheets closer
    than ``tol`` edge lengths, e.g. closed lips, pass the offset test but face each
    other); edges within the noise level of the plane fits are kept by both tests, so
    an orientation seam on a noisy flat sheet is not cut. A row
    with fewer than K kept candidates looks among its 4 K, then 8 K nearest; a row still
    short (a sampling too coarse to tell the sheets apart) is filled with its nearest
    dropped candidates.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
        Validated, duplicate-free points, N > k.
    k : int
        Neighbours per point.
    fit_k : int
        Neighbours of the first plane fits.
    tol : float
        Offset tolerance of the crossing test, relative to the edge length.
    passes : int
        Rounds of (normal fit, offset test).
    orient_passes : int
        Rounds of (orientation, opposed-normal test, normal fit).
    orient_cos : float
        Cosine below which oriented normals count as opposed.
    borrow : float, optional
        When given, every plane fit of a point whose predicted error
        (:func:`~parambench.methods.pointset.normals.pca_fit`) is more than ``borrow``
        times the smallest among its neighbours' takes that neighbour's normal: a point
        at the free edge of one sheet whose neighbours include the other sheet's edge
        fits a plane across the gap (50-80 degrees off on "fold"), its interior neighbour
        does not. Plain PCA normals when None.

    Returns
    -------
    graph : KnnGraph
        Rows nearest first, self excluded.
    diagnostics : dict
        ``n_dropped_edges`` (Euclidean K-nearest edges i -> j left out),
        ``n_points_with_dropped`` and ``n_points_filled`` (rows that kept a dropped edge
        for want of others), ``noise_level`` (offsets below it never drop an edge).
    """
    n = points.shape[0]
    tree = cKDTree(points)
    m = min(n - 1, 2 * k)
    dist, idx = tree.query(points, k=m + 1, workers=-1)
    cand = np.ascontiguousarray(idx[:, 1:], dtype=np.int64)
    dist = np.ascontiguousarray(dist[:, 1:], dtype=np.float64)
    normals = _fitted_normals(points, cand[:, :min(fit_k, m)], borrow)
    rows = np.broadcast_to(np.arange(n)[:, None], cand.shape)
    noise = _noise_level(points, cand, normals)
    for _ in range(max(1, int(passes))):
        keep = ~_crossing(points, normals, rows, cand, tol, noise)
        sel, sel_dist, count = _select_kept(cand, dist, keep, k)
        normals = _fitted_normals(points, sel, borrow)
    oriented = None
    for _ in range(int(orient_passes)):
        # Sheets closer than a fifth of an edge pass the offset test; their normals,
        # oriented along the pruned graph (which goes round a lip rather than across it),
        # face each other.
        oriented = normals * consistent_signs(points, normals, sel)[:, None]
        # Opposed normals with offsets within the noise are an orientation seam, not a gap.
        opposed = ((np.einsum("nki,ni->nk", oriented[cand], oriented) < orient_cos)
                   & (_off_plane(points, normals, rows, cand) > noise))
        keep &= ~opposed
        sel, sel_dist, count = _select_kept(cand, dist, keep, k)
        normals = _fitted_normals(points, sel, borrow)
    sel, sel_dist = sel.copy(), sel_dist.copy()
    short = np.flatnonzero(count < k)
    for factor in _WIDER_POOLS:
        if short.size == 0 or m >= n - 1:
            break
        mm = min(n - 1, factor * k)
        wd, wi = tree.query(points[short], k=mm + 1, workers=-1)
        wi, wd = wi[:, 1:].astype(np.int64), wd[:, 1:]
        wkeep = ~_crossing(points, normals, np.broadcast_to(short[:, None], wi.shape), wi, tol, noise)
        if oriented is not None:
            wkeep &= ~((np.einsum("nki,ni->nk", oriented[wi], oriented[short]) < orient_cos)
                       & (_off_plane(points, normals, np.broadcast_to(short[:, None], wi.shape), wi) > noise))
        s_idx, s_dist, s_count = _select_kept(wi, wd, wkeep, k)
        better = s_count > count[short]
        sel[short[better]], sel_dist[short[better]] = s_idx[better], s_dist[better]
        count[short[better]] = s_count[better]
        short = short[count[short] < k]
    resort = np.argsort(sel_dist, axis=1, kind="stable")
    sel = np.ascontiguousarray(np.take_along_axis(sel, resort, axis=1))
    sel_dist = np.ascontiguousarray(np.take_along_axis(sel_dist, resort, axis=1))
    dropped = ~keep[:, :k]
    graph = KnnGraph(indices=sel, distances=sel_dist, mean_spacing=float(sel_dist.mean()))
    return graph, {"n_dropped_edges": int(dropped.sum()), "n_points_with_dropped": int(dropped.any(axis=1).sum()),
                   "n_points_filled": int(short.size), "noise_level": noise}


# --------------------------------------------------------------------------------------
# Pruning only where a gap is found (neighbours="auto", the default)
# --------------------------------------------------------------------------------------

#: A dropped edge whose ends are more than this many hops apart along the pruned graph
#: crosses a gap. Measured on the 56 cases of bench/benchmarks/bench_realdata.py: edges
#: the pruning drops on curvature or noise (protrusions' fingertips, noise 0.5 spacings)
#: all have a detour of at most 4 hops (at most 3 on every case but one edge of
#: fold/noise 0.5); on camelhead, fold (random, graded), cortex-lh and bunny10k
#: 13 to 5409 dropped edges have none.
GAP_HOPS = 4

#: ``borrow`` of the second pruning where a gap is found (see :func:`gap_aware_knn_graph`).
BORROW_RATIO = 5.0


def _confirmed_cuts(plain: KnnGraph, pruned: KnnGraph, hops: int) -> tuple[KnnGraph, int]:
    """The K nearest without the edges ``pruned`` left out that have no detour of ``hops`` along it.

    ``plain`` is the Euclidean graph with more columns than ``pruned``'s K: an edge i-j
    (either direction) is cut when ``pruned``'s row i left j out although j is nearer
    than its last member, and i and j are more than ``hops`` apart along ``pruned``.
    Each row keeps its K nearest uncut candidates (cut ones fill a row that has too few).
    """
    n, k = pruned.indices.shape
    cand, dist = plain.indices, plain.distances
    left_out = ~(cand[:, :, None] == pruned.indices[:, None, :]).any(axis=2) & (dist <= pruned.distances[:, -1:])
    rows = np.broadcast_to(np.arange(n, dtype=np.int64)[:, None], cand.shape)
    far = far_along_graph(symmetric_adjacency(pruned), rows[left_out], cand[left_out], hops)
    return graph_without_edges(cand, dist, rows[left_out][far], cand[left_out][far], k)


def graph_without_edges(cand: np.ndarray, dist: np.ndarray, i: np.ndarray, j: np.ndarray,
                        k: int) -> tuple[KnnGraph, int]:
    """The ``k`` nearest candidates of each row once the edges ``i[e]``-``j[e]`` are cut (either direction).

    Parameters
    ----------
    cand, dist : (N, C) numpy.ndarray of int64, float64
        Candidate neighbours of each point, nearest first, and their distances (C >= k).
    i, j : (E,) numpy.ndarray of int64
        Ends of the edges to cut.
    k : int

    Returns
    -------
    graph : KnnGraph
        Each row keeps its ``k`` nearest uncut candidates (cut ones fill a row that has too
        few), nearest first.
    n_cut : int
        Distinct edges cut.
    """
    n = cand.shape[0]
    rows = np.broadcast_to(np.arange(n, dtype=np.int64)[:, None], cand.shape)
    # Symmetric: an edge cut from one end is cut from the other too.
    pairs = np.unique(np.concatenate([i * n + j, j * n + i]))
    cut = np.isin(rows * n + cand, pairs)
    order = np.argsort(cut, axis=1, kind="stable")[:, :k]
    sel, sel_dist = np.take_along_axis(cand, order, axis=1), np.take_along_axis(dist, order, axis=1)
    resort = np.argsort(sel_dist, axis=1, kind="stable")
    sel = np.ascontiguousarray(np.take_along_axis(sel, resort, axis=1))
    sel_dist = np.ascontiguousarray(np.take_along_axis(sel_dist, resort, axis=1))
    return KnnGraph(indices=sel, distances=sel_dist, mean_spacing=float(sel_dist.mean())), int(pairs.size // 2)


def gap_aware_knn_graph(points: np.ndarray, k: int = 8, *, hops: int = GAP_HOPS,
                        borrow: float = BORROW_RATIO) -> tuple[KnnGraph, dict]:
    """The K nearest without the edges that cross a gap where the points have one; the Euclidean K nearest otherwise.

    :func:`pruned_knn_graph` also drops a few edges where no gap is (a fingertip whose
    radius of curvature is a fraction of a spacing, noise of half a spacing), and there
    it made ocp's maps worse (protrusions, random 2k: 34 foldovers instead of 17). An
    edge across a gap joins points far apart on the surface, so the pruned graph has no
    short detour between its ends; an edge dropped on curvature or noise has one (its
    ends share neighbours). So a gap is found when at least one dropped edge's ends are
    more than ``hops`` hops apart along the pruned graph; without one the graph is the
    Euclidean K nearest (the same as ``neighbours="euclidean"``, bit for bit).

    Where a gap is found, the pruning is run again with ``borrow`` (poorly fitted
    normals taken from the best-fitted neighbour: the plain pruning kept 6-24 edges
    between the free edges of the "fold" surface's sheets, and those alone made ocp
    fail there: removing just them by the ground truth gave 0 foldovers), and of the
    edges it leaves out only those with no detour of ``hops`` along its graph are cut
    (the borrowed normals also drop edges on the fold's tight bend, which have
    detours). Measured with ocp on "fold" (random and graded, 2k and 20k): no edge
    across the gap left, 0 foldovers, QC 1.002-1.018x scp-igl's, the same for
    ``borrow`` 5, 10 and 20 (camelhead's figures swing with it: see bench/MEASUREMENTS.md).

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
        Validated, duplicate-free points, N > k.
    k : int
        Neighbours per point.
    hops : int
        Detour length (edges) above which a left-out edge crosses a gap.
    borrow : float
        ``borrow`` of the second pruning (see :func:`pruned_knn_graph`).

    Returns
    -------
    graph : KnnGraph
        Rows nearest first, self excluded.
    diagnostics : dict
        The first pruning's (:func:`pruned_knn_graph`), plus ``n_gap_edges`` (its
        dropped Euclidean K-nearest edges without a detour of ``hops``), ``pruned``
        (whether a gap was found) and, when it was, ``n_cut_edges`` (undirected edges
        cut from the graph returned).
    """
    plain = knn_graph(points, k)
    pruned, diagnostics = pruned_knn_graph(points, k)
    # Euclidean K-nearest edges i -> j that the pruned graph's row i lacks.
    dropped = ~(plain.indices[:, :, None] == pruned.indices[:, None, :]).any(axis=2)
    rows, slot = np.nonzero(dropped)
    far = far_along_graph(symmetric_adjacency(pruned), rows, plain.indices[rows, slot], hops)
    n_gap = int(far.sum())
    diagnostics = dict(diagnostics, n_gap_edges=n_gap, pruned=bool(n_gap))
    if not n_gap:
        return plain, diagnostics
    refined, _ = pruned_knn_graph(points, k, borrow=borrow)
    candidates = knn_graph(points, min(points.shape[0] - 1, _WIDER_POOLS[0] * k))
    graph, n_cut = _confirmed_cuts(candidates, refined, hops)
    return graph, dict(diagnostics, n_cut_edges=n_cut)


def gap_suspected(points: np.ndarray, graph: KnnGraph, normals: np.ndarray, *, hops: int = GAP_HOPS,
                  tol: float = FACING_TOL, orient_cos: float = ORIENT_COS) -> int:
    """Edges of a kNN graph that may cross a gap: a cheap screen before :func:`gap_aware_knn_graph`.

    The front end's own oriented normals (fitted on the Euclidean graph) decide, with the
    tests of :func:`pruned_knn_graph` in one pass: an edge is suspect when its ends lie on
    opposite sides of each other's planes (:func:`_crossing`) or their oriented normals
    are opposed beyond the noise; a suspect edge counts when its ends are more than
    ``hops`` apart along the graph without the suspects. Only where this count is
    non-zero does the front end pay for :func:`gap_aware_knn_graph` (about 10x the kNN
    search); on surfaces without gaps the screen costs two passes over the edges.
    Checked on the 56 cases of ``bench_realdata.py``: it flags every case where
    :func:`gap_aware_knn_graph` finds a gap (camelhead, cortex-lh, bunny10k, the four
    fold samplings).

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    graph : KnnGraph
        On ``points``.
    normals : (N, 3) numpy.ndarray of float64
        Unit normals, consistently oriented.

    Returns
    -------
    int
        Suspect directed edges without a detour of ``hops``.
    """
    cand = graph.indices
    rows = np.broadcast_to(np.arange(points.shape[0])[:, None], cand.shape)
    noise = _noise_level(points, cand, normals)
    suspect = np.empty(cand.shape, dtype=np.bool_)
    _suspect_edges(points, normals, np.ascontiguousarray(cand, dtype=np.int64), float(tol), float(noise),
                   float(orient_cos), suspect)
    if not suspect.any():
        return 0
    r, c = np.nonzero(suspect)
    kept = ~suspect
    n = points.shape[0]
    rest = sp.csr_matrix((np.ones(int(kept.sum())), (rows[kept], cand[kept])), shape=(n, n))
    return int(far_along_graph((rest + rest.T).tocsr(), r, cand[r, c], hops).sum())


@numba.njit(cache=_CACHE, nogil=True, parallel=True)
def _suspect_edges(points, normals, cand, tol, noise, orient_cos, out):
    """``out[i, c]``: edge i -> cand[i, c] fails :func:`_crossing` or has opposed normals beyond the noise.

    One pass over the edges instead of a dozen (N, K, 3) temporaries; the arithmetic is
    that of ``_crossing`` and ``_off_plane`` in the same order (see ``_dot3``), so the
    tests decide alike.
    """
    n, k = cand.shape
    for i in numba.prange(n):
        nix, niy, niz = normals[i, 0], normals[i, 1], normals[i, 2]
        for c in range(k):
            j = cand[i, c]
            njx, njy, njz = normals[j, 0], normals[j, 1], normals[j, 2]
            dx = points[j, 0] - points[i, 0]
            dy = points[j, 1] - points[i, 1]
            dz = points[j, 2] - points[i, 2]
            length = np.sqrt(_dot3(dx, dy, dz, dx, dy, dz))
            along_i = _dot3(dx, dy, dz, nix, niy, niz)
            along_j = _dot3(dx, dy, dz, njx, njy, njz)
            a = along_i / length
            b = -along_j / length
            dot = _dot3(nix, niy, niz, njx, njy, njz)
            crossing = a * b * dot < 0 and min(abs(a), abs(b)) > max(tol, noise / length)
            opposed = _dot3(njx, njy, njz, nix, niy, niz) < orient_cos and min(abs(along_i), abs(along_j)) > noise
            out[i, c] = crossing or opposed
