"""Point normals: PCA fit, consistent orientation, smoothing (paper Sec. 3, 3.1).

Orientation rule (documented once, used everywhere): normals are first made consistent
by propagation along a minimum spanning tree of the kNN graph, then the global sign is
chosen so that the sum of all normals ``m`` has a non-negative component along its own
largest-magnitude axis (for the generated surfaces, whose normals point roughly to +z,
this means ``m_z >= 0``). When the normals nearly cancel (``|m| < 0.05 N``, a closed or
strongly curved surface) the sign is chosen so that normals point away from the
centroid on average.
"""

from __future__ import annotations

from pathlib import Path

import numba
import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import minimum_spanning_tree

from parambench.datasets_gen.errors import InconsistentNormalsError, InvalidInputError, repairable

from ..numba_cache import configure_numba_cache
from .local_fits import linear_smooth_rows, pca_rows
from .neighbourhoods import _find
from .row_chunks import for_each_chunk, worker_count

__all__ = [
    "pca_normals",
    "pca_fit",
    "noise_adaptive_normals",
    "NOISY_TARGET_DEG",
    "NOISY_MAX_K",
    "NOISE_TARGET_DEG",
    "orient_normals",
    "consistent_signs",
    "smooth_normals",
    "SMOOTHING_KINDS",
    "check_user_normals",
    "misoriented_normals",
    "normal_alignment",
    "MIN_NORMAL_ALIGNMENT",
    "tangent_frames",
]

# On-disk kernel cache where one is writable, none otherwise (see parambench.methods.numba_cache).
_CACHE, _ = configure_numba_cache(Path(__file__).resolve().parent)

#: Rows per batch of the per-point fits (batches run on worker threads, see
#: :mod:`parambench.methods.pointset.row_chunks`; the compiled fits of
#: :mod:`parambench.methods.pointset.local_fits` need no temporaries per batch). Each row's
#: arithmetic does not depend on the batch size (tested).
_PCA_CHUNK = 25_000

#: Ridge on the slopes of the local-linear normal smoothing, relative to its matrix's trace.
_SMOOTH_RIDGE = 1e-9

#: Weight of the off-tangent-plane term of the orientation tree's edge weights.
_OFF_PLANE_WEIGHT = 3.0

#: Weight, per radian of predicted fit error at either end, added to an orientation tree
#: edge (see :func:`consistent_signs`).
_FIT_ERROR_WEIGHT = 1.0

#: Below this ``|sum of normals| / N`` the global sign falls back to "away from the centroid".
_CANCEL_TOL = 0.05


def pca_normals(points: np.ndarray, knn_indices: np.ndarray) -> np.ndarray:
    """Unoriented normals from PCA of each point's K-neighbourhood (the point included).

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    knn_indices : (N, K) numpy.ndarray of int64

    Returns
    -------
    (N, 3) numpy.ndarray of float64
        Unit eigenvectors of the smallest eigenvalue of each neighbourhood covariance;
        signs arbitrary.
    """
    return pca_fit(points, knn_indices)[0]


