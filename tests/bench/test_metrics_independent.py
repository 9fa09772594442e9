"""The judge's own loops, turning numbers and foldovers agree with the methods' versions.

``parambench.bench.metrics`` re-implements these on purpose (it must not import the methods'
numerics); comparing the two on several inputs makes a bug in either one show here.
"""

import ast
from pathlib import Path

import numpy as np
import pytest

import parambench.bench.metrics as metrics_pkg
from parambench.bench.metrics import (count_foldovers, flipped_mask, mesh_boundary_loops, signed_area_2d,
                           triangle_signed_areas, turning_number)
from parambench.datasets_gen.mesh_loops import boundary_loops as methods_boundary_loops
from parambench.datasets_gen.registry import make_surface
from parambench.methods.geometry2d import flipped_triangles as methods_flipped
from parambench.methods.geometry2d import signed_area_2d as methods_signed_area_2d
from parambench.methods.geometry2d import triangle_signed_areas as methods_triangle_areas
from parambench.methods.geometry2d import turning_number as methods_turning_number


def _cyclic_key(loop) -> tuple:
    loop = np.asarray(loop)
    return tuple(np.roll(loop, -int(np.argmin(loop))).tolist())


def _polygons():
    rng = np.random.default_rng(7)
    t = np.linspace(0.0, 2.0 * np.pi, 97, endpoint=False)
    circle = np.column_stack([np.cos(t), np.sin(t)])
    star = circle * (1.0 + 0.6 * np.cos(5 * t))[:, None]
    twice = np.column_stack([np.cos(2 * t), np.sin(2 * t)]) * (1.0 + 0.1 * np.cos(t))[:, None]
    limacon = np.column_stack([(0.5 + np.cos(t)) * np.cos(t), (0.5 + np.cos(t)) * np.sin(t)])
    eight = np.column_stack([np.sin(t), np.sin(t) * np.cos(t)])
    repeated = np.repeat(circle[::8], 2, axis=0)  # every vertex twice: zero-length edges
    wobbly = circle + rng.normal(scale=0.02, size=circle.shape)
    return {"circle": (circle, 1), "clockwise": (circle[::-1], -1), "star": (star, 1), "twice": (twice, 2),
            "limacon": (limacon, 2), "figure-eight": (eight, 0), "repeated": (repeated, 1),
            "wobbly": (wobbly, 1), "random": (rng.normal(size=(40, 2)), None)}


@pytest.mark.parametrize("name", list(_polygons()))
def test_turning_number_agrees_with_the_methods(name):
    polygon, expected = _polygons()[name]
    ours, theirs = turning_number(polygon), methods_turning_number(polygon)
    assert ours == pytest.approx(theirs, abs=1e-9)
    assert ours == pytest.approx(round(ours), abs=1e-9)
    if expected is not None:
        assert ours == pytest.approx(expected, abs=1e-9)
    assert signed_area_2d(polygon) == pytest.approx(methods_signed_area_2d(polygon), rel=1e-12, abs=1e-12)


def test_turning_number_of_a_unit_square_by_hand():
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    assert turning_number(square) == pytest.approx(1.0, abs=1e-15)
    assert signed_area_2d(square) == pytest.approx(1.0) and signed_area_2d(square[::-1]) == pytest.approx(-1.0)


@pytest.mark.parametrize("dataset", ["bump", "holes", "cylinder", "real/camelhead", "real/bump-domain"])
def test_mesh_loops_agree_with_the_methods(dataset):
    surface = make_surface(dataset, seed=0) if dataset.startswith("real/") else make_surface(dataset, 600, seed=3)
    ours, theirs = mesh_boundary_loops(surface.faces), methods_boundary_loops(surface.faces)
    assert len(ours) >= 1 and len(ours) == len(theirs)
    # same loops, same direction, same longest-first order; the start vertex may differ
    assert [len(lp) for lp in ours] == [len(lp) for lp in theirs]
    assert sorted(map(_cyclic_key, ours)) == sorted(map(_cyclic_key, theirs))
    shuffled = surface.faces[np.random.default_rng(1).permutation(len(surface.faces))]
    assert [lp.tolist() for lp in mesh_boundary_loops(shuffled)] == [lp.tolist() for lp in ours]


def test_mesh_loops_by_hand():
    # two triangles of a square (outer loop 0-1-2-3) and a closed tetrahedron (no loop)
    assert [lp.tolist() for lp in mesh_boundary_loops(np.array([[0, 1, 2], [0, 2, 3]]))] == [[0, 1, 2, 3]]
    assert [lp.tolist() for lp in mesh_boundary_loops(np.array([[0, 2, 1], [0, 3, 2]]))] == [[0, 3, 2, 1]]
    tetra = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]])
    assert mesh_boundary_loops(tetra) == []


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_foldovers_agree_with_the_methods(seed):
    surface = make_surface("holes", 500, seed=seed)
    rng = np.random.default_rng(seed)
    uv = surface.points[:, :2] + rng.normal(scale=0.03, size=(surface.n_points, 2))
    uv[:5] = uv[0]  # a few collapsed triangles around point 0
    for mirror in (1.0, -1.0):
        z = uv * [1.0, mirror]
        ours = triangle_signed_areas(z, surface.faces)
        np.testing.assert_allclose(ours, methods_triangle_areas(z, surface.faces), rtol=1e-12, atol=1e-15)
        mask = flipped_mask(ours)
        np.testing.assert_array_equal(mask, methods_flipped(z, surface.faces))
        assert 0 < count_foldovers(ours) == mask.sum() < len(surface.faces) / 2


def test_metrics_import_none_of_the_methods():
    folder = Path(metrics_pkg.__file__).parent
    for path in folder.glob("*.py"):
        tree = ast.parse(path.read_text())
        names = [a.name for node in ast.walk(tree) if isinstance(node, ast.Import) for a in node.names]
        names += [node.module or "" for node in ast.walk(tree) if isinstance(node, ast.ImportFrom) and not node.level]
        assert not [n for n in names if n == "methods" or n.startswith("methods.")], path.name
