"""The first map from the unrolled boundary: exact on developable surfaces, and a mesh where SDP's pair gives none."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree
from sklearn.datasets import make_s_curve

from parambench.bench.metrics import similarity_align
from parambench.datasets_gen.errors import SolverError
from parambench.methods.geometry2d import triangle_signed_areas, turning_number
from parambench.methods.pointset.boundary_first_map import boundary_first_map, unrolled_loop
from parambench.methods.pointset.frontend import build_frontend
from parambench.methods.pointset.mesh_refine import first_map_faces


def _rms_over_diameter(uv: np.ndarray, exact: np.ndarray) -> float:
    aligned = similarity_align(uv, exact)
    return float(np.sqrt(np.mean(np.sum((aligned - exact) ** 2, axis=1))) / np.linalg.norm(np.ptp(exact, axis=0)))


def _half_cylinder_rim(n_side: int = 60, radius: float = 1.0, height: float = 2.0):
    """A rectangle pi x 2 rolled onto half a cylinder: rim points counter-clockwise about
    the outward normals, their exact unrolling and their normals."""
    s = np.linspace(0.0, np.pi * radius, n_side, endpoint=False)
    y = np.linspace(0.0, height, n_side // 3, endpoint=False)
    flat = np.concatenate([np.c_[s, np.zeros_like(s)], np.c_[np.full_like(y, np.pi * radius), y],
                           np.c_[np.pi * radius - s, np.full_like(s, height)], np.c_[np.zeros_like(y), height - y]])
    angle = flat[:, 0] / radius
    points = np.c_[radius * np.cos(angle), flat[:, 1], radius * np.sin(angle)]
    # d/ds x d/dy is the inward normal: the loop, counter-clockwise in (s, y), turns
    # counter-clockwise about it.
    normals = -np.c_[np.cos(angle), np.zeros_like(angle), np.sin(angle)]
    return points, normals, flat


def test_the_rim_of_a_rolled_rectangle_unrolls_to_the_rectangle():
    points, normals, flat = _half_cylinder_rim()
    loop = np.arange(len(points))
    polygon = unrolled_loop(points, normals, loop)
    assert turning_number(polygon) == pytest.approx(1.0)
    # Chords of the curved rim are shorter than its arcs (by 1 - sinc, 1.1e-4 here): the
    # polygon is the rectangle's up to that (measured 2.2e-5 of the diameter).
    assert _rms_over_diameter(polygon, flat) < 1e-4
    # Seen from the other side (the loop walked the other way about the outward normals)
    # the polygon is the rectangle's mirror image.
    backwards = loop[::-1]
    mirrored = unrolled_loop(points, -normals, backwards)
    assert turning_number(mirrored) == pytest.approx(1.0)
    assert _rms_over_diameter(mirrored, flat[backwards]) < 1e-4


def test_a_loop_that_repeats_a_point_is_refused():
    points, normals, _ = _half_cylinder_rim()
    with pytest.raises(SolverError, match="repeats a point"):
        unrolled_loop(points, normals, np.r_[0, 0, np.arange(1, len(points))])


@pytest.mark.parametrize("seed", [0, 1])
def test_scikit_learns_s_curve_maps_close_to_its_unrolling(seed):
    """Uniform random points on scikit-learn's S-curve (data nobody here made; no point on
    the rim), a strip 4.7 times longer than wide on two half-turns of a cylinder: the first
    map is its exact unrolling up to the Laplacian's error (measured 6.8e-4 / 1.3e-3 of the
    diameter at 20k / 2k points), and its uv triangulation is a mesh of the surface, no
    triangle reversed against the unrolling."""
    x, t = make_s_curve(4000, random_state=seed)
    front = build_frontend(x)
    _, rows = cKDTree(x).query(front.points)
    exact = np.c_[t, x[:, 1]][rows]
    assert len(front.boundary_loops) == 1
    uv = boundary_first_map(front.points, front.normals, front.boundary_loops[0], front.L)
    assert _rms_over_diameter(uv, exact) < 3e-3
    faces, _ = first_map_faces(front.points, uv, front.boundary_loops)
    signed = triangle_signed_areas(exact, faces)
    assert np.all(signed > 0) or np.all(signed < 0)
