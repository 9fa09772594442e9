"""The dense boundary path's Schur complement: one whole-matrix LU against one solve per kept vertex.

``pytest bench --benchmark-only -k reduction``. Each case times
:class:`~parambench.methods.spectral.reduction.BoundaryReduction` with S from the trailing
block of one LU (the default up to ``TRAILING_SCHUR_MAX`` kept vertices) and, in the same
process, with ``TRAILING_SCHUR_MAX = 0`` (an interior factorisation and one solve per kept
vertex). ``extra_info``: sizes, both times (factorisation and S), their ratio and the
largest difference of the two S over S's largest entry. Cases: cotangent Laplacians of
generated meshes (jittered) and pymeshlab's bunny cut open by a plane.
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
