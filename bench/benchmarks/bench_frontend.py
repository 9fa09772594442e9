"""The point-set front end: speed at 10k and 100k points, DEM accuracy against potpourri3d.

``pytest bench --benchmark-only -k frontend``. Per-stage seconds (knn, normals, dem,
weights, boundary) go to ``extra_info``; the target is the whole front end on 100k points
in under 10 s on 2 cores, growing linearly with N (fitted exponent <= 1.1 from 10k to
1M: ``PARAMBENCH_FRONTEND_SIZES=10000,100000,1000000``).

The accuracy benchmark samples a spherical cap (radius 1, polar angle 1 rad) by a jittered
golden-angle spiral, where the exact log map is known in closed form, and compares on the
same points (the DEM ball members of 40 centres) our DEM with the vector-heat log map of
``potpourri3d.PointCloudHeatSolver``: RMS error over the ball divided by its radius,
after the best rotation of each method's tangent frame (potpourri3d orients its frames by
its own, unoriented, normal estimates, so a reflection is allowed for it).
"""

from __future__ import annotations

import os
import time

import numpy as np
import pytest

from parambench.methods.pointset.dem import dem_balls
from parambench.methods.pointset.frontend import build_frontend
from parambench.methods.pointset.neighbourhoods import knn_graph, symmetric_adjacency
from parambench.methods.pointset.normals import orient_normals, pca_normals, smooth_normals

SIZES = [int(s) for s in os.environ.get("PARAMBENCH_FRONTEND_SIZES", "10000,100000").split(",") if s.strip()]


def _bump(n_points: int):
    from parambench.datasets_gen.registry import make_surface

    return make_surface("bump", n_points, sampling="jittered", seed=0, noise=0.0)


@pytest.fixture(scope="module", autouse=True)
def _compiled():
    """Compile (or load from cache) the numba kernels outside the timed rounds."""
    g = np.stack(np.meshgrid(np.arange(20.0), np.arange(20.0)), axis=-1).reshape(-1, 2)
    build_frontend(np.c_[g, np.zeros(len(g))])


@pytest.mark.parametrize("n_points", SIZES, ids=[f"{n // 1000}k" for n in SIZES])
def test_frontend_speed(benchmark, n_points):
    surface = _bump(n_points)
    benchmark.group = "frontend"
    result = benchmark.pedantic(build_frontend, args=(surface.points,), rounds=3 if n_points <= 10_000 else 1,
                                iterations=1)
    diag = result.diagnostics
    benchmark.extra_info.update({
        "n_points": surface.n_points,
        "stage_timings": {k: round(v, 4) for k, v in result.timings.items()},
        "seconds_per_100k_points": benchmark.stats.stats.min * 1e5 / surface.n_points,
        "ball_size": diag["ball_size"],
        "n_boundary_loops": len(result.boundary_loops),
        "reconstruction_error_rel_l2": diag["reconstruction_error"],
        "negative_weight_fraction": diag["negative_weights"]["negative_fraction"],
    })


def _spherical_cap(n_points: int, cap_angle: float = 1.0, seed: int = 0):
    """Golden-angle spiral on a unit-sphere cap, jittered by 0.3 spacings; returns points
    (= exact normals)."""
    rng = np.random.default_rng(seed)
    i = np.arange(n_points) + 0.5
    cos_polar = 1.0 - (1.0 - np.cos(cap_angle)) * i / n_points  # area-uniform rings
    polar = np.arccos(cos_polar)
    azim = np.pi * (3.0 - np.sqrt(5.0)) * i
    h = np.sqrt(2 * np.pi * (1 - np.cos(cap_angle)) / n_points)
    polar = np.clip(polar + rng.uniform(-0.3, 0.3, n_points) * h, 0.0, cap_angle)
    azim = azim + rng.uniform(-0.3, 0.3, n_points) * h / np.maximum(np.sin(polar), h)
    return np.c_[np.sin(polar) * np.cos(azim), np.sin(polar) * np.sin(azim), np.cos(polar)]


def _exact_log(points, c, members):
    s = points[c]
    q = points[members]
    cosang = np.clip(q @ s, -1.0, 1.0)
    tangent = q - cosang[:, None] * s
    norm = np.linalg.norm(tangent, axis=1, keepdims=True)
    log3 = np.arccos(cosang)[:, None] * tangent / np.where(norm > 0, norm, 1.0)
    a1 = np.cross(s, [0.3, 0.1, 0.9])
    a1 /= np.linalg.norm(a1)
    return np.c_[log3 @ a1, log3 @ np.cross(s, a1)]


def _fit_error(ours, exact, allow_reflection):
    best = np.inf
    for refl in (1.0, -1.0) if allow_reflection else (1.0,):
        u, _, vt = np.linalg.svd(ours.T @ exact)
        rot = u @ np.diag([1.0, refl * np.sign(np.linalg.det(u @ vt))]) @ vt
        rms = np.sqrt(np.mean(np.sum((ours @ rot - exact) ** 2, axis=1)))
        best = min(best, rms / np.linalg.norm(exact, axis=1).max())
    return best


@pytest.mark.parametrize("eps_factor", [2.5, 10.0], ids=["ball-2.5l", "ball-10l"])
def test_dem_accuracy_vs_potpourri3d(benchmark, eps_factor):
    import potpourri3d as pp3d

    points = _spherical_cap(10_000)
    graph = knn_graph(points, 8)
    adj = symmetric_adjacency(graph)
    normals = orient_normals(points, pca_normals(points, graph.indices), graph.indices)
    normals = smooth_normals(points, normals, graph.indices, graph.distances, graph.mean_spacing)
    centres = np.random.default_rng(1).choice(len(points), 40, replace=False)

    def ours():
        return dem_balls(points, normals, adj, graph.mean_spacing, ball_eps_factor=eps_factor, max_ball=2048,
                         centres=centres)

    benchmark.group = "dem-accuracy"
    balls = benchmark.pedantic(ours, rounds=3, iterations=1)
    start = time.perf_counter()
    solver = pp3d.PointCloudHeatSolver(points)
    pp3d_setup = time.perf_counter() - start
    err_ours, err_pp3d = [], []
    start = time.perf_counter()
    for row, c in enumerate(centres):
        members = balls.indices[row][balls.indices[row] >= 0]
        exact = _exact_log(points, c, members)
        err_ours.append(_fit_error(balls.coords[row][: members.size], exact, allow_reflection=False))
        err_pp3d.append(_fit_error(solver.compute_log_map(int(c))[members], exact, allow_reflection=True))
    pp3d_seconds = (time.perf_counter() - start) / len(centres)
    benchmark.extra_info.update({
        "n_points": len(points),
        "ball_eps_factor": eps_factor,
        "mean_ball_size": float(balls.sizes.mean()),
        "dem_rel_rms_error": float(np.mean(err_ours)),
        "potpourri3d_rel_rms_error": float(np.mean(err_pp3d)),
        "dem_seconds_per_centre": benchmark.stats.stats.min / len(centres),
        "potpourri3d_setup_seconds": pp3d_setup,
        "potpourri3d_seconds_per_centre": pp3d_seconds,
    })
