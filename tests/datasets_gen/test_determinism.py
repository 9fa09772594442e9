"""Seeds: the same seed reproduces every array; another seed changes the random samplings."""

from __future__ import annotations

import numpy as np
import pytest

from parambench.datasets_gen.registry import make_surface

ARRAYS = ("points", "faces", "normals", "boundary_mask", "exact_uv")


def _same(a, b) -> bool:
    if a.exact_uv is None or b.exact_uv is None:
        if a.exact_uv is not b.exact_uv:
            return False
    return all(getattr(a, k) is None and getattr(b, k) is None or np.array_equal(getattr(a, k), getattr(b, k))
               for k in ARRAYS) and all(np.array_equal(x, y) for x, y in zip(a.boundary_loops, b.boundary_loops))


@pytest.mark.parametrize("sampling", ["grid", "jittered", "random", "blue-noise", "graded"])
@pytest.mark.parametrize("name", ["holes-bumped", "cap", "protrusions", "gnome-strip", "slit", "fold"])
def test_same_seed_same_arrays(name, sampling):
    a = make_surface(name, 700, sampling=sampling, seed=11, noise=0.2)
    b = make_surface(name, 700, sampling=sampling, seed=11, noise=0.2)
    assert _same(a, b)


@pytest.mark.parametrize("sampling", ["jittered", "random", "blue-noise", "graded"])
@pytest.mark.parametrize("name", ["plane", "cylinder", "gnome-strip", "fold"])
def test_other_seed_other_points(name, sampling):
    a = make_surface(name, 700, sampling=sampling, seed=1)
    b = make_surface(name, 700, sampling=sampling, seed=2)
    rows_a = {tuple(r) for r in np.round(a.points, 12)}
    rows_b = {tuple(r) for r in np.round(b.points, 12)}
    # not a permutation of the same points: most points moved
    assert len(rows_a & rows_b) < 0.1 * len(rows_a)


def test_grid_points_do_not_depend_on_seed_but_order_does():
    a = make_surface("bump", 900, sampling="grid", seed=1)
    b = make_surface("bump", 900, sampling="grid", seed=2)
    order_a, order_b = np.lexsort(a.points.T), np.lexsort(b.points.T)
    assert np.array_equal(a.points[order_a], b.points[order_b])
    assert not np.array_equal(a.points, b.points)  # the order is a seeded shuffle


def test_noise_moves_points_along_exact_normals_only():
    clean = make_surface("saddle", 3000, sampling="jittered", seed=5)
    noisy = make_surface("saddle", 3000, sampling="jittered", seed=5, noise=0.5)
    d = noisy.points - clean.points
    along = np.einsum("ij,ij->i", d, clean.normals)
    assert np.allclose(d, along[:, None] * clean.normals, atol=1e-12)
    # Gaussian with std = noise * mean spacing
    assert abs(along.std() / (0.5 * clean.params["spacing"]) - 1) < 0.06
    assert abs(along.mean()) < 0.1 * along.std()
    for k in ("faces", "normals", "exact_uv", "boundary_mask"):
        a, b = getattr(clean, k), getattr(noisy, k)
        assert (a is None and b is None) or np.array_equal(a, b)
    assert noisy.params["noise"] == 0.5
