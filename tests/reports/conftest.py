"""A writer of synthetic results directories in the sweep's storage format.

The report must work from stored results alone, so its tests build them here instead of
running methods: small grid meshes of a bump and a saddle, uv maps with a known amount of
shear (and one deliberate foldover), per-face QC computed from those maps, timings that
follow known power laws, an OCP landscape with turning-number steps, weight samples and a
detected boundary, one failed cell, and a pytest-benchmark JSON file.
"""

from __future__ import annotations

import json
import os
import shutil
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from parambench.bench.schema import dataset_key, encode_loops

#: Time exponents the synthetic timings follow, per method.
TIME_EXPONENTS = {"lscm": 1.1, "scp": 1.3, "ocp": 1.5}
FAIL_ERROR = ("ConvergenceError",
              "OCP line search did not reach turning number 1 after 40 steps; raise k_max or the neighbourhood size.")


@dataclass
class Spec:
    """What to write."""

    datasets: dict = field(default_factory=lambda: {"bump": [144, 400], "saddle": [144]})
    methods: tuple = ("lscm", "scp", "ocp")
    seeds: tuple = (0, 1)
    failed: tuple = (("ocp", "saddle", 1),)  # (method, dataset, seed) cells that fail
    fail_all: bool = False
    parquet: bool = True
    run_json: bool = True


def grid_mesh(n: int, dataset: str):
    """An n x n grid over [-1, 1]^2 lifted to a bump or a saddle; faces CCW seen from +z."""
    t = np.linspace(-1.0, 1.0, n)
    x, y = np.meshgrid(t, t, indexing="xy")
    x, y = x.ravel(), y.ravel()
    z = 0.4 * np.exp(-(x**2 + y**2) / 0.3) if dataset == "bump" else 0.25 * (x**2 - y**2)
    points = np.column_stack([x, y, z])
    i, j = np.meshgrid(np.arange(n - 1), np.arange(n - 1), indexing="xy")
    a = (j * n + i).ravel()
    faces = np.concatenate([np.column_stack([a, a + 1, a + n + 1]), np.column_stack([a, a + n + 1, a + n])])
    bottom = np.arange(n)
    right = np.arange(1, n) * n + n - 1
    top = (n - 1) * n + np.arange(n - 2, -1, -1)
    left = np.arange(n - 2, 0, -1) * n
    loop = np.concatenate([bottom, right, top, left])  # CCW
    return points, faces.astype(np.int64), loop


def per_face_qc(points, faces, uv):
    """Ratio of singular values of each triangle's affine map from 3D to uv."""
    p0, p1, p2 = (points[faces[:, k]] for k in range(3))
    e1, e2 = p1 - p0, p2 - p0
    len1 = np.linalg.norm(e1, axis=1)
    ex = e1 / len1[:, None]
    normal = np.cross(e1, e2)
    ey = np.cross(normal / np.linalg.norm(normal, axis=1)[:, None], ex)
    q = np.stack([np.column_stack([len1, np.zeros_like(len1)]),
                  np.column_stack([np.einsum("ij,ij->i", e2, ex), np.einsum("ij,ij->i", e2, ey)])], axis=2)
    du = np.stack([uv[faces[:, 1]] - uv[faces[:, 0]], uv[faces[:, 2]] - uv[faces[:, 0]]], axis=2)
    jac = du @ np.linalg.inv(q)
    s = np.linalg.svd(jac, compute_uv=False)
    return s[:, 0] / np.maximum(s[:, 1], 1e-300)


def flipped_mask(faces, uv):
    e1 = uv[faces[:, 1]] - uv[faces[:, 0]]
    e2 = uv[faces[:, 2]] - uv[faces[:, 0]]
    signed = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    majority = 1.0 if np.count_nonzero(signed > 0) >= np.count_nonzero(signed < 0) else -1.0
    return signed * majority < 0


