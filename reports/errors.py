"""Errors the report builder raises on purpose."""

from __future__ import annotations

from parambench.datasets_gen.errors import ParambenchError

__all__ = ["EmptyResultsError"]


class EmptyResultsError(ParambenchError):
    """The results directory is missing or holds no finished cell: there is nothing to report."""
