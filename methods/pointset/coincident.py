"""Coincident points of a point set: merged before a point-set method runs, expanded after.

Scans and merged exports often repeat a point. The point-set front end cannot use a
repeated point (its neighbourhood has a zero offset), and the point set has no faces that
could tell the copies apart, so copies are one sample: the method runs on one
representative per group (the group's first point, input order kept) and every copy gets
its representative's uv. The output keeps one row per input point, in input order.

Points count as coincident when closer than ``MERGE_SPACING_TOL`` times the median
nearest-neighbour spacing (never less than the bounding-box tolerance of
:func:`parambench.datasets_gen.surface.find_duplicate_points`, so the front end's own check accepts
the representatives).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, replace
from typing import Any, Callable

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from parambench.datasets_gen.errors import TooFewPointsError
from parambench.datasets_gen.surface import MIN_POINTS, MethodInput, duplicate_tolerance, find_duplicate_points

__all__ = ["CoincidentPointsWarning", "CoincidentGroups", "MERGE_SPACING_TOL", "merge_tolerance",
           "coincident_groups", "run_on_representatives", "warn_merged"]

#: Points closer than this fraction of the median nearest-neighbour spacing are merged.
MERGE_SPACING_TOL = 1e-6

#: Points whose spacing is measured (a strided subset: the median needs no more).
SPACING_SAMPLE = 20_000


class CoincidentPointsWarning(UserWarning):
    """Coincident input points were merged before a point-set method ran."""


@dataclass(frozen=True)
class CoincidentGroups:
    """Which input points share a representative.

    Attributes
    ----------
    representatives : (R,) numpy.ndarray of int64
        Input index of each group's first point, increasing.
    inverse : (N,) numpy.ndarray of int64
        For each input point, the row of its representative in ``representatives``.
    tolerance : float
        Merge distance used, in the points' length unit.
    """

    representatives: np.ndarray
    inverse: np.ndarray
    tolerance: float

    @property
    def n_merged(self) -> int:
        """Number of input points that are copies (N - R)."""
        return int(self.inverse.size - self.representatives.size)


def merge_tolerance(points: np.ndarray, tree: cKDTree | None = None) -> float:
    """Distance below which two points count as one sample.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    tree : scipy.spatial.cKDTree, optional
        Built over ``points``.

    Returns
    -------
    float
        ``MERGE_SPACING_TOL`` times the median distance to the nearest distinct point,
        at least :func:`~parambench.datasets_gen.surface.duplicate_tolerance`.
    """
    floor = duplicate_tolerance(points)
    tree = cKDTree(points) if tree is None else tree
    sample = points[:: max(1, points.shape[0] // SPACING_SAMPLE)]
    # k=2 sees the nearest other point; rows whose nearest is a copy say nothing of the
    # spacing and are left out of the median.
    dist, _ = tree.query(sample, k=2)
    distinct = dist[:, 1][dist[:, 1] > floor]
    if distinct.size == 0:
        return floor
    return max(floor, MERGE_SPACING_TOL * float(np.median(distinct)))


def coincident_groups(points: np.ndarray) -> CoincidentGroups:
    """Group coincident points (chains of close pairs form one group).

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64

    Returns
    -------
    CoincidentGroups
    """
    n = points.shape[0]
    # Sliding-midpoint splits: half the build time of a balanced tree at a million points,
    # and the same exact answers (nearest distances, the set of close pairs).
    tree = cKDTree(points, balanced_tree=False)
    tol = merge_tolerance(points, tree)
    pairs = find_duplicate_points(points, tol=tol, tree=tree)
    if pairs.size == 0:
        return CoincidentGroups(np.arange(n, dtype=np.int64), np.arange(n, dtype=np.int64), tol)
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, labels = connected_components(graph, directed=False)
    # A group's representative is its first point; numbering groups by it keeps input order.
    first = np.full(labels.max() + 1, n, dtype=np.int64)
    np.minimum.at(first, labels, np.arange(n, dtype=np.int64))
    order = np.argsort(first)
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    return CoincidentGroups(first[order], rank[labels].astype(np.int64), tol)


def warn_merged(name: str, groups: CoincidentGroups, what_happened: str, stacklevel: int = 3) -> None:
    """Warn once (CoincidentPointsWarning) that ``groups`` merged copies; no-op when none were merged.

    Parameters
    ----------
    name : str
        The surface's name, first in the message.
    groups : CoincidentGroups
    what_happened : str
        The rest of the message; ``{}`` is replaced by the number of distinct points.
    stacklevel : int
        Passed to :func:`warnings.warn`.
    """
    if groups.n_merged == 0:
        return
    warnings.warn(
        f"{name}: {groups.n_merged} of {groups.inverse.size} points coincide with an earlier point "
        f"(within {groups.tolerance:.3g}); " + what_happened.format(groups.representatives.size) + ".",
        CoincidentPointsWarning, stacklevel=stacklevel)


def _loops_on_representatives(loops, groups: CoincidentGroups):
    """Given boundary loops (``boundary="given"`` of ``fbcp-pc``) renumbered to the representatives.

    A copy's index becomes its representative's; a repeat of the previous point is dropped.
    """
    if loops is None:
        return None
    out = []
    for loop in loops:
        ids = groups.inverse[np.asarray(loop, dtype=np.int64)]
        keep = ids != np.roll(ids, 1)
        out.append(ids[keep] if keep.any() else ids[:1])
    return out


def run_on_representatives(run: Callable[..., Any], surface: MethodInput, params: dict) -> Any:
    """Run a point-set method on one representative per group of coincident points.

    Parameters
    ----------
    run : callable
        ``run(surface, **params)`` returning a :class:`~parambench.methods.base.Parameterization`
        over the points it is given.
    surface : MethodInput
        The method's input; faces, if any, are not passed on (a point-set method reads
        positions and, where given, normals).
    params : dict
        Resolved method parameters.

    Returns
    -------
    Parameterization
        One uv row per input point in input order, copies with their representative's uv;
        ``faces`` and ``diagnostics["boundary_loops"]`` renumbered to input indices;
        ``diagnostics["n_coincident_merged"]`` set.

    Warns
    -----
    CoincidentPointsWarning
        Once, with the number of merged points, when any were merged.

    Raises
    ------
    ParambenchError
        Whatever the method or the MethodInput built on the representatives raises;
        TooFewPointsError, before any warning, when fewer than ``MIN_POINTS`` distinct points remain.
    """
    groups = coincident_groups(surface.points)
    if groups.n_merged == 0:
        return run(surface, **params)
    reps = groups.representatives
    if reps.size < MIN_POINTS:
        raise TooFewPointsError(
            f"{surface.name}: {groups.n_merged} of {groups.inverse.size} points coincide with an earlier point "
            f"(within {groups.tolerance:.3g}), leaving {reps.size} distinct point(s); at least {MIN_POINTS} are "
            "needed: pass points that sample the surface.")
    warn_merged(surface.name, groups, "the method ran on the {} distinct points and each copy gets its "
                "representative's uv", stacklevel=4)
    normals = None if surface.normals is None else surface.normals[reps]
    distinct = replace(surface, points=surface.points[reps], faces=None, normals=normals,
                       boundary_loops=_loops_on_representatives(surface.boundary_loops, groups))
    result = run(distinct, **params)
    result.uv = result.uv[groups.inverse]
    if result.faces is not None:
        result.faces = reps[result.faces]
    loops = result.diagnostics.get("boundary_loops")
    if loops is not None:
        result.diagnostics["boundary_loops"] = [reps[np.asarray(loop, dtype=np.int64)].tolist() for loop in loops]
    result.diagnostics["n_coincident_merged"] = groups.n_merged
    return result