def method_uv(method: str, points: np.ndarray, n: int, seed: int) -> np.ndarray:
    xy = points[:, :2].copy()
    if method == "lscm":
        uv = xy * np.array([1.0, 1.0]) + 0.15 * points[:, 2:3]
    elif method == "scp":
        uv = xy * np.array([1.0, 1.1])
    else:  # ocp: rotated, a little sheared, and one interior vertex dragged across its neighbours
        angle = 0.3
        rot = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
        uv = (xy @ rot.T) * np.array([1.0, 1.25])
        centre = (n // 2) * n + n // 2
        step = 2.0 / (n - 1)
        uv[centre] += np.array([2.5 * step, 0.3 * step])
    rng = np.random.default_rng(seed)
    return uv + rng.normal(scale=1e-4, size=uv.shape)


def loops_arrays(prefix: str, loops) -> dict:
    return encode_loops(prefix, loops)


def landscape(k_opt: float):
    k = np.geomspace(0.2, 5.0, 40) * k_opt
    t = np.where(k >= k_opt, 1.0, np.ceil(k_opt / k))
    energy = (k / k_opt - 1.0) ** 2 + 0.01 + 0.3 * (t - 1)
    return k, energy, t


def write_benchmark_json(path: Path) -> Path:
    """A pytest-benchmark file with three benchmarks in two groups."""
    benches = []
    for group, name, median in (("weights", "test_wtan_2k", 0.012), ("weights", "test_wcot_2k", 0.004),
                                ("solve", "test_ocp_2k", 0.35)):
        benches.append({
            "group": group, "name": name, "fullname": f"bench/test_x.py::{name}", "params": None,
            "param": None, "extra_info": {"n_points": 2000},
            "options": {"disable_gc": False, "timer": "perf_counter", "min_rounds": 5, "max_time": 1.0,
                        "min_time": 5e-06, "warmup": False},
            "stats": {"min": median * 0.9, "max": median * 1.4, "mean": median * 1.05, "stddev": median * 0.1,
                      "rounds": 7, "median": median, "iqr": median * 0.1, "q1": median * 0.95,
                      "q3": median * 1.05, "iqr_outliers": 0, "stddev_outliers": 1, "outliers": "1;0",
                      "ld15iqr": median * 0.9, "hd15iqr": median * 1.4, "ops": 1.0 / median,
                      "total": median * 7, "iterations": 1},
        })
    data = {"machine_info": {"node": "test", "python_version": "3.11"}, "commit_info": {"id": "abc"},
            "benchmarks": benches, "datetime": "2024-05-01T12:00:00", "version": "4.0.0"}
    path.write_text(json.dumps(data, indent=1))
    return path


def write_results(root: Path, spec: Spec | None = None) -> list[dict]:
    """Write a results directory in the storage contract's format; returns the rows."""
    spec = spec or Spec()
    cells = root / "cells"
    datasets_dir = root / "datasets"
    cells.mkdir(parents=True, exist_ok=True)
    datasets_dir.mkdir(parents=True, exist_ok=True)
    rows = []
    for dataset, sizes in spec.datasets.items():
        for size in sizes:
            n = int(round(np.sqrt(size)))
            points, faces, loop = grid_mesh(n, dataset)
            boundary = np.zeros(len(points), dtype=bool)
            boundary[loop] = True
            for seed in spec.seeds:
                rng = np.random.default_rng(seed)
                det_mask = boundary.copy()
                det_mask[rng.choice(loop, size=2, replace=False)] = False  # two misses
                det_mask[(n // 2) * n + 1] = True  # one false alarm
                det_loop = loop[det_mask[loop]]
                np.savez_compressed(
                    datasets_dir / f"{dataset_key(dataset, size, 'poisson', 0.0, seed)}.npz",
                    w_tan_interior=rng.normal(0.17, 0.05, 3000), w_tan_boundary=rng.normal(0.25, 0.2, 400),
                    w_cot_interior=rng.normal(0.5, 0.25, 3000), w_cot_boundary=rng.normal(0.3, 0.3, 400),
                    points=points.astype(np.float32), det_boundary_mask=det_mask,
                    **loops_arrays("gt", [loop]), **loops_arrays("det", [det_loop]))
                for method in spec.methods:
                    cell_id = f"{dataset}-{size}-poisson-s{seed}-{method}-{zlib.crc32(f'{dataset}{size}{seed}{method}'.encode()):010d}"
                    row = {"cell_id": cell_id, "dataset": dataset, "size": size, "sampling": "poisson",
                           "noise": 0.0, "seed": seed, "method": method,
                           "params": json.dumps({"k": 12} if method == "ocp" else {}), "n_points": len(points),
                           "n_faces": len(faces), "artifact": "", "k_opt": None, "peak_memory_mb": 12.5}
                    metric_keys = ("qc_mean", "qc_p95", "qc_max", "foldovers", "foldover_fraction", "collapsed",
                                   "area_distortion", "exact_error", "n_eval_faces", "time_total")
                    if spec.fail_all or (method, dataset, seed) in spec.failed:
                        row.update({k: None for k in metric_keys}, status="failed",
                                   error_type=FAIL_ERROR[0], error=FAIL_ERROR[1], turning_numbers="[]",
                                   eval_mesh="", timings="{}", diagnostics="{}")
                    else:
                        uv = method_uv(method, points, n, seed)
                        qc = per_face_qc(points, faces, uv)
                        flipped = flipped_mask(faces, uv)
                        time_total = 2e-6 * len(points) ** TIME_EXPONENTS[method] * (1.0 + 0.02 * seed)
                        row.update(status="ok", error_type="", error="", qc_mean=float(qc.mean()),
                                   qc_p95=float(np.quantile(qc, 0.95)), qc_max=float(qc.max()),
                                   foldovers=int(flipped.sum()), foldover_fraction=float(flipped.mean()),
                                   collapsed=False, area_distortion=float(1.0 + 0.1 * qc.std()),
                                   turning_numbers=json.dumps([1.0]),
                                   exact_error=0.01 * (1 + seed) if dataset == "bump" else None,
                                   n_eval_faces=len(faces),
                                   eval_mesh="uv-delaunay" if method == "ocp" else "ground-truth",
                                   time_total=time_total,
                                   timings=json.dumps({"solve": 0.8 * time_total, "total": time_total}),
                                   diagnostics=json.dumps({"iterations": 12}))
                        arrays = {"points": points.astype(np.float32), "faces": faces.astype(np.int32), "uv": uv,
                                  "qc": qc, "flipped": flipped, **loops_arrays("gt", [loop])}
                        if method == "ocp":
                            k_opt = 3.2 + 0.1 * seed
                            row["k_opt"] = k_opt
                            k, energy, t = landscape(k_opt)
                            arrays.update(landscape_k=k, landscape_E=energy, landscape_t=t,
                                          **loops_arrays("det", [det_loop]))
                        np.savez_compressed(cells / f"{cell_id}.npz", **arrays)
                        row["artifact"] = f"cells/{cell_id}.npz"
                    (cells / f"{cell_id}.json").write_text(json.dumps(row, sort_keys=True))
                    rows.append(row)
    if spec.parquet:
        pd.DataFrame(rows).to_parquet(root / "results.parquet", index=False)
        pd.DataFrame(rows).to_csv(root / "results.csv", index=False)
    if spec.run_json:
        meta = {"package_version": "0.1.0", "git_commit": "0123456789abcdef0123456789abcdef01234567",
                "machine": {"hostname": "testhost", "platform": "Linux-6.1-x86_64", "python": "3.11.2",
                            "cpu_count": 2, "memory_gb": 24.0},
                "date": "2024-05-01T12:00:00+00:00", "command": "parambench run --suite quick",
                "suite": "quick", "parameters": {"sizes": [144, 400], "noise": [0.0]}, "seeds": list(spec.seeds)}
        (root / "run.json").write_text(json.dumps(meta, indent=2))
    return rows


def _artifacts_dir() -> Path:
    default = Path(__file__).resolve().parents[2] / "test-artifacts"
    path = Path(os.environ.get("PARAMBENCH_TEST_ARTIFACTS", default)) / "reports"
    path.mkdir(parents=True, exist_ok=True)
    return path


def _require_tool(name: str) -> str:
    path = shutil.which(name)
    if path is None:
        message = (f"{name} is not installed; install it with `apt-get install -y chromium chromium-driver "
                   f"poppler-utils`.")
        if os.environ.get("CI"):
            pytest.fail(message)
        pytest.skip(message)
    return path


# The test modules are imported in importlib mode, so helpers reach them as fixtures.

@pytest.fixture(scope="session")
def artifacts_dir() -> Path:
    """Where tests leave screenshots and rendered pages (PARAMBENCH_TEST_ARTIFACTS, gitignored)."""
    return _artifacts_dir()


@pytest.fixture(scope="session")
def require_tool():
    """``require_tool(name)`` -> path of an executable; fails under CI (it must be there), skips elsewhere."""
    return _require_tool


@pytest.fixture(scope="session")
def make_results():
    """``make_results(root, spec=None)`` writes a synthetic results directory and returns its rows."""
    return write_results


@pytest.fixture(scope="session")
def spec_type():
    """The :class:`Spec` class, to describe partial result sets."""
    return Spec


@pytest.fixture(scope="session")
def mesh_tools():
    """Helpers that build the synthetic meshes and maps."""
    return {"grid_mesh": grid_mesh, "per_face_qc": per_face_qc, "flipped_mask": flipped_mask,
            "loops_arrays": loops_arrays, "landscape": landscape, "method_uv": method_uv,
            "write_benchmark_json": write_benchmark_json, "fail_error": FAIL_ERROR,
            "time_exponents": TIME_EXPONENTS}


@pytest.fixture
def results_dir(tmp_path) -> Path:
    """The default synthetic results: bump at two sizes, saddle, three methods, two seeds, one failure."""
    root = tmp_path / "results"
    write_results(root)
    return root


@pytest.fixture(scope="session")
def built_report(tmp_path_factory):
    """The default results with their HTML and PDF report (and a benchmark file), built once per session."""
    from parambench.reports.build import build_report

    root = tmp_path_factory.mktemp("built") / "results"
    rows = write_results(root)
    bench = write_benchmark_json(root.parent / "bench.json")
    paths = build_report(root, benchmark_json=[bench])
    return {"root": root, "rows": rows, "paths": paths, "bench": bench}
