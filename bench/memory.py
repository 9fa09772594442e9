"""Peak resident memory of a block of code, sampled from /proc (Linux).

numpy's tracemalloc hooks miss memory allocated inside compiled libraries (SuperLU,
libigl), so the resident set size is sampled instead; on systems without /proc the
peak is reported as NaN. A sampling thread cannot run while a compiled call holds the
GIL (libigl's solvers do), so the kernel's high-water mark is also read at every stage
boundary. Where Linux lets a process reset that mark (``/proc/self/clear_refs``), it is
reset at every stage boundary, so each stage is credited with its own exact peak even
when an earlier run in the process went higher (``bench_scaling.py`` times ``scp-igl``
once as the baseline and again as a benchmark: at 1M points the second run's solve was
credited 0.69 GB, its samples, under the first run's mark). Elsewhere a stage is
credited with the process's high-water mark (``ru_maxrss``) only when it raised it.
"""

from __future__ import annotations

import os
import resource
import threading
from contextlib import contextmanager
from typing import Iterator

from parambench.methods.base import active_stage, add_stage_hook, remove_stage_hook

__all__ = ["current_rss_mb", "high_water_mb", "reset_high_water", "PeakMemory"]

_PAGE = os.sysconf("SC_PAGE_SIZE") if hasattr(os, "sysconf") else 4096


def high_water_mb() -> float:
    """Peak resident set size of this process since start or the last :func:`reset_high_water`, in MiB.

    ``VmHWM`` of ``/proc/self/status`` (which the reset lowers); ``ru_maxrss`` where
    that file is missing.
    """
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024.0  # kB
    except (OSError, ValueError, IndexError):
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # KiB on Linux


def reset_high_water() -> bool:
    """Lower the high-water mark to the current resident set (Linux >= 4.0); True when done.

    Writing 5 to ``/proc/self/clear_refs`` resets only the mark (no page-table walk), so
    it is cheap enough for every stage boundary.
    """
    try:
        with open("/proc/self/clear_refs", "w") as fh:
            fh.write("5")
        return True
    except OSError:
        return False


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
        Highest RSS (MiB, whole process) seen while each :class:`parambench.methods.base.StageTimer`
        stage was running (see :func:`parambench.methods.base.active_stage`); time outside any
        stage counts as ``"other"``. Sampled every ``interval``, and exact from the
        high-water mark: reset at every stage boundary where Linux allows it, else read
        when the stage ends and credited only if the stage raised it.
    """

    def __init__(self, interval: float = 0.01) -> None:
        self.interval = interval
        self.peak_mb = float("nan")
        self.delta_mb = float("nan")
        self.stage_peak_mb: dict[str, float] = {}

    def _sample(self) -> None:
        self._credit(active_stage() or "other", current_rss_mb())

    def _credit(self, stage: str, value: float) -> None:
        self.peak_mb = max(self.peak_mb, value)
        self.stage_peak_mb[stage] = max(self.stage_peak_mb.get(stage, 0.0), value)

    @contextmanager
    def measure(self) -> Iterator["PeakMemory"]:
        start = current_rss_mb()
        self.peak_mb = start
        self.stage_peak_mb = {}
        stop = threading.Event()
        resettable = reset_high_water()
        running: list[str] = []  # the stages entered and not yet left, outermost first
        marks: list[float] = []
        hwm_start = high_water_mb()

        def credit_running(value: float) -> None:
            # With resets, the mark since the last boundary belongs to every running stage
            # (to "other" between stages).
            for stage in running or ["other"]:
                self._credit(stage, value)

        def hook(event: str, stage: str) -> None:
            if resettable:
                credit_running(high_water_mb())
                if event == "enter":
                    running.append(stage)
                elif running:
                    running.pop()
                reset_high_water()
                return
            if event == "enter":
                marks.append(high_water_mb())
                return
            before, now = marks.pop() if marks else hwm_start, high_water_mb()
            if now > before:
                self._credit(stage, now)

        def sample() -> None:
            while not stop.wait(self.interval):
                self._sample()

        thread = threading.Thread(target=sample, daemon=True)
        add_stage_hook(hook)
        thread.start()
        try:
            yield self
        finally:
            stop.set()
            thread.join()
            remove_stage_hook(hook)
            self._sample()
            if resettable:
                credit_running(high_water_mb())
            elif high_water_mb() > hwm_start:
                self.peak_mb = max(self.peak_mb, high_water_mb())
            self.delta_mb = self.peak_mb - start
