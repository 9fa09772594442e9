"""Peak resident memory of a block of code, sampled from /proc (Linux).

numpy's tracemalloc hooks miss memory allocated inside compiled libraries (SuperLU,
libigl), so the resident set size is sampled instead; on systems without /proc the
peak is reported as NaN.
"""

from __future__ import annotations

import os
import threading
from contextlib import contextmanager
from typing import Iterator

from methods.base import active_stage

__all__ = ["current_rss_mb", "PeakMemory"]

_PAGE = os.sysconf("SC_PAGE_SIZE") if hasattr(os, "sysconf") else 4096


def current_rss_mb() -> float:
    """Resident set size of this process in MiB (NaN where /proc is missing)."""
    try:
        with open("/proc/self/statm") as fh:
            return int(fh.read().split()[1]) * _PAGE / 2**20
    except OSError:
        return float("nan")


class PeakMemory:
    """Samples RSS every ``interval`` seconds in a thread while the block runs.

    Attributes
    ----------
    peak_mb : float
        Highest RSS seen during the block, in MiB.
    delta_mb : float
        ``peak_mb`` minus the RSS when the block started: what the block added.
    stage_peak_mb : dict of str to float
        Highest RSS (MiB, whole process) seen while each :class:`methods.base.StageTimer`
        stage was running (see :func:`methods.base.active_stage`); time outside any
        stage counts as ``"other"``. Stages shorter than ``interval`` may be missed.
    """

    def __init__(self, interval: float = 0.01) -> None:
        self.interval = interval
        self.peak_mb = float("nan")
        self.delta_mb = float("nan")
        self.stage_peak_mb: dict[str, float] = {}

    def _sample(self) -> None:
        rss = current_rss_mb()
        stage = active_stage() or "other"
        self.peak_mb = max(self.peak_mb, rss)
        self.stage_peak_mb[stage] = max(self.stage_peak_mb.get(stage, 0.0), rss)

    @contextmanager
    def measure(self) -> Iterator["PeakMemory"]:
        start = current_rss_mb()
        self.peak_mb = start
        self.stage_peak_mb = {}
        stop = threading.Event()

        def sample() -> None:
            while not stop.wait(self.interval):
                self._sample()

        thread = threading.Thread(target=sample, daemon=True)
        thread.start()
        try:
            yield self
        finally:
            stop.set()
            thread.join()
            self._sample()
            self.delta_mb = self.peak_mb - start
