"""The dense boundary path's Schur complement: one whole-matrix LU against one solve per kept vertex.

``pytest bench --benchmark-only -k reduction``. Each case times
:class:`~parambench.methods.spectral.reduction.BoundaryReduction` with S from the trailing
block of one LU (the default up to ``TRAILING_SCHUR_MAX`` kept vertices) and, in the same
process, with ``TRAILING_SCHUR_MAX = 0`` (an interior factorisation and one solve per kept
vertex). ``extra_info``: sizes, both times (factorisation and S), their ratio and the
largest difference of the two S over S's largest entry. Cases: cotangent Laplacians of
generated meshes (jittered) and pymeshlab's bunny cut open by a plane.

``-k subspace_products``: ``ocp`` end to end on bare points, where its boundary is too long
for the dense path, with the subspace search's Schur products from that one LU (the
default while K is at most ``TRAILING_PRODUCTS_PER_SEPARATOR`` times the interior ordering's
root separator) against interior solves
(``TRAILING_PRODUCTS_MAX = 0``), min of 3 each, alternating, in one process;
``extra_info``: both times, their ratio, K and the two maps' largest distance over the
map's diameter. ``holes`` is the case the rule leaves on interior solves (K / s 2.9).
"""

from __future__ import annotations

import time

import numpy as np
import pytest
import scipy.sparse as sp

import parambench.methods.spectral.reduction as reduction
from parambench.datasets_gen.io import load_surface
from parambench.datasets_gen.plane_cut import cut_by_plane
from parambench.datasets_gen.real import pymeshlab_samples_dir
from parambench.datasets_gen.registry import make_surface
from parambench.methods.mesh.weights import laplacian, mesh_weights
from parambench.methods.registry import get_method
from parambench.methods.spectral.ordering import nested_dissection

CASES = [("cap", 5000), ("saddle", 8000), ("bump", 20000), ("bunny-cut", 0)]


def _surface(name: str, size: int):
    if name == "bunny-cut":
        path = pymeshlab_samples_dir() / "bunny.obj"
        if not path.is_file():
            pytest.skip("pymeshlab's sample bunny is not installed")
        return cut_by_plane(load_surface(path), 1, 0.45)
    return make_surface(name, size, sampling="jittered", seed=0)


@pytest.mark.parametrize("name,size", CASES, ids=[f"{n}-{s}" if s else n for n, s in CASES])
def test_schur_complement_from_one_lu(benchmark, monkeypatch, name, size):
    surface = _surface(name, size)
    lap = sp.csr_matrix(laplacian(mesh_weights(surface.points, surface.faces, "cotangent")))
    keep = np.concatenate(surface.boundary_loops)
    interior = np.setdiff1d(np.arange(lap.shape[0]), keep)
    perm = nested_dissection(surface.points[interior], lap[interior][:, interior])
    benchmark.group = "reduction"
    trailing = benchmark.pedantic(lambda: reduction.BoundaryReduction(lap, keep, perm).schur, rounds=3, iterations=1)
    with monkeypatch.context() as patch:
        patch.setattr(reduction, "TRAILING_SCHUR_MAX", 0)
        start = time.perf_counter()
        by_solves = reduction.BoundaryReduction(lap, keep, perm).schur
        solves_seconds = time.perf_counter() - start
    benchmark.extra_info.update(
        n_points=int(lap.shape[0]), n_kept=int(keep.size), solves_seconds=solves_seconds,
        time_ratio_vs_solves=benchmark.stats.stats.min / solves_seconds,
        schur_relative_difference=float(np.abs(trailing - by_solves).max() / np.abs(by_solves).max()))


PRODUCT_CASES = [("bump", 10000), ("saddle", 10000), ("cap", 10000), ("holes", 10000), ("bump", 50000)]


@pytest.mark.parametrize("name,size", PRODUCT_CASES, ids=[f"{n}-{s}" for n, s in PRODUCT_CASES])
def test_subspace_products_from_one_lu(benchmark, monkeypatch, name, size):
    surface = make_surface(name, size, sampling="jittered", seed=0)
    ocp = get_method("ocp")
    ocp(make_surface(name, 2000, sampling="jittered", seed=0).method_input(False))  # compiled kernels warm
    baseline = {"seconds": [], "result": None}

    def run_with_interior_solves():  # pedantic's untimed setup: the two paths alternate
        with monkeypatch.context() as patch:
            patch.setattr(reduction, "TRAILING_PRODUCTS_MAX", 0)
            start = time.perf_counter()
            baseline["result"] = ocp(surface.method_input(False))
            baseline["seconds"].append(time.perf_counter() - start)

    benchmark.group = "reduction-subspace"
    result = benchmark.pedantic(lambda: ocp(surface.method_input(False)), setup=run_with_interior_solves,
                                rounds=3, iterations=1)
    uv_old = baseline["result"].uv
    n_kept = int(sum(len(loop) for loop in result.diagnostics["boundary_loops"]))
    benchmark.extra_info.update(
        n_points=int(surface.points.shape[0]), n_kept=n_kept,
        backend=result.diagnostics.get("backend"), solves_seconds=min(baseline["seconds"]),
        time_ratio_vs_solves=benchmark.stats.stats.min / min(baseline["seconds"]),
        uv_max_difference_over_diameter=float(np.abs(result.uv - uv_old).max() / np.ptp(uv_old, axis=0).max()),
        selfcheck_passed=bool(result.diagnostics["selfcheck"]["passed"]))
