"""``released``: an error held through a fallback does not keep the failed solve's arrays."""

from __future__ import annotations

import weakref

from parambench.datasets_gen.errors import SolverError, released


class _Big:
    """Stands in for a matrix a failed solve had in its frame."""


def test_released_frees_the_locals_of_the_frames_an_error_came_through():
    refs = []

    def fails():
        big = _Big()
        refs.append(weakref.ref(big))
        raise SolverError("no map (stand-in)")

    try:
        fails()
    except SolverError as exc:
        kept = exc
    assert refs[0]() is not None  # the traceback holds the frame, and the frame its locals
    assert released(kept) is kept
    assert refs[0]() is None
    assert str(kept) == "no map (stand-in)" and kept.__traceback__ is not None


def test_released_leaves_a_running_frame_alone():
    big = _Big()
    ref = weakref.ref(big)
    try:
        raise SolverError("raised here")
    except SolverError as exc:
        released(exc)  # this frame is still running: its locals stay
    assert ref() is big
