"""Surface validation: every bad input raises its specific error with a helpful message."""

import numpy as np
import pytest

from datasets_gen.errors import (
    DegenerateFacesError,
    DuplicatePointsError,
    InvalidInputError,
    TooFewPointsError,
)
from datasets_gen.surface import Surface


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


def test_duplicate_points():
    pts, _ = _square()
    pts = np.vstack([pts, pts[1]])
    with pytest.raises(DuplicatePointsError, match="1 and 5"):
        Surface(pts)


def test_face_index_out_of_range():
    pts, faces = _square()
    faces[0, 0] = 5
    with pytest.raises(InvalidInputError, match="0-based"):
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
