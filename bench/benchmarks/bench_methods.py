"""Every registered method on every dataset of the quick suite.

Timing comes from pytest-benchmark; quality metrics and the time ratio against
``scp-igl`` on the same surface, measured in the same process, go to ``extra_info``.
"""

from __future__ import annotations

import pytest

from parambench.bench.metrics import evaluate
from parambench.bench.run_cell import surface_for
from parambench.bench.suites import get_suite
from parambench.methods.registry import all_methods, get_method

from parambench.bench.benchmarks.timing import best_of, run_or_skip

QUICK = get_suite("quick")
SIZE = QUICK.sizes[0]
SAMPLING = QUICK.samplings[0]
CASES = [(d, m) for d in QUICK.datasets for m in all_methods()]
BASELINE = "scp-igl"


def _surface(dataset: str):
    size = 0 if dataset.startswith("real/") else SIZE
    sampling = "" if dataset.startswith("real/") else SAMPLING
    return surface_for(dataset, size, sampling, 0.0, 0)


@pytest.mark.parametrize("dataset,method_name", CASES, ids=[f"{d}-{m}" for d, m in CASES])
def test_method_on_quick_dataset(benchmark, dataset, method_name):
    surface = _surface(dataset)
    method = get_method(method_name)
    given = surface.method_input(method.needs_faces)  # no ground truth reaches the method
    benchmark.group = dataset
    result = run_or_skip(lambda: method(given))
    baseline = get_method(BASELINE)
    base_time = best_of(lambda: baseline(surface))
    result = benchmark.pedantic(lambda: method(given), rounds=3, iterations=1)
    metrics = evaluate(surface.points, surface.faces if surface.faces is not None else result.faces,
                       result.uv, exact_uv=surface.exact_uv, boundary_loops=surface.boundary_loops,
                       diameter=surface.diameter) if (surface.faces is not None or result.faces is not None) else {}
    benchmark.extra_info.update({k: metrics[k] for k in ("qc_mean", "qc_p95", "foldovers", "exact_error")
                                 if k in metrics})
    benchmark.extra_info["n_points"] = surface.n_points
    benchmark.extra_info[f"time_ratio_vs_{BASELINE}"] = benchmark.stats.stats.min / base_time
    benchmark.extra_info["stage_timings"] = result.timings
