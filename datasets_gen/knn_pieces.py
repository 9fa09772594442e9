"""Pieces of a point set under its symmetrised k-nearest-neighbour graph, and what joins them.

Shared by the point-set front end (which refuses a graph that falls apart) and
``flatten --repair`` (which keeps the largest piece): both say which ``k_nn`` would join
the pieces. Scan lines or raster rows sampled several times further apart than along
them fall apart at a small K into one piece per line, all of a size; keeping the
largest of those keeps one line (31 lines of 302 points, 10 spacings apart: 302 of
9,343 points), while ``k_nn=24`` maps them whole.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from .errors import DisconnectedError, repairable

__all__ = ["CONNECTING_K", "COMPARABLE_SHARE", "CURVE_SPREAD", "knn_labels", "connecting_k", "comparable_pieces",
           "pieces_are_curves", "suggested_k", "disconnected_error"]

#: The K values :func:`connecting_k` tries, in order.
CONNECTING_K = (12, 16, 24, 32, 48, 64)
#: Pieces are comparable (keeping the largest is no repair) when the second largest has
#: at least this share of the largest's points.
COMPARABLE_SHARE = 0.5
#: A point lies on a curve when its K nearest spread across their main direction by at
#: most this share of their spread along it (standard deviations); the pieces are curves
#: when at least 90 % of the points do. Scan lines jittered by 5 % of the spacing across:
#: about 0.03; a jittered grid patch: about 1.
CURVE_SPREAD = 0.2


def _labels(n: int, neighbours: np.ndarray) -> np.ndarray:
    rows = np.repeat(np.arange(n), neighbours.shape[1])
    graph = sp.csr_matrix((np.ones(rows.size), (rows, neighbours.ravel())), shape=(n, n))
    return connected_components(graph, directed=False)[1]


def knn_labels(points: np.ndarray, k: int) -> np.ndarray:
    """Piece label of each point under its ``k`` nearest neighbours (either direction joins).

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    k : int
        Neighbours per point (capped at N - 1).

    Returns
    -------
    (N,) numpy.ndarray of int32
        Labels 0 .. pieces - 1.
    """
    k = min(int(k), len(points) - 1)
    _, idx = cKDTree(points).query(points, k=k + 1, workers=-1)
    return _labels(len(points), idx[:, 1:])


def connecting_k(points: np.ndarray, k: int) -> int | None:
    """The smallest of :data:`CONNECTING_K` above ``k`` under which the points are one piece.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    k : int
        The K that left them in pieces.

    Returns
    -------
    int or None
        None when even the largest of :data:`CONNECTING_K` leaves several pieces.
    """
    tried = [c for c in CONNECTING_K if k < c < len(points)]
    if not tried:
        return None
    _, idx = cKDTree(points).query(points, k=tried[-1] + 1, workers=-1)
    for c in tried:
        if _labels(len(points), idx[:, 1:c + 1]).max() == 0:
            return c
    return None


def suggested_k(joining: int) -> int:
    """The ``k_nn`` to propose for scan lines that ``joining`` neighbours join: the first of
    :data:`CONNECTING_K` at least twice it (or twice it).

    A neighbourhood that only just reaches the next line sees it on one side: lines 10
    and 15 spacings apart (8k points, a plane) joined at 12 and 16 and mapped at 24 and
    32, not at 12 and 24.
    """
    return next((c for c in CONNECTING_K if c >= 2 * joining), 2 * joining)


def pieces_are_curves(points: np.ndarray, k: int) -> bool:
    """Whether the points, piece by piece, sample curves (scan lines, raster rows), not surfaces.

    Judged on each point's ``k`` nearest neighbours (which, in a graph that falls apart,
    lie in its own piece): see :data:`CURVE_SPREAD`.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    k : int
    """
    k = min(int(k), len(points) - 1)
    _, idx = cKDTree(points).query(points, k=k + 1, workers=-1)
    near = points[idx] - points[idx].mean(axis=1, keepdims=True)
    spread = np.linalg.eigvalsh(np.einsum("nki,nkj->nij", near, near))  # ascending
    across = np.sqrt(np.maximum(spread[:, 1], 0.0) / np.maximum(spread[:, 2], 1e-300))
    return bool(np.mean(across <= CURVE_SPREAD) >= 0.9)


def comparable_pieces(sizes: np.ndarray) -> bool:
    """Whether the second largest piece has at least :data:`COMPARABLE_SHARE` of the largest's points.

    Parameters
    ----------
    sizes : (P,) array_like of int
        Piece sizes, largest first.
    """
    sizes = np.asarray(sizes)
    return bool(sizes.size > 1 and sizes[1] >= COMPARABLE_SHARE * sizes[0])


def disconnected_error(sizes: np.ndarray, k: int, points: np.ndarray | None = None) -> DisconnectedError:
    """The error for a point set whose ``k``-nearest-neighbour graph has several pieces.

    It names the pieces' sizes, the ``k_nn`` that joins them when the pieces are curves
    (:func:`pieces_are_curves`: scan lines, which a larger K joins into the surface they
    sample; separate patches are not joined by a longer reach) and one of
    :data:`CONNECTING_K` does, and, unless the pieces are comparable (then keeping the
    largest drops as much as it keeps), offers ``--repair``.

    Parameters
    ----------
    sizes : (P,) array_like of int
        Piece sizes, largest first (P >= 2).
    k : int
        The K used.
    points : (N, 3) numpy.ndarray of float64, optional

    Returns
    -------
    DisconnectedError
        Marked repairable (:func:`~parambench.datasets_gen.errors.repairable`) unless
        the pieces are comparable.
    """
    sizes = np.asarray(sizes)
    shown = ", ".join(str(int(s)) for s in sizes[:8]) + (", ..." if sizes.size > 8 else "")
    joining = None if points is None or not pieces_are_curves(points, k) else connecting_k(points, k)
    comparable = comparable_pieces(sizes)
    if joining is not None:
        advice = ("the points lie on lines (rows or scan lines sampled further apart than along them): "
                  f"try k_nn={suggested_k(joining)} (k_nn={joining} joins them into one piece; twice that reaches "
                  "the lines on both sides)")
    else:
        advice = "flatten each separately or increase k_nn"
    if comparable:
        advice += (f" (keeping the largest piece would drop {int(sizes.sum() - sizes[0])} of "
                   f"{int(sizes.sum())} points)")
    exc = DisconnectedError(f"the {k}-nearest-neighbour graph has several components: {shown} points"
                            f"{f' ({sizes.size} in all)' if sizes.size > 8 else ''}; {advice}.")
    return exc if comparable else repairable(exc)
