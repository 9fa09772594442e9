"""Surface validation: every bad input raises its specific error with a helpful message."""

import re

import numpy as np
import pytest

from parambench.datasets_gen.errors import (
    DegenerateFacesError,
    DuplicatePointsError,
    InvalidInputError,
    TooFewPointsError,
)
from parambench.datasets_gen.surface import MethodInput, Surface


def _square():
    pts = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.5, 0.5, 0.1]], float)
    faces = np.array([[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]])
    return pts, faces


def test_valid_surface_converts_types():
    pts, faces = _square()
    s = Surface(pts.astype(np.float32), faces.astype(np.int32))
    assert s.points.dtype == np.float64 and s.faces.dtype == np.int64
    assert s.n_points == 5 and s.has_faces
    assert s.points_only().faces is None and s.points_only().n_points == 5


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_points(bad):
    pts, _ = _square()
    pts[2, 1] = bad
    with pytest.raises(InvalidInputError, match="row 2"):
        Surface(pts)


def test_wrong_shape_and_dtype():
    with pytest.raises(InvalidInputError, match=r"\(N, 3\)"):
        Surface(np.zeros((10, 2)))
    with pytest.raises(InvalidInputError, match="numeric"):
        Surface(np.array([["a", "b", "c"]] * 5))


def test_too_few_points():
    with pytest.raises(TooFewPointsError, match="at least 4"):
        Surface(np.eye(3))


def test_coincident_points_of_a_point_set_are_data():
    # point-set methods merge them (parambench.methods.pointset.coincident); the Surface keeps every row
    pts, _ = _square()
    s = Surface(np.vstack([pts, pts[1]]))
    assert s.n_points == 6 and np.array_equal(s.points[5], s.points[1])


def test_coincident_mesh_vertices_kept_apart_by_the_faces_are_a_seam():
    # vertex 5 is a copy of vertex 1 that only the last face uses: a cut along 1-4 seen from
    # face (1, 2, 4)'s side, as textured OBJ exports store seams
    pts, faces = _square()
    seam = np.vstack([pts, pts[1]])
    cut = np.array([[0, 1, 4], [5, 2, 4], [2, 3, 4], [3, 0, 4]])
    s = Surface(seam, cut)
    assert s.n_points == 6 and len(s.faces) == 4


def test_edge_joining_coincident_vertices_is_refused():
    pts, faces = _square()
    # vertex 5 sits 1e-10 from vertex 1 (coincident to the 1e-9-of-diagonal tolerance), so
    # face (1, 5, 2) passes the area test but has a (numerically) zero-length edge
    seam = np.vstack([pts, pts[1] + [0, 0, 1e-10]])
    joined = np.vstack([faces, [[1, 5, 2]]])
    with pytest.raises(DegenerateFacesError, match=r"coincident vertices \(first: vertices 1 and 5 in face 4\)"):
        Surface(seam, joined)


def test_require_unique_points_still_refuses_for_its_callers():
    from parambench.datasets_gen.surface import require_unique_points

    pts, _ = _square()
    with pytest.raises(DuplicatePointsError, match="1 and 5"):
        require_unique_points(np.vstack([pts, pts[1]]))


def test_method_input_holds_no_ground_truth():
    from parambench.datasets_gen.registry import make_surface

    gt = make_surface("cap", 300, sampling="jittered", seed=0)  # cap has an exact map
    assert gt.normals is not None and gt.exact_uv is not None and gt.boundary_loops is not None
    for needs_faces in (False, True):
        given = gt.method_input(needs_faces)
        assert isinstance(given, MethodInput)
        assert given.normals is None and given.boundary_loops is None and given.name == gt.name
        for key in ("exact_uv", "exact_map_kind", "boundary_mask", "params", "seed"):
            assert not hasattr(given, key), key
        np.testing.assert_array_equal(given.points, gt.points)
        assert (given.faces is not None) == needs_faces
    # a file's own normals are data: kept for a point-set method when asked
    np.testing.assert_allclose(gt.method_input(False, keep_normals=True).normals, gt.normals, atol=1e-15)
    assert gt.method_input(True, keep_normals=True).normals is None
    assert gt.exact_uv is not None  # the ground truth itself is untouched


def test_face_index_out_of_range():
    pts, faces = _square()
    faces[0, 0] = 5
    with pytest.raises(InvalidInputError, match="0-based"):
        Surface(pts, faces)


@pytest.mark.parametrize("dtype, bad, shown", [(np.uint64, 2**63 + 5, "[0, 9223372036854775813]"),
                                               (np.float64, 1e300, "[0, 1e+300]"), (np.int64, -3, "[-3, 4]")])
def test_out_of_range_faces_are_named_as_given_not_wrapped(dtype, bad, shown):
    """uint64 indices above 2**63 and huge whole floats were cast first and reported as negatives."""
    pts, faces = _square()
    faces = faces.astype(dtype)
    faces[0, 0] = bad
    with pytest.raises(InvalidInputError, match=re.escape(f"found range {shown}")):
        Surface(pts, faces)


def test_degenerate_faces():
    pts, faces = _square()
    rep = faces.copy()
    rep[1] = [1, 1, 4]
    with pytest.raises(DegenerateFacesError, match="repeat a vertex"):
        Surface(pts, rep)
    collinear = np.vstack([pts, [[2, 0, 0]]])
    with pytest.raises(DegenerateFacesError, match="zero area"):
        Surface(collinear, np.vstack([faces, [[0, 1, 5]]]))


def test_normals_are_normalised_and_checked():
    pts, faces = _square()
    s = Surface(pts, faces, normals=np.tile([0, 0, 2.0], (5, 1)))
    np.testing.assert_allclose(np.linalg.norm(s.normals, axis=1), 1.0)
    with pytest.raises(InvalidInputError, match="zero-length"):
        Surface(pts, faces, normals=np.zeros((5, 3)))


def test_ragged_rows_and_fractional_loops_are_refused_by_name():
    """A ragged list raised numpy's "inhomogeneous shape"; loops of 0.5, 1.2, 2.7 became 0, 1, 2."""
    with pytest.raises(InvalidInputError, match="rows of different lengths"):
        MethodInput([[0.0, 0.0, 0.0], [1.0, 2.0]])
    points = np.random.default_rng(0).random((20, 3))
    with pytest.raises(InvalidInputError, match="whole point indices"):
        MethodInput(points, boundary_loops=[[0.5, 1.2, 2.7]])
    assert MethodInput(points, boundary_loops=[[0.0, 1.0, 2.0]]).boundary_loops[0].tolist() == [0, 1, 2]
