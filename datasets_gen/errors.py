"""Exception hierarchy shared by every parambench package.

Every error a user can provoke with bad input or a failing solver is a subclass of
:class:`ParambenchError`, so scripts can catch the family at once, and the command line
turns any of them into one line on stderr and exit code 2. Messages say what to do.

This module lives in ``datasets_gen`` because that package sits at the root of the data
flow (``Surface`` is defined there); it depends on nothing else in the project.
"""

from __future__ import annotations

import traceback

__all__ = [
    "repairable",
    "REPAIR_ACTION",
    "released",
    "ParambenchError",
    "InputFileError",
    "InvalidInputError",
    "DuplicatePointsError",
    "TooFewPointsError",
    "DegenerateFacesError",
    "TopologyError",
    "NotADiskError",
    "DisconnectedError",
    "NoBoundaryError",
    "InconsistentNormalsError",
    "UnknownNameError",
    "MissingFacesError",
    "SolverError",
    "ConvergenceError",
    "ResourceLimitError",
    "ResultsInUseError",
]


class ParambenchError(ValueError):
    """Base class of every error parambench raises on purpose."""


class InputFileError(ParambenchError):
    """A file is missing, unreadable, or in a format parambench cannot read or write."""


class InvalidInputError(ParambenchError):
    """Arrays of the wrong shape or dtype, NaN or infinite coordinates, indices out of range."""


class DuplicatePointsError(InvalidInputError):
    """Two or more input points coincide (within tolerance)."""


class TooFewPointsError(InvalidInputError):
    """Fewer points than the method or neighbourhood size needs."""


class DegenerateFacesError(InvalidInputError):
    """Faces with repeated vertices or (numerically) zero area."""


class TopologyError(ParambenchError):
    """The surface is not of the topology a method needs."""


class NotADiskError(TopologyError):
    """The mesh is not a single disk-like component (closed, several components, non-manifold)."""


class DisconnectedError(TopologyError):
    """A mesh or a neighbourhood graph has several connected components."""


class NoBoundaryError(TopologyError):
    """No boundary was found: the surface looks closed."""


class InconsistentNormalsError(InvalidInputError):
    """User-supplied normals are not consistently oriented or not usable."""


class UnknownNameError(ParambenchError, KeyError):
    """Unknown method, dataset, suite or parameter name."""

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0]) if self.args else ""


class MissingFacesError(ParambenchError):
    """A mesh method was given a point set without faces."""


class SolverError(ParambenchError):
    """A numerical solve failed or produced an invalid result; the map is not returned."""


class ConvergenceError(SolverError):
    """An iterative solver or search did not converge."""


class ResourceLimitError(ParambenchError):
    """The input is too large for this method's memory or time complexity."""


class ResultsInUseError(ParambenchError):
    """A results folder is locked by another running sweep."""


#: What ``--repair`` does, as the command line offers it, unless an error says otherwise.
REPAIR_ACTION = "keep the largest piece and repair it"


def repairable(exc: ParambenchError, action: str = REPAIR_ACTION) -> ParambenchError:
    """Mark an error that the command line's ``--repair`` removes, so that it can offer it; returns ``exc``.

    :func:`parambench.datasets_gen.repair.repair_surface` removes several pieces,
    unreferenced vertices, non-manifold edges or vertices and duplicate faces (the
    default ``action``); the command line also flips misoriented given normals of a point
    set and drops given normals far off the surface. ``action`` (``exc.repair_action``)
    completes "pass --repair to ...".
    """
    exc.repairable = True
    exc.repair_action = action
    return exc


def released(exc: BaseException) -> BaseException:
    """Drop the local variables of the frames ``exc`` came through; returns ``exc``.

    A method that falls back after a failed solve (another energy, a filled hole, a
    retry) holds the error while the fallback runs, and the error's traceback holds the
    failed solve's frames with every matrix and subspace block they had: at 300k points
    scattered over ``real/lilium``, ``ocp``'s peak grew to 10.3 GB over its fallbacks and
    retries. Where a frame also holds the error itself (passed on to be raised again),
    the cycle outlives the fallback until the cyclic collector runs. The message and the
    traceback's lines are kept; frames still running are left alone
    (:func:`traceback.clear_frames`).
    """
    traceback.clear_frames(exc.__traceback__)
    return exc
