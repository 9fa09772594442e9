"""Error hints that name only parameters of the method that is running.

Shared numerics (the k search, eigen-solvers, mesh weights) run under several methods,
so they cannot know which parameters the user can change: ``ocp`` has no ``normalized``,
no method has ``backend``, and suggesting ``k_search='direct'`` to a run that used it
sends the user in a circle. Such a site raises with :func:`hinted`, listing every remedy
as a :class:`Hint`; :func:`method_hints`, around a method's run, keeps only the hints
whose parameter the method has and whose suggested value differs from the one in use.
"""

from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, Iterator, Mapping

from parambench.datasets_gen.errors import ParambenchError

__all__ = ["Hint", "hinted", "fit_hints", "error_note", "method_hints"]

_ANY = object()

#: Said when every hint named a parameter the running method does not have.
FALLBACK = "try another method ('parambench list')"


@dataclass(frozen=True)
class Hint:
    """One remedy an error message offers.

    Attributes
    ----------
    text : str
        The remedy as written, e.g. ``"use k_search='direct'"``.
    param : str or None
        The method parameter it changes; None when it names none (e.g. "repair the mesh").
    value : object
        The value it suggests; the hint is dropped when the method already runs with it.
        Omit for "another value" (e.g. "a larger reg_eps").
    direction : {0, 1, -1}
        With ``value``: 1 for "raise it (e.g. to ``value``)", dropped when the method
        already runs with ``value`` or more; -1 for "lower it", dropped at ``value`` or
        less; 0 (default): dropped only at ``value`` itself.
    """

    text: str
    param: str | None = None
    value: Any = _ANY
    direction: int = 0

    def applies(self, defaults: Mapping[str, Any], params: Mapping[str, Any]) -> bool:
        """True when the method has ``param`` and does not already use ``value`` (or, with a
        ``direction``, a value at least as far that way)."""
        if self.param is None:
            return True
        if self.param not in defaults:
            return False
        if self.value is _ANY:
            return True
        current = params.get(self.param, defaults[self.param])
        if self.direction:
            try:
                return bool((current - self.value) * self.direction < 0)
            except TypeError:  # not a number (None: the method's own choice)
                return True
        return current != self.value


def _render(stem: str, hints: tuple[Hint, ...]) -> str:
    # One hint per parameter (the first): errors restated upstream ("the detected boundary
    # looks wrong") add their own hints before the solver's, which may name it again.
    kept, named = [], set()
    for hint in hints:
        if hint.param is not None:
            if hint.param in named:
                continue
            named.add(hint.param)
        kept.append(hint)
    if not kept:
        return f"{stem}."
    return f"{stem}; {', or '.join(h.text for h in kept)}."


def hinted(error_cls: type[ParambenchError], stem: str, *hints: Hint) -> ParambenchError:
    """An error whose message is ``stem`` followed by every hint (fitted later by :func:`fit_hints`).

    Parameters
    ----------
    error_cls : type
        A :class:`ParambenchError` subclass.
    stem : str
        What went wrong, without a final full stop.
    *hints : Hint
        Remedies, most useful first.

    Returns
    -------
    ParambenchError
        To be raised by the caller (``raise hinted(...) from None``). A hint given twice
        (a restated error adds remedies its cause may already offer) is said once, where
        it first appears.
    """
    hints = tuple(dict.fromkeys(hints))
    exc = error_cls(_render(stem, hints))
    exc.parambench_hints = (stem, hints)
    return exc


def fit_hints(exc: BaseException, defaults: Mapping[str, Any], params: Mapping[str, Any]) -> None:
    """Rewrite the message of an error from :func:`hinted` for one method, in place.

    Hints naming a parameter the method lacks, or the value it already uses, are
    dropped; when none is left, :data:`FALLBACK` is said instead. Errors raised
    without hints are left alone.

    Parameters
    ----------
    exc : BaseException
    defaults : mapping
        The method's ``defaults`` (its parameter names).
    params : mapping
        The parameters it ran with.
    """
    stem, hints = getattr(exc, "parambench_hints", (None, ()))
    if stem is None:
        return
    kept = tuple(h for h in hints if h.applies(defaults, params)) or (Hint(FALLBACK),)
    exc.args = (_render(stem, kept),)
    exc.parambench_hints = (stem, kept)


def error_note(exc: BaseException, defaults: Mapping[str, Any] | None = None,
               params: Mapping[str, Any] | None = None) -> str:
    """``"ErrorClass: message"`` of an error a method recovered from, for its diagnostics.

    The message's hints are fitted to the method first (:func:`fit_hints`, in place), so
    a diagnostic never suggests a parameter the method does not have; without
    ``defaults`` (shared numerics, which do not know the method) they are left out.

    Parameters
    ----------
    exc : BaseException
    defaults, params : mapping, optional
        As for :func:`fit_hints`.

    Returns
    -------
    str
    """
    if defaults is None:
        stem, hints = getattr(exc, "parambench_hints", (None, ()))
        return f"{type(exc).__name__}: {exc if stem is None else _render(stem, ())}"
    fit_hints(exc, defaults, params or {})
    return f"{type(exc).__name__}: {exc}"


@contextmanager
def method_hints(defaults: Mapping[str, Any], params: Mapping[str, Any]) -> Iterator[None]:
    """Fit the hints of any :class:`ParambenchError` raised inside to one method's parameters.

    Examples
    --------
    >>> from parambench.datasets_gen.errors import SolverError
    >>> try:
    ...     with method_hints({"k_search": "line"}, {"k_search": "direct"}):
    ...         raise hinted(SolverError, "no k found", Hint("use k_search='direct'", "k_search", "direct"),
    ...                      Hint("use normalized=False", "normalized", False))
    ... except SolverError as exc:
    ...     print(exc)
    no k found; try another method ('parambench list').
    """
    try:
        yield
    except ParambenchError as exc:
        fit_hints(exc, defaults, params)
        raise
