"""Shared meshes and helpers for the mesh-method tests (about 5k vertices each)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import Delaunay

from parambench.bench.metrics.alignment import similarity_align
from parambench.bench.metrics.orientation import count_foldovers
from parambench.datasets_gen.registry import make_surface
from parambench.datasets_gen.surface import Surface


def rms_after_similarity(uv: np.ndarray, ref: np.ndarray) -> float:
    """RMS distance after the best similarity (reflection allowed), over ref's bbox diagonal."""
    aligned = similarity_align(uv, ref)
    return float(np.sqrt(np.mean(np.sum((aligned - ref) ** 2, axis=1))) / np.linalg.norm(np.ptp(ref, axis=0)))


def foldovers(surface: Surface, uv: np.ndarray) -> int:
    """Triangles whose signed uv area opposes the majority."""
    q = uv[surface.faces]
    a, b = q[:, 1] - q[:, 0], q[:, 2] - q[:, 0]
    return count_foldovers(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])


def lattice_patch(rows: int = 8, cols: int = 10) -> Surface:
    """Flat equilateral triangular lattice in a parallelogram (valence 6 inside, straight sides)."""
    i, j = np.meshgrid(np.arange(cols, dtype=float), np.arange(rows, dtype=float))
    x = (i + 0.5 * j).ravel()
    y = (j * np.sqrt(3.0) / 2.0).ravel()
    pts = np.column_stack([x, y, np.zeros_like(x)])
    faces = Delaunay(pts[:, :2]).simplices.astype(np.int64)
    return Surface(pts, faces, name="lattice")


@pytest.fixture(scope="session")
def surfaces() -> dict[str, Surface]:
    """Generated test surfaces, built once."""
    return {
        "saddle": make_surface("saddle", 5000, sampling="grid", seed=0),
        "saddle-jittered": make_surface("saddle", 5000, sampling="jittered", seed=0),
        "cap": make_surface("cap", 5000, sampling="grid", seed=0),
        "cylinder": make_surface("cylinder", 5000, sampling="grid", seed=0),
        "holes": make_surface("holes", 5000, sampling="jittered", seed=0),
        "bump": make_surface("bump", 5000, sampling="random", seed=0),
    }


@pytest.fixture(scope="session")
def rms():
    """``rms(uv, ref)``: see :func:`rms_after_similarity`."""
    return rms_after_similarity


@pytest.fixture(scope="session")
def fold_count():
    """``fold_count(surface, uv)``: see :func:`foldovers`."""
    return foldovers


@pytest.fixture
def lattice() -> Surface:
    """A flat equilateral lattice patch (see :func:`lattice_patch`)."""
    return lattice_patch()
