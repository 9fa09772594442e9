"""Plane cuts of a closed mesh (the real-data cases whose rim zigzags across triangles)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import ConvexHull

from parambench.datasets_gen.errors import InvalidInputError
from parambench.datasets_gen.plane_cut import cut_by_plane
from parambench.datasets_gen.surface import Surface


@pytest.fixture(scope="module")
def sphere() -> Surface:
    """The convex hull of 2000 Fibonacci points on the unit sphere, faces outward."""
    i = np.arange(2000) + 0.5
    z = 1.0 - 2.0 * i / 2000
    phi = np.pi * (1.0 + 5.0 ** 0.5) * i
    r = np.sqrt(1.0 - z * z)
    points = np.c_[r * np.cos(phi), r * np.sin(phi), z]
    faces = ConvexHull(points).simplices.astype(np.int64)
    a, b, c = (points[faces[:, k]] for k in range(3))
    inward = np.einsum("ij,ij->i", np.cross(b - a, c - a), a + b + c) < 0
    faces[inward] = faces[inward][:, ::-1]
    return Surface(points=points, faces=faces, name="sphere")


@pytest.mark.parametrize("keep_above", [True, False])
def test_half_sphere_has_one_loop_on_the_plane(sphere, keep_above):
    cut = cut_by_plane(sphere, 2, 0.5, keep_above=keep_above)
    z = cut.points[:, 2]
    level = np.median(sphere.points[:, 2])
    assert ((z > level) if keep_above else (z < level)).all()
    assert len(cut.boundary_loops) == 1 and cut.boundary_mask.sum() == cut.boundary_loops[0].size
    edge = np.linalg.norm(sphere.points[sphere.faces[:, 0]] - sphere.points[sphere.faces[:, 1]], axis=1).max()
    assert np.abs(z[cut.boundary_loops[0]] - level).max() <= edge  # the rim follows the plane
    # Every face of the sphere wholly on the kept side is kept (the half is connected).
    side = sphere.points[:, 2][sphere.faces]
    expected = ((side > level) if keep_above else (side < level)).all(axis=1)
    assert len(cut.faces) == expected.sum()
    assert len(cut.points) == np.unique(sphere.faces[expected]).size  # unused vertices dropped
    assert cut.params["cut"] == {"axis": 2, "quantile": 0.5, "keep_above": keep_above}


def test_bad_cuts_are_refused(sphere):
    with pytest.raises(InvalidInputError, match="point set"):
        cut_by_plane(Surface(points=sphere.points, name="pts"), 2, 0.5)
    with pytest.raises(InvalidInputError, match="axis"):
        cut_by_plane(sphere, 3, 0.5)
    with pytest.raises(InvalidInputError, match="quantile"):
        cut_by_plane(sphere, 0, 1.0)
    with pytest.raises(InvalidInputError, match="no face"):
        cut_by_plane(sphere, 2, 0.9995)
