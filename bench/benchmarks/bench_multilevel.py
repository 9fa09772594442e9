"""Accuracy of ``ocp``'s two-level solve against its direct solve (issue #14, item 2).

``pytest bench/benchmarks/bench_multilevel.py --benchmark-only --benchmark-json=ml.json``.
Without ``--benchmark-only`` every case is skipped. Cases: every generated surface
(jittered) at the sizes of ``PARAMBENCH_MULTILEVEL_SIZES`` (comma-separated, default
``100000``; add 1000000 for the issue's full set: about 6 min per surface on 2 cores,
most of it the direct solve) and the real meshes as bare points, which are below
``solver="auto"``'s threshold, so the two-level path is forced there.

Timed (one round): ``ocp`` with ``solver="multilevel"``; ``solver="direct"`` runs on the
same points in the same process. In ``extra_info``: ``k_rel_diff`` (|k_ml - k_direct| /
k_direct), ``qc_rel_diff`` (QC mean on the ground-truth mesh, relative), both maps'
foldovers on the mesh, ``uv_rms_over_diameter`` (RMS distance of the two maps after a
similarity alignment, over the surface's diameter), both self-check verdicts,
``time_ratio_vs_direct``, the two-grid cycles, whether the fine map was polished because
its k search did not settle (``polish_unsettled``), and ``meets_target``: the issue's
thresholds (k to 1e-3, QC to 0.2 %, uv to 1e-3 of the diameter, 0 foldovers) all met.
An error on either path is recorded (``direct_error``, ``multilevel_error``), not raised.
"""

from __future__ import annotations

import os
import time

import numpy as np
import pytest

from parambench.bench.metrics import evaluate, similarity_align
from parambench.datasets_gen.errors import ParambenchError
from parambench.datasets_gen.registry import dataset_names, make_surface
from parambench.methods.registry import get_method

SIZES = [int(s) for s in os.environ.get("PARAMBENCH_MULTILEVEL_SIZES", "100000").split(",") if s.strip()]
REAL = [name for name in dataset_names() if name.startswith("real/")]
GENERATED = [name for name in dataset_names() if not name.startswith("real/")]
CASES = [(name, n) for n in SIZES for name in GENERATED] + [(name, 0) for name in REAL]

#: Issue #14's accuracy thresholds.
TARGET = {"k_rel_diff": 1e-3, "qc_rel_diff": 2e-3, "uv_rms_over_diameter": 1e-3}


@pytest.fixture(autouse=True)
def _benchmark_only(request):
    """Minutes of work per case at 100k points: run only when benchmarks are asked for."""
    if not request.config.getoption("benchmark_only", False):
        pytest.skip("multilevel accuracy benchmark: run it with --benchmark-only")


def _run(given, solver):
    try:
        start = time.perf_counter()
        result = get_method("ocp")(given, solver=solver)
        return result, time.perf_counter() - start, None
    except ParambenchError as exc:
        return None, None, f"{type(exc).__name__}: {exc}"


def _quality(surface, uv) -> dict:
    metrics = evaluate(surface.points, surface.faces, uv, boundary_loops=surface.boundary_loops,
                       diameter=surface.diameter)
    return {"qc_mean": float(metrics["qc_mean"]), "foldovers": int(metrics["foldovers"])}


def compare(surface, direct, multilevel) -> dict:
    """The accuracy figures of ``multilevel`` against ``direct`` (Parameterizations on ``surface``)."""
    qd, qm = _quality(surface, direct.uv), _quality(surface, multilevel.uv)
    kd, km = float(direct.diagnostics["k_opt"]), float(multilevel.diagnostics["k_opt"])
    aligned = similarity_align(multilevel.uv, direct.uv)
    rms = float(np.sqrt(np.mean(np.sum((aligned - direct.uv) ** 2, axis=1))) / surface.diameter)
    out = {"k_rel_diff": abs(km - kd) / abs(kd), "qc_rel_diff": abs(qm["qc_mean"] / qd["qc_mean"] - 1.0),
           "uv_rms_over_diameter": rms, "direct_foldovers": qd["foldovers"], "multilevel_foldovers": qm["foldovers"],
           "direct_qc_mean": qd["qc_mean"], "multilevel_qc_mean": qm["qc_mean"],
           "direct_selfcheck": bool(direct.diagnostics["selfcheck"]["passed"]),
           "multilevel_selfcheck": bool(multilevel.diagnostics["selfcheck"]["passed"])}
    out["meets_target"] = bool(all(out[key] <= limit for key, limit in TARGET.items())
                               and out["multilevel_foldovers"] == 0)
    return out


@pytest.mark.parametrize("dataset,size", CASES, ids=[f"{d.replace('/', '-')}-{n // 1000}k" if n else d.replace("/", "-")
                                                     for d, n in CASES])
def test_multilevel_matches_direct(benchmark, dataset, size):
    surface = make_surface(dataset, seed=0) if not size else make_surface(dataset, size, sampling="jittered", seed=0)
    benchmark.group = f"multilevel-{size // 1000}k" if size else "multilevel-real"
    given = surface.method_input(False)
    direct, direct_seconds, direct_error = _run(given, "direct")
    holder = {}
    benchmark.pedantic(lambda: holder.update(zip(("result", "seconds", "error"), _run(given, "multilevel"))),
                       rounds=1, iterations=1)
    multilevel = holder["result"]
    info = {"dataset": dataset, "n_points": surface.n_points, "direct_error": direct_error,
            "multilevel_error": holder["error"], "direct_seconds": direct_seconds,
            "multilevel_seconds": holder["seconds"]}
    if direct is not None and multilevel is not None:
        info.update(compare(surface, direct, multilevel))
        info.update(time_ratio_vs_direct=holder["seconds"] / direct_seconds,
                    twogrid_cycles=multilevel.diagnostics.get("twogrid_cycles"),
                    twogrid_fell_back=multilevel.diagnostics.get("twogrid_fell_back"),
                    coarse_points=multilevel.diagnostics.get("coarse_points"),
                    map_scale_spread=multilevel.diagnostics.get("map_scale_spread"),
                    full_space_steps=multilevel.diagnostics.get("full_space_steps", 0),
                    polish_unsettled=bool(multilevel.diagnostics.get("polish_unsettled", False)))
    benchmark.extra_info.update(info)
