"""Small meshes for the spectral-core tests, given to the core as (L, loops) only."""

from __future__ import annotations

import numpy as np
import pytest

from parambench.datasets_gen.registry import make_surface
from parambench.methods.mesh.topology import boundary_loops
from parambench.methods.mesh.weights import laplacian, mesh_weights


class MeshCase:
    """A generated surface with its cotangent Laplacian and oriented loops."""

    def __init__(self, name: str, n: int, sampling: str, **options) -> None:
        self.surface = make_surface(name, n, sampling=sampling, seed=0, **options)
        self.points = self.surface.points
        self.faces = self.surface.faces
        self.loops = boundary_loops(self.faces)
        self.lap = laplacian(mesh_weights(self.points, self.faces, "cotangent"))

    def weights_laplacian(self, kind: str, normalized: bool = False):
        return laplacian(mesh_weights(self.points, self.faces, kind, normalized=normalized))


@pytest.fixture(scope="session")
def plane() -> MeshCase:
    return MeshCase("plane", 1500, "random")


@pytest.fixture(scope="session")
def saddle() -> MeshCase:
    return MeshCase("saddle", 2000, "grid")


@pytest.fixture(scope="session")
def holes() -> MeshCase:
    return MeshCase("holes", 2500, "jittered")


@pytest.fixture(scope="session")
def uv_rms():
    """RMS distance after similarity alignment, over the reference's bbox diagonal."""
    from parambench.bench.metrics.alignment import similarity_align

    def rms(uv, ref):
        al = similarity_align(uv, ref)
        return float(np.sqrt(np.mean(np.sum((al - ref) ** 2, axis=1))) / np.linalg.norm(np.ptp(ref, axis=0)))

    return rms
