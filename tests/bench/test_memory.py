"""Peak resident memory, whole and per StageTimer stage."""

from __future__ import annotations

import time

import numpy as np

from parambench.bench.memory import PeakMemory, current_rss_mb, high_water_mb
from parambench.methods.base import StageTimer, active_stage


def test_active_stage_follows_nested_stages():
    timer = StageTimer()
    assert active_stage() is None
    with timer("outer"):
        assert active_stage() == "outer"
        with timer("inner"):
            assert active_stage() == "inner"
        assert active_stage() == "outer"
    assert active_stage() is None


def test_memory_is_attributed_to_the_stage_that_allocated_it():
    timer = StageTimer()
    peak = PeakMemory(interval=0.005)
    with peak.measure():
        with timer("small"):
            small = np.ones(1000)
            # Give the sampler a few chances to look while the stage runs.
            for _ in range(20):
                small += 1.0
                time.sleep(0.01)
        with timer("big"):
            big = np.ones(50 * 2**20 // 8)  # 50 MiB, touched
            for _ in range(20):
                big[:: 512] += 1.0
                time.sleep(0.01)
        del big
    assert {"small", "big"} <= set(peak.stage_peak_mb)
    assert peak.stage_peak_mb["big"] >= peak.stage_peak_mb["small"] + 40
    assert peak.peak_mb >= peak.stage_peak_mb["big"]
    assert peak.delta_mb >= 40
    assert current_rss_mb() > 0



def test_a_stage_the_sampler_cannot_see_is_credited_from_the_high_water_mark():
    # A sampler that never wakes stands for one blocked by a compiled call holding the GIL.
    timer = StageTimer()
    peak = PeakMemory(interval=3600.0)
    extra_mb = high_water_mb() - current_rss_mb() + 100.0  # enough to raise the high-water mark
    with peak.measure():
        with timer("burst"):
            block = np.ones(int(extra_mb * 2**20 / 8))
            del block
    assert peak.stage_peak_mb["burst"] >= high_water_mb() - 1.0
    assert peak.peak_mb >= peak.stage_peak_mb["burst"]
