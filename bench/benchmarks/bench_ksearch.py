"""The k line search of Eq. 16 against the one-shot k_opt (``k_search="direct"``), side by side.

``pytest bench --benchmark-only -k ksearch``. Each case times the line search with
pytest-benchmark and, in the same process, the direct solve; ``extra_info`` holds both
k_opt, their relative difference, eigen-solve counts, QC means and the time ratio. The
direct k is the largest generalised eigenvalue with a regular eigenvector; with the
non-symmetric point-set Laplacians there may be none (then the line search's optimum has
positive energy). Such a failure is recorded with its message, not skipped, because it
is part of the comparison.
"""

from __future__ import annotations

import time

import pytest

from parambench.bench.metrics import evaluate
from parambench.bench.run_cell import surface_for
from parambench.bench.suites import get_suite
from parambench.datasets_gen.errors import ParambenchError
from parambench.methods.registry import get_method

QUICK = get_suite("quick")
SIZE = QUICK.sizes[0]
SAMPLING = QUICK.samplings[0]
DATASETS = [d for d in QUICK.datasets if not d.startswith("real/")]
#: (method, fixed parameters): the point-set OCP and the cotangent mesh DNCP (symmetric L).
SEARCHES = [("ocp", {}), ("dncp-opt", {"weights": "cotangent"})]
CASES = [(d, m, p) for d in DATASETS for m, p in SEARCHES]


def _qc(surface, result) -> float:
    return evaluate(surface.points, surface.faces, result.uv, boundary_loops=surface.boundary_loops)["qc_mean"]


@pytest.mark.parametrize("dataset,method_name,params", CASES, ids=[f"{d}-{m}" for d, m, _ in CASES])
def test_line_search_against_direct_k(benchmark, dataset, method_name, params):
    surface = surface_for(dataset, SIZE, SAMPLING, 0.0, 0)
    method = get_method(method_name)
    given = surface.method_input(method.needs_faces)  # no ground truth reaches the method
    benchmark.group = f"ksearch-{method_name}"
    line = benchmark.pedantic(lambda: method(given, k_search="line", **params), rounds=1, iterations=1)
    info = {"k_line": line.diagnostics["k_opt"], "qc_line": _qc(surface, line),
            "eigen_solves_line": line.diagnostics.get("n_eigen_solves"),
            "k_evaluations_line": line.diagnostics.get("n_k_evaluations")}
    start = time.perf_counter()
    try:
        direct = method(given, k_search="direct", **params)
    except ParambenchError as exc:
        info.update(direct_status="failed", direct_error=f"{type(exc).__name__}: {exc}")
    else:
        seconds = time.perf_counter() - start
        info.update(direct_status="ok", k_direct=direct.diagnostics["k_opt"], qc_direct=_qc(surface, direct),
                    k_relative_difference=abs(direct.diagnostics["k_opt"] / info["k_line"] - 1.0),
                    time_ratio_direct_vs_line=seconds / benchmark.stats.stats.min)
    benchmark.extra_info.update(info)