def pca_fit(points: np.ndarray, nbh_indices: np.ndarray, valid: np.ndarray | None = None
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """PCA plane fit of each point with its neighbours: normal, eigenvalues, predicted error.

    The predicted error treats the fit as a regression of the normal offsets on the two
    in-plane coordinates: with residual variance ``s2 = lambda_0 / (m - 3)`` over ``m``
    points and in-plane sums of squares ``lambda_1``, ``lambda_2``, the slopes have variance
    ``s2 / lambda_1`` and ``s2 / lambda_2``, so the normal's rms tilt is
    ``sqrt(s2 (1 / lambda_1 + 1 / lambda_2))`` radians. Measured on the generated surfaces
    with normal noise of 0.25 and 0.5 spacings (jittered, 2k and 20k points, K = 8 to 64),
    the median prediction is within 20 % of the mean true error.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    nbh_indices : (M, K) numpy.ndarray of int64
        Neighbours of the first M points (the point itself excluded).
    valid : (M, K) numpy.ndarray of bool, optional
        Which neighbour columns take part (all when omitted); at least 3 per row.

    Returns
    -------
    normals : (M, 3) numpy.ndarray of float64
        Unit normals, signs arbitrary.
    eigenvalues : (M, 3) numpy.ndarray of float64
        Ascending eigenvalues of the neighbourhood scatter matrix (sums, not means).
    error : (M,) numpy.ndarray of float64
        Predicted rms tilt of the normal, radians.
    """
    m = nbh_indices.shape[0]
    nbh = np.ascontiguousarray(nbh_indices, dtype=np.int64)
    valid = (np.ones(nbh.shape, dtype=np.bool_) if valid is None
             else np.ascontiguousarray(valid, dtype=np.bool_))
    pts = np.ascontiguousarray(points, dtype=np.float64)
    normals = np.empty((m, 3))
    lam = np.empty((m, 3))
    for_each_chunk(lambda rows: pca_rows(pts, nbh, valid, rows.start, rows.stop, normals, lam), m, _PCA_CHUNK)
    count = 1.0 + valid.sum(axis=1)
    s2 = lam[:, 0] / np.maximum(count - 3.0, 1.0)
    tiny = np.finfo(np.float64).tiny
    error = np.sqrt(s2 * (1.0 / np.maximum(lam[:, 1], tiny) + 1.0 / np.maximum(lam[:, 2], tiny)))
    return normals, lam, error


#: Predicted rms normal error (degrees) above which :func:`noise_adaptive_normals` refits
#: a point's normal on a larger neighbourhood. Clean generated surfaces predict at most
#: ~2 degrees at K = 8 (95th percentile; 0.2-0.9 median), normal noise of 0.25 and 0.5
#: spacings 8 and 15 degrees.
NOISE_TARGET_DEG = 4.0

#: Largest neighbourhood (points besides the centre) of the refit.
NOISE_MAX_K = 64

#: The refit's target and largest neighbourhood on samplings the front end finds noisy and
#: full of close pairs (where it projects the balls' coordinates instead of the upwind
#: DEM): there two points a small fraction of a spacing apart along the surface but up to
#: a spacing apart along the normal keep their order in the map only if the normal is
#: right to a degree or two. Measured with ``ocp`` on 2k random samplings at normal noise
#: 0.5 spacings, foldovers on the true mesh at (4 degrees, 64) -> (2, 160): bump 11 -> 9,
#: holes 10 -> 0, saddle 9 -> 2, slit 22 -> 0. Applied to every sampling instead, the
#: clean ones' maps got worse (protrusions random 20k 0 -> 4 foldovers, camelhead 200 ->
#: 333), so it stays with the noisy, close-paired ones.
NOISY_TARGET_DEG = 2.0
NOISY_MAX_K = 160

#: A refit is kept only where its residual variance is at most this multiple of the median
#: (neighbourhood-averaged) K-fit residual variance among its members: noise has about
#: the same variance at every scale; curvature, a second sheet or a crease make it grow
#: with the neighbourhood. Measured ratios at 20k jittered points, refits of 13, 19 and 32
#: neighbours: noise 0.5 spacings on the plane, median 1.1-1.3, 99th percentile 2.1-2.2;
#: clean bump, saddle and cap (curvature alone), median 2.4-2.7, 4.5-5.1 and 11-13.
NOISE_RESIDUAL_GROWTH = 3.0

#: Refit sizes tried per point (each round halves the way down to K).
_REFIT_ROUNDS = 3

#: Points refitted per batch (neighbour lists and fits of at most ~100 MB).
_REFIT_CHUNK = 50_000


def noise_adaptive_normals(points: np.ndarray, knn_indices: np.ndarray, *, target_deg: float = NOISE_TARGET_DEG,
                           max_k: int = NOISE_MAX_K, return_error: bool = False
                           ) -> tuple[np.ndarray, dict] | tuple[np.ndarray, dict, np.ndarray]:
    """PCA normals, refitted on larger neighbourhoods where the fit residual says noise.

    Each point's normal is first fitted on its K nearest neighbours (as
    :func:`pca_normals`), with the predicted error of :func:`pca_fit`. Where that exceeds
    ``target_deg``, the error of a plane fit falls about as 1/m with the number m of
    points (the residual stays, the in-plane spread grows as m), so the point is refitted
    on its ``m = ceil((K + 1) * error / target)`` nearest points (at most ``max_k + 1``;
    a density-adaptive size: counted in points, not in length; the noise level is the
    K-fits' residual variance averaged over the point's K-neighbourhood). The refit is
    kept where it predicts a smaller error (than the larger of the K-fit's and the one from
    the averaged noise level) and its residual variance is at most
    ``NOISE_RESIDUAL_GROWTH`` times the median of the K-fits' among its members:
    residual that grows with the neighbourhood is curvature, a crease or another sheet,
    not noise, and a larger fit would be worse there; such points try sizes halfway
    down to K (``_REFIT_ROUNDS`` sizes in all). Points whose small
    fit predicts at most ``target_deg`` keep exactly the :func:`pca_normals` normal, so
    clean samplings are unchanged (on the generated surfaces, all but a few points of
    the clean ``fold``, whose sheets 2-2.5 spacings apart fall into one neighbourhood).

    Measured mean error against the exact normals (jittered plane, bump, saddle, cap,
    2k and 20k points, noise 0.5 spacings): 18-19 degrees at K = 8, 3-5 degrees here.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    knn_indices : (N, K) numpy.ndarray of int64
        Nearest neighbours, nearest first, self excluded.
    target_deg : float
        Predicted rms error (degrees) below which a normal is kept.
    max_k : int
        Largest refit neighbourhood (neighbours besides the point).
    return_error : bool
        Also return each normal's predicted error (for :func:`orient_normals`).

    Returns
    -------
    normals : (N, 3) numpy.ndarray of float64
        Unit normals, signs arbitrary.
    info : dict
        JSON-serialisable: ``predicted_error_deg`` {median, p95} of the K-fits,
        ``n_refit`` (points whose normal was refitted), ``refit_k`` {median, max} over
        those, ``target_deg``.
    error : (N,) numpy.ndarray of float64
        Only with ``return_error``: the predicted rms error (radians) of each point's
        K-neighbour fit, refitted or not (a point whose small fit was poor stays a risky
        link for :func:`consistent_signs` even where a larger fit was kept: on the fractal
        terrain of height 0.5, seed 7, the refits' errors left 1855 points misoriented,
        the small fits' 100).
    """
    n, k = knn_indices.shape
    normals, lam, error = pca_fit(points, knn_indices)
    target = np.radians(float(target_deg))
    info = {"predicted_error_deg": {"median": float(np.degrees(np.median(error))),
                                    "p95": float(np.degrees(np.percentile(error, 95)))},
            "n_refit": 0, "refit_k": None, "target_deg": float(target_deg)}
    # Residual variance of the small fits, averaged over the neighbourhood (6 degrees of
    # freedom per point are too few to size or compare one point's fits).
    s2 = lam[:, 0] / max(k + 1 - 3, 1)
    s2_mean = (s2 + s2[knn_indices].sum(axis=1)) / (k + 1)
    tiny = np.finfo(np.float64).tiny
    error_mean = np.sqrt(s2_mean * (1.0 / np.maximum(lam[:, 1], tiny) + 1.0 / np.maximum(lam[:, 2], tiny)))
    # Refit where the point's own fit predicts too large an error (a point whose
    # neighbours are coplanar is kept even if its neighbourhood is not: next to a
    # crease). A refit must beat the larger of the two predictions: a fit whose few
    # points happen to lie near a tilted plane predicts a small error of its own.
    want = np.flatnonzero(error > target)
    small_error = np.maximum(error, error_mean)[want]
    big_k = min(int(max_k), n - 1)
    if want.size == 0 or big_k <= k:
        return (normals, info, error) if return_error else (normals, info)
    from scipy.spatial import cKDTree

    size = np.clip(np.ceil((k + 1) * error_mean[want] / target), k + 1, big_k + 1).astype(np.int64) - 1
    tree = cKDTree(points)
    done = np.zeros(want.size, dtype=bool)
    chosen = np.zeros(want.size, dtype=np.int64)
    for lo in range(0, want.size, _REFIT_CHUNK):  # bounded memory: ~100 MB per chunk
        sl = slice(lo, min(lo + _REFIT_CHUNK, want.size))
        rows = want[sl]
        _, idx = tree.query(points[rows], k=int(size[sl].max()) + 1, workers=-1)
        idx = idx[:, 1:]
        # Largest passing size first; where the residual grows too much, halve the way
        # down to K (curvature: a smaller refit still averages noise with little bias).
        for _ in range(_REFIT_ROUNDS):
            todo = np.flatnonzero(~done[sl] & (size[sl] > k))
            if todo.size == 0:
                break
            sz = size[sl][todo]
            valid = np.arange(idx.shape[1])[None, :] < sz[:, None]
            big_normals, big_lam, big_error = pca_fit_rows(points, rows[todo], idx[todo], valid)
            big_s2 = big_lam[:, 0] / np.maximum(sz + 1 - 3, 1)
            # Noise alone: the refit's residual variance is about the typical small-fit
            # one among its members (a median: robust to the few members at a crease).
            typical = _masked_median(s2_mean[idx[todo]], valid)
            ok = (big_error < small_error[sl][todo]) & (big_s2 <= NOISE_RESIDUAL_GROWTH * typical)
            normals[rows[todo[ok]]] = big_normals[ok]
            done[lo + todo[ok]] = True
            chosen[lo + todo[ok]] = sz[ok]
            size[lo + todo[~ok]] = (sz[~ok] + k) // 2
    keep = done
    size = chosen
    info["n_refit"] = int(keep.sum())
    if keep.any():
        info["refit_k"] = {"median": float(np.median(size[keep])), "max": int(size[keep].max())}
    return (normals, info, error) if return_error else (normals, info)


def fit_error_median(normal_fit: dict | None) -> float | None:
    """The median predicted plane-fit error (degrees) in :func:`noise_adaptive_normals`' facts, None without it."""
    median = ((normal_fit or {}).get("predicted_error_deg") or {}).get("median")
    return None if median is None else float(median)


def _masked_median(values: np.ndarray, valid: np.ndarray, chunk: int = 100_000) -> np.ndarray:
    """Median of each row's ``valid`` entries (at least one per row)."""
    out = np.empty(values.shape[0])
    for lo in range(0, values.shape[0], chunk):
        sl = slice(lo, lo + chunk)
        out[sl] = np.nanmedian(np.where(valid[sl], values[sl], np.nan), axis=1)
    return out


def pca_fit_rows(points: np.ndarray, rows: np.ndarray, nbh_indices: np.ndarray, valid: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`pca_fit` for the points ``rows`` only (``nbh_indices`` and ``valid`` per row)."""
    # pca_fit reads the centre as points[i] for row i: give it the rows' points first.
    local = np.concatenate([points[rows], points])
    return pca_fit(local, nbh_indices + rows.shape[0], valid)


def consistent_signs(points: np.ndarray, normals: np.ndarray, knn_indices: np.ndarray,
                     fit_error: np.ndarray | None = None) -> np.ndarray:
    """Signs (+1/-1) making normals agree along a minimum spanning tree of the kNN graph.

    Edge weights are ``1 - |n_i . n_j| + 3 (|n_i . e| + |n_j . e|)``, e the unit edge
    direction: the first term is Hoppe et al.'s (1992), so signs are decided across the
    most parallel pairs first; the second keeps the tree off edges that leave the tangent
    planes, which is what an edge across a thin part of the surface does (its two ends
    have anti-parallel normals, |n_i . n_j| ~ 1, and plain Hoppe weights would prefer
    it). Measured on the real meshes: the mesh vertex normals of camelhead disagreed with
    the propagation at 466 of 11381 points with plain Hoppe weights, at none with these.
    With ``fit_error``, each edge also costs ``_FIT_ERROR_WEIGHT`` times its ends' predicted
    fit errors: a sign passed on through a normal that may lie in the tangent plane is a
    coin toss for everything behind it, so such points become the tree's leaves. Measured
    on pymeshlab's fractal terrains (height 0.3-0.5, knife-edge ridges under the sampling
    scale): 1755 of 16641 and 1990 of 16641 points oriented against the mesh without it,
    8 and 100 with it; on the real-data benchmark only cases that fail either way changed.
    Each point's sign is the product of the edge flips on its tree path to the root,
    computed by one breadth-first pass over the tree (compiled). Each row of
    ``knn_indices`` must list distinct points.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    normals : (N, 3) numpy.ndarray of float64
        Unit normals, arbitrary signs.
    knn_indices : (N, K) numpy.ndarray of int64
        A connected neighbourhood graph.
    fit_error : (N,) numpy.ndarray of float64, optional
        Predicted rms error (radians) of each normal's fit
        (:func:`noise_adaptive_normals` with ``return_error``).

    Returns
    -------
    (N,) numpy.ndarray of float64
        ``signs * normals`` is consistently oriented (root point keeps its sign; every
        tree component has its own root if the graph is disconnected).
    """
    n, k = knn_indices.shape
    knn = np.ascontiguousarray(knn_indices, dtype=np.int64)
    # Built straight in CSR form (columns sorted per row, as scipy's COO conversion
    # leaves them): the MST's edge sort then sees the weights in the same order.
    indices = np.empty(n * k, dtype=np.int64)
    weights = np.empty(n * k)
    # Inside the kernel: at 1M points a vectorised sum would hold 128 MB more.
    errors = np.zeros(n) if fit_error is None else np.ascontiguousarray(fit_error, dtype=np.float64)
    _tree_weights(points, normals, knn, _OFF_PLANE_WEIGHT, errors, _FIT_ERROR_WEIGHT, indices, weights)
    tree_ptr, tree_idx = spanning_forest(indices, weights, k)
    return _tree_flips(normals, tree_ptr, tree_idx)


def spanning_forest(indices: np.ndarray, weights: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Minimum spanning forest of a graph whose CSR rows all have ``k`` entries: the rows it keeps.

    The same tree as scipy's ``minimum_spanning_tree`` (:func:`_spanning_forest_scipy`,
    the reference, and the path for weights that are not positive and finite): that is
    Kruskal's algorithm over the entries in stable order of weight (equal weights in
    entry order), which here sorts the entries in ``worker_count()`` parts on all cores
    and merges them (scipy's, on one core, took 1.3-2.2 s at a million points; this
    about half that, on the 2-core benchmark machine). Kruskal keeps an entry iff its
    ends are still in different trees, so the same order gives the same entries
    whatever the union-find does (and an entry whose reverse, at the same weight, comes
    first can be left out: it would be rejected).

    Parameters
    ----------
    indices : (N * k,) numpy.ndarray of int64
        Column of each entry; row i holds entries ``i * k`` to ``i * k + k - 1``.
    weights : (N * k,) numpy.ndarray of float64
    k : int

    Returns
    -------
    indptr : (N + 1,) numpy.ndarray of int64
    indices : (M,) numpy.ndarray of int64
        The kept entries as CSR rows, in their original order within each row.
    """
    n = indices.size // k if k else 0
    if n == 0 or not (np.isfinite(weights).all() and (weights > 0).all()):
        return _spanning_forest_scipy(indices, weights, k)
    # An entry whose reverse (same weight) comes earlier is always rejected (its ends
    # are joined by then): left out, the sort and the loop see about half the entries.
    first = np.empty(indices.size, dtype=np.bool_)
    _first_of_twins(indices, weights, k, first)
    entries = np.flatnonzero(first)
    order = entries[_stable_order(weights[entries])]
    keep = _kruskal_keep(order, indices, k, n)
    indptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(keep.reshape(n, k).sum(axis=1), out=indptr[1:])
    return indptr, indices[keep]


def _spanning_forest_scipy(indices: np.ndarray, weights: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """:func:`spanning_forest` by scipy's ``minimum_spanning_tree`` (reference, and any odd weights)."""
    n = indices.size // k if k else 0
    idx_dtype = np.int32 if indices.size < 2**31 - 1 else np.int64
    graph = sp.csr_matrix((weights, indices.astype(idx_dtype), np.arange(0, n * k + 1, k, dtype=idx_dtype)),
                          shape=(n, n))
    tree = minimum_spanning_tree(graph).tocsr()
    return tree.indptr.astype(np.int64), tree.indices.astype(np.int64)


def _stable_order(keys: np.ndarray) -> np.ndarray:
    """``np.argsort(keys, kind="stable")`` for keys without NaN, on all cores.

    Each of ``worker_count()`` contiguous parts is sorted by numpy's default sort (about
    twice as fast as its stable one on these weights), its runs of equal keys put back
    in position order (so the part is sorted stably), and the parts are merged.
    """
    m = keys.size
    order = np.empty(m, dtype=np.int64)

    def part(rows: slice) -> None:
        order[rows] = np.argsort(keys[rows])
        order[rows] += rows.start
        _sort_tied_runs(keys, order[rows])

    parts = max(1, min(worker_count(), m))
    chunk = -(-m // parts)
    for_each_chunk(part, m, chunk)
    bounds = list(range(0, m, chunk)) + [m]
    spare = np.empty_like(order)
    while len(bounds) > 2:  # merge neighbouring runs pairwise (an odd last run is copied)
        for g in range(0, len(bounds) - 1, 2):
            _merge_runs(keys, order, bounds[g], bounds[g + 1], bounds[min(g + 2, len(bounds) - 1)], spare)
        order, spare = spare, order
        bounds = bounds[:-1:2] + [m]
    return order


@numba.njit(cache=_CACHE, nogil=True)
def _sort_tied_runs(keys, order):
    """Sort each run of equal ``keys[order]`` by position: an (unstable) argsort becomes the stable one."""
    m = order.size
    lo = 0
    while lo < m:
        hi = lo + 1
        while hi < m and keys[order[hi]] == keys[order[lo]]:
            hi += 1
        if hi - lo > 16:
            # Long runs exist: on an exactly flat region every edge has parallel normals
            # and lies in the plane, so its weight is the floor 1e-9 (protrusions' flat
            # base at 100k points: insertion sort here took 6 s of the front end's 8).
            order[lo:hi] = np.sort(order[lo:hi])
        else:
            for i in range(lo + 1, hi):  # insertion sort: most runs are the two directions of an edge
                v = order[i]
                j = i
                while j > lo and order[j - 1] > v:
                    order[j] = order[j - 1]
                    j -= 1
                order[j] = v
        lo = hi


@numba.njit(cache=_CACHE, nogil=True)
def _merge_runs(keys, order, lo, mid, hi, out):
    """Merge the sorted runs ``order[lo:mid]`` and ``order[mid:hi]`` into ``out[lo:hi]``; ties keep the first run's first."""
    i, j, o = lo, mid, lo
    while i < mid and j < hi:
        if keys[order[j]] < keys[order[i]]:
            out[o] = order[j]
            j += 1
        else:
            out[o] = order[i]
            i += 1
        o += 1
    while i < mid:
        out[o] = order[i]
        i += 1
        o += 1
    while j < hi:
        out[o] = order[j]
        j += 1
        o += 1


@numba.njit(cache=_CACHE, nogil=True, parallel=True)
def _first_of_twins(indices, weights, k, out):
    """``out[e]``: no earlier entry joins the same two points at the same weight (rows of ``k`` entries).

    The reverse of entry e (row i, column j) is in row j; it comes earlier when j < i.
    """
    n = indices.size // k
    for i in numba.prange(n):
        for e in range(i * k, i * k + k):
            j = indices[e]
            out[e] = True
            if j < i:
                for f in range(j * k, j * k + k):
                    if indices[f] == i and weights[f] == weights[e]:
                        out[e] = False
                        break


@numba.njit(cache=_CACHE, nogil=True)
def _kruskal_keep(order, indices, k, n):
    """Kruskal's algorithm over the entries in ``order`` (entry e joins row ``e // k`` and ``indices[e]``).

    Returns a mask over all entries of ``indices``: the kept ones.
    """
    parent = np.arange(n)
    keep = np.zeros(indices.size, dtype=np.bool_)
    joined = 0
    for e in order:
        if joined == n - 1:
            break  # one tree: every later entry closes a cycle
        a = _find(parent, e // k)
        b = _find(parent, indices[e])
        if a != b:
            parent[max(a, b)] = min(a, b)
            keep[e] = True
            joined += 1
    return keep


@numba.njit(cache=_CACHE, nogil=True)
def _dot3(ax, ay, az, bx, by, bz):
    # numpy's einsum("ij,ij->i") over 3 columns sums as (x0 + x2) + x1 (measured, numpy
    # 2.4): the same order keeps results bit-identical to the numpy code these kernels replaced.
    return (ax * bx + az * bz) + ay * by


@numba.njit(cache=_CACHE, nogil=True, parallel=True)
def _tree_weights(points, normals, knn, off_plane_weight, fit_error, fit_weight, indices, weights):
    """The orientation graph's CSR rows (see :func:`consistent_signs`): columns sorted, their weights.

    Arithmetic in the order of the numpy expressions it replaced (see ``_dot3``), so the
    weights are the same to the bit (the MST's ties depend on them); the fit-error term
    is added last (adding 0.0 where no errors are given changes no bit).
    """
    n, k = knn.shape
    for i in numba.prange(n):
        base = i * k
        for c in range(k):
            j = knn[i, c]
            dot = _dot3(normals[i, 0], normals[i, 1], normals[i, 2], normals[j, 0], normals[j, 1], normals[j, 2])
            ex = points[j, 0] - points[i, 0]
            ey = points[j, 1] - points[i, 1]
            ez = points[j, 2] - points[i, 2]
            length = np.sqrt((ex * ex + ey * ey) + ez * ez)  # np.linalg.norm's order
            ex /= length
            ey /= length
            ez /= length
            off = (abs(_dot3(normals[i, 0], normals[i, 1], normals[i, 2], ex, ey, ez))
                   + abs(_dot3(normals[j, 0], normals[j, 1], normals[j, 2], ex, ey, ez)))
            w = 1.0 - abs(dot) + off_plane_weight * off + 1e-9 + fit_weight * (fit_error[i] + fit_error[j])
            # Insertion into the row's sorted columns (k is small).
            pos = base + c
            while pos > base and indices[pos - 1] > j:
                indices[pos] = indices[pos - 1]
                weights[pos] = weights[pos - 1]
                pos -= 1
            indices[pos] = j
            weights[pos] = w


@numba.njit(cache=_CACHE, nogil=True)
def _tree_flips(normals, indptr, indices):
    """Signs making normals agree along a forest given as CSR edges (either direction).

    Breadth-first from the lowest unvisited point of each tree (its root keeps +1): a
    point's sign is its parent's, flipped when their normals point apart.
    """
    n = indptr.size - 1
    # Both directions of every edge, as CSR rows (counting sort by end point).
    degree = np.zeros(n + 1, dtype=np.int64)
    for i in range(n):
        for e in range(indptr[i], indptr[i + 1]):
            degree[i + 1] += 1
            degree[indices[e] + 1] += 1
    start = np.cumsum(degree)
    fill = start[:-1].copy()
    nbrs = np.empty(start[-1], dtype=np.int64)
    for i in range(n):
        for e in range(indptr[i], indptr[i + 1]):
            j = indices[e]
            nbrs[fill[i]] = j
            fill[i] += 1
            nbrs[fill[j]] = i
            fill[j] += 1
    flip = np.zeros(n)
    queue = np.empty(n, dtype=np.int64)
    for root in range(n):
        if flip[root] != 0.0:
            continue
        flip[root] = 1.0
        queue[0] = root
        head, tail = 0, 1
        while head < tail:
            v = queue[head]
            head += 1
            for e in range(start[v], start[v + 1]):
                u = nbrs[e]
                if flip[u] != 0.0:
                    continue
                dot = _dot3(normals[u, 0], normals[u, 1], normals[u, 2], normals[v, 0], normals[v, 1], normals[v, 2])
                flip[u] = -flip[v] if dot < 0.0 else flip[v]
                queue[tail] = u
                tail += 1
    return flip


def _global_sign(points: np.ndarray, normals: np.ndarray) -> float:
    total = normals.sum(axis=0)
    if np.linalg.norm(total) >= _CANCEL_TOL * normals.shape[0]:
        axis = int(np.argmax(np.abs(total)))
        return 1.0 if total[axis] >= 0 else -1.0
    outward = np.einsum("ij,ij->", normals, points - points.mean(axis=0))
    return 1.0 if outward >= 0 else -1.0


def orient_normals(points: np.ndarray, normals: np.ndarray, knn_indices: np.ndarray,
                   fit_error: np.ndarray | None = None) -> np.ndarray:
    """Consistently oriented normals with the module's global sign rule.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    normals : (N, 3) numpy.ndarray of float64
        Unit normals, arbitrary signs (e.g. from :func:`pca_normals`).
    knn_indices : (N, K) numpy.ndarray of int64
    fit_error : (N,) numpy.ndarray of float64, optional
        Predicted fit error of each normal (radians), see :func:`consistent_signs`.

    Returns
    -------
    (N, 3) numpy.ndarray of float64
    """
    oriented = normals * consistent_signs(points, normals, knn_indices, fit_error)[:, None]
    return oriented * _global_sign(points, oriented)


SMOOTHING_KINDS = ("linear", "average")


def smooth_normals(points: np.ndarray, normals: np.ndarray, knn_indices: np.ndarray,
                   knn_distances: np.ndarray, mean_spacing: float, *, method: str = "linear") -> np.ndarray:
    """Distance-weighted smoothing of normals over the K-neighbourhood (Sec. 3.1).

    Weights are ``1 / (|p - q| + 1e-4 l)`` over the K neighbours q; the point itself is
    left out, as in the authors' DEM code (the small offset only guards near-coincident
    points). The paper evaluates this in-line with the DEM; since it does not depend on
    the DEM centre, it is computed once here, which gives the same normals.

    ``method="average"`` is the paper's weighted mean of the neighbours' normals. On a
    curved surface a one-sided neighbourhood (every boundary point) tilts that mean
    towards the neighbours' side by about (offset x curvature), which costs DEM accuracy
    near the boundary. ``method="linear"`` (default) fits the same weighted data with a
    linear model ``n(q) = a + J (q - p)`` in p's tangent plane and keeps ``a``: the
    weighted average corrected for that first-order tilt (local-linear instead of
    local-constant regression). It smooths noise about as much and has no boundary tilt.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    normals : (N, 3) numpy.ndarray of float64
        Consistently oriented unit normals.
    knn_indices, knn_distances : (N, K) numpy.ndarray
    mean_spacing : float
        ``l``.
    method : {"linear", "average"}

    Returns
    -------
    (N, 3) numpy.ndarray of float64
        Unit normals.

    Raises
    ------
    InvalidInputError
        Unknown ``method``.
    """
    if method not in SMOOTHING_KINDS:
        raise InvalidInputError(f"normal smoothing must be one of {', '.join(SMOOTHING_KINDS)}, got {method!r}.")
    n = normals.shape[0]
    avg = np.empty_like(normals)
    knn = np.ascontiguousarray(knn_indices, dtype=np.int64)
    weights = 1.0 / (np.asarray(knn_distances, dtype=np.float64) + 1e-4 * mean_spacing)
    if method == "average":
        def smooth(sl: slice) -> None:
            avg[sl] = np.einsum("nk,nkj->nj", weights[sl], normals[knn[sl]])
    else:
        e1, e2 = tangent_frames(normals)
        pts = np.ascontiguousarray(points, dtype=np.float64)
        nrm = np.ascontiguousarray(normals, dtype=np.float64)

        def smooth(sl: slice) -> None:
            # A tiny ridge on the slopes keeps collinear neighbourhoods solvable; their
            # intercept then tends to the plain weighted average.
            linear_smooth_rows(pts, nrm, e1, e2, knn, weights, _SMOOTH_RIDGE, sl.start, sl.stop, avg)

    for_each_chunk(smooth, n, _PCA_CHUNK)
    norm = np.linalg.norm(avg, axis=1, keepdims=True)
    # A neighbourhood whose normals cancel exactly cannot be averaged: keep the original.
    bad = norm[:, 0] < 1e-12
    norm[bad] = 1.0
    avg[bad] = normals[bad]
    return avg / norm


def misoriented_normals(points: np.ndarray, normals: np.ndarray, knn_indices: np.ndarray) -> np.ndarray:
    """The given normals that point to the other side of the surface than the rest.

    Parameters
    ----------
    points, normals : (N, 3) numpy.ndarray of float64
    knn_indices : (N, K) numpy.ndarray of int64
        A connected neighbourhood graph (rows of distinct points).

    Returns
    -------
    (N,) numpy.ndarray of bool
        The smaller of the two groups :func:`consistent_signs` splits the normals into
        (none when they agree).
    """
    flipped = consistent_signs(points, normals, knn_indices) < 0
    return flipped if flipped.sum() <= normals.shape[0] - flipped.sum() else ~flipped


def normal_alignment(normals: np.ndarray, fitted: np.ndarray) -> float:
    """Median ``|n . n_fit|`` of given normals against fitted ones (1: perpendicular to the points)."""
    return float(np.median(np.abs(np.einsum("ij,ij->i", normals, fitted))))


#: Given normals whose median ``|cos|`` to the fitted ones is below this are refused.
MIN_NORMAL_ALIGNMENT = 0.5


def check_user_normals(points: np.ndarray, normals: np.ndarray, fitted: np.ndarray, knn_indices: np.ndarray) -> None:
    """Raise when user-supplied normals are inconsistently oriented or off the surface.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    normals : (N, 3) numpy.ndarray of float64
        The user's unit normals.
    fitted : (N, 3) numpy.ndarray of float64
        PCA normals of the same points (any signs).
    knn_indices : (N, K) numpy.ndarray of int64

    Raises
    ------
    InconsistentNormalsError
        The normals are mostly far from perpendicular to the point set (median
        ``|n . n_pca|`` below :data:`MIN_NORMAL_ALIGNMENT`, i.e. more than 60 degrees off;
        tested first), or some point to the other side of the surface than the rest (a
        consistent field needs no sign change under MST propagation). Marked repairable:
        the command line's ``--repair`` drops the first kind and flips the second.
    """
    # Off the surface first: a field of tangents has no orientation worth mending.
    align = normal_alignment(normals, fitted)
    if align < MIN_NORMAL_ALIGNMENT:
        raise repairable(InconsistentNormalsError(
            f"the given normals are far from perpendicular to the point set (median |cos| to the fitted "
            f"normals {align:.2f}); fix them, or omit normals to let parambench estimate them."
        ), "estimate normals instead")
    odd = np.flatnonzero(misoriented_normals(points, normals, knn_indices))
    if odd.size:
        raise repairable(InconsistentNormalsError(
            f"{odd.size} of {normals.shape[0]} given normals point to the other side of the surface than their "
            f"neighbours (first: point {int(odd[0])}); fix their orientation, or omit normals to let "
            "parambench estimate them."
        ), "flip them")


def tangent_frames(normals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A right-handed orthonormal tangent frame per normal, continuous away from n_z = -1.

    Uses the branchless construction of Duff et al. (2017), so ``e1 x e2 = n``.

    Parameters
    ----------
    normals : (N, 3) numpy.ndarray of float64
        Unit normals.

    Returns
    -------
    e1, e2 : (N, 3) numpy.ndarray of float64
    """
    x, y, z = normals[:, 0], normals[:, 1], normals[:, 2]
    sign = np.where(z >= 0.0, 1.0, -1.0)
    a = -1.0 / (sign + z)
    b = x * y * a
    e1 = np.stack([1.0 + sign * x * x * a, sign * b, -sign * x], axis=1)
    e2 = np.stack([b, sign + y * y * a, -y], axis=1)
    return e1, e2
