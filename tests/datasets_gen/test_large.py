"""A large surface (slow): the pipeline stays valid and honours the count at 200k points."""

from __future__ import annotations

import numpy as np
import pytest

from parambench.datasets_gen.registry import make_surface
from parambench.methods.mesh.topology import require_connected_disk_like


@pytest.mark.slow
@pytest.mark.parametrize("name,sampling", [("protrusions", "blue-noise"), ("holes-bumped", "random")])
def test_200k_points(name, sampling):
    s = make_surface(name, 200_000, sampling=sampling, seed=0)
    assert abs(s.n_points / 200_000 - 1) < 0.05
    loops = require_connected_disk_like(s.points, s.faces)
    assert len(loops) == len(s.boundary_loops) == (4 if name == "holes-bumped" else 1)
    used = np.zeros(s.n_points, bool)
    used[s.faces.ravel()] = True
    assert used.all()
