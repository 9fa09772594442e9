"""Method input and ground truth are separate types (issue #16 item 5).

A method's ``solve`` receives a :class:`MethodInput`: what a user's file would hold, with no
exact map, boundary mask, generator parameters or seed, even when the caller hands the
method a full generated :class:`Surface`.
"""

from __future__ import annotations

import numpy as np
import pytest

from parambench.datasets_gen.errors import DegenerateFacesError, InvalidInputError, TooFewPointsError
from parambench.datasets_gen.registry import make_surface
from parambench.datasets_gen.surface import MethodInput, Surface
from parambench.methods import get_method, method_names
from parambench.methods.pose import normalised_surface

GROUND_TRUTH = ("exact_uv", "exact_map_kind", "boundary_mask", "params", "seed")


@pytest.fixture(scope="module")
def cap():
    surface = make_surface("cap", 300, sampling="jittered", seed=0)  # exact map, normals, loops, mesh
    assert surface.exact_uv is not None and surface.normals is not None and surface.boundary_loops is not None
    return surface


class _Stop(Exception):
    """Raised by the spy once it has seen the input (the method need not run)."""


@pytest.mark.parametrize("name", method_names())
def test_every_method_solves_on_a_method_input_without_ground_truth(cap, name, monkeypatch):
    method = get_method(name)
    seen = []

    def spy(self, surface, params, timer):
        seen.append(surface)
        raise _Stop

    monkeypatch.setattr(type(method), "solve", spy)
    with pytest.raises(_Stop):
        method(cap)
    (given,) = seen
    assert isinstance(given, MethodInput)
    for key in GROUND_TRUTH:
        assert not hasattr(given, key), key
    # what the caller gave is kept: faces, normals (turned with the unit pose), loops
    assert given.faces is cap.faces
    assert given.normals is not None and given.name == cap.name
    assert len(given.boundary_loops) == len(cap.boundary_loops)
    assert all(np.array_equal(a, b) for a, b in zip(given.boundary_loops, cap.boundary_loops))
    assert cap.exact_uv is not None and cap.params  # the caller's Surface is untouched


def test_method_input_of_a_surface_returns_the_new_type(cap):
    for needs_faces in (False, True):
        given = cap.method_input(needs_faces)
        assert isinstance(given, MethodInput) and not isinstance(given, Surface)
        assert given.boundary_loops is None and given.n_points == cap.n_points
        assert given.has_faces == needs_faces


def test_converting_a_surface_keeps_the_data_bit_identical(cap):
    given = cap.as_method_input()
    assert isinstance(given, MethodInput)
    assert given.points is cap.points and given.faces is cap.faces and given.normals is cap.normals
    assert given.name == cap.name
    assert all(a is b for a, b in zip(given.boundary_loops, cap.boundary_loops))
    assert len(given.boundary_loops) == len(cap.boundary_loops)
    for key in GROUND_TRUTH:
        assert not hasattr(given, key), key
    # a MethodInput passes through the conversion as is
    from parambench.methods.base import as_method_input

    assert as_method_input(given) is given


def test_a_method_refuses_anything_else(cap):
    with pytest.raises(InvalidInputError, match="Surface or a MethodInput"):
        get_method("sdp")(cap.points)


def test_unit_pose_copy_is_a_method_input_without_the_exact_map(cap):
    unit, pose = normalised_surface(cap)
    assert isinstance(unit, MethodInput) and not hasattr(unit, "exact_uv")
    np.testing.assert_array_equal(unit.points, pose.to_unit(cap.points))
    assert unit.faces is cap.faces


# --- validation: the same functions as Surface -------------------------------------------


def _square():
    pts = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.5, 0.5, 0.1]], float)
    faces = np.array([[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]])
    return pts, faces


def test_method_input_converts_types_like_surface():
    pts, faces = _square()
    given = MethodInput(pts.astype(np.float32), faces.astype(np.int32), normals=2 * np.ones((5, 3)),
                        boundary_loops=[[0, 1, 2, 3]])
    assert given.points.dtype == np.float64 and given.faces.dtype == np.int64
    np.testing.assert_allclose(np.linalg.norm(given.normals, axis=1), 1.0)
    assert given.boundary_loops[0].dtype == np.int64
    assert given.n_points == 5 and given.has_faces and not MethodInput(pts).has_faces


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_method_input_rejects_non_finite_points_like_surface(bad):
    pts, _ = _square()
    pts[2, 1] = bad
    for cls in (Surface, MethodInput):
        with pytest.raises(InvalidInputError, match="row 2"):
            cls(pts)


def test_method_input_rejects_what_surface_rejects():
    pts, faces = _square()
    for cls in (Surface, MethodInput):
        with pytest.raises(TooFewPointsError, match="at least 4"):
            cls(np.eye(3))
        with pytest.raises(InvalidInputError, match="face indices"):
            cls(pts, faces + 1)
        with pytest.raises(InvalidInputError, match="normals"):
            cls(pts, normals=np.zeros((5, 3)))
        seam = np.vstack([pts, pts[1] + [0, 0, 1e-10]])
        with pytest.raises(DegenerateFacesError, match="coincident vertices"):
            cls(seam, np.vstack([faces, [[1, 5, 2]]]))
