"""Helpers shared by the benchmark modules: in-process baselines and skipping refused inputs."""

from __future__ import annotations

import time

import pytest

from parambench.datasets_gen.errors import ParambenchError


def best_of(fn, repeat: int = 3) -> float:
    """Smallest wall-clock seconds of ``repeat`` calls: the in-process baseline for ratios."""
    best = float("inf")
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - start)
    return best


def run_or_skip(fn):
    """Call ``fn``; a ParambenchError (method refuses this input) skips the benchmark with its message."""
    try:
        return fn()
    except ParambenchError as exc:
        pytest.skip(f"{type(exc).__name__}: {exc}")
