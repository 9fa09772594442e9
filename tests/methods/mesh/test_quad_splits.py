"""Quads a triangulation could split either way, and cotangent weights averaged over both
splits: :mod:`parambench.methods.mesh.quad_splits` (and ``topology.interior_edges``)."""

import numpy as np
import pytest
from scipy.spatial import Delaunay

from parambench.datasets_gen.errors import InvalidInputError
from parambench.datasets_gen.surface import MethodInput
from parambench.methods.base import StageTimer
from parambench.methods.mesh.conformal_setup import build_mesh_problem, solve_with_k_rule
from parambench.methods.mesh.quad_splits import ambiguous_quads, split_averaged_cotangent
from parambench.methods.mesh.topology import interior_edges
from parambench.methods.mesh.weights import mesh_weights

from .conftest import rms_after_similarity


def _grid(n: int = 12, diagonal: str = "/", height=None):
    """An n x n grid of unit cells, every cell split along ``diagonal``; heights z(x, y)."""
    y, x = np.mgrid[0:n + 1, 0:n + 1].astype(float)
    z = np.zeros_like(x) if height is None else height(x, y)
    points = np.column_stack([x.ravel(), y.ravel(), z.ravel()])
    v = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b, c, d = v[:-1, :-1].ravel(), v[:-1, 1:].ravel(), v[1:, 1:].ravel(), v[1:, :-1].ravel()
    if diagonal == "/":
        faces = np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    else:
        faces = np.concatenate([np.column_stack([a, b, d]), np.column_stack([b, c, d])])
    return points, faces.astype(np.int64)


def _signed_areas(uv, faces):
    p = uv[faces]
    e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    return e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]


def _bumps(x, y):
    return 0.8 * np.sin(x / 2.0) * np.cos(y / 3.0)


def test_interior_edges_run_as_in_their_first_face_with_the_opposite_corners():
    faces = np.array([[0, 1, 2], [2, 1, 3], [2, 3, 4]])
    edges, pair, opposite = interior_edges(faces)
    assert edges.tolist() == [[1, 2], [3, 2]]
    assert pair.tolist() == [[0, 1], [1, 2]]
    assert opposite.tolist() == [[0, 3], [1, 4]]


def test_every_cell_of_a_grid_is_a_quad_and_its_flip_is_the_other_diagonal():
    points, faces = _grid(diagonal="/")
    split, flipped = ambiguous_quads(points, faces, points[:, :2])
    assert split.shape[0] == faces.shape[0]          # every triangle, in 144 quads
    assert np.unique(np.sort(split, axis=1), axis=0).shape[0] == faces.shape[0]
    _, other = _grid(diagonal="\\")
    key = lambda f: {tuple(sorted(t)) for t in f.tolist()}  # noqa: E731
    assert key(flipped) == key(other)
    assert (_signed_areas(points[:, :2], flipped) > 0).all()   # oriented as the faces


def test_quads_of_a_random_triangulation_are_near_ties_and_share_no_triangle():
    rng = np.random.default_rng(3)
    uv = rng.random((400, 2))
    faces = Delaunay(uv).simplices.astype(np.int64)
    faces[_signed_areas(uv, faces) < 0] = faces[_signed_areas(uv, faces) < 0][:, [0, 2, 1]]
    points = np.column_stack([uv, np.zeros(len(uv))])
    split, flipped = ambiguous_quads(points, faces, uv, tolerance_deg=10.0)
    assert 0 < split.shape[0] < faces.shape[0]
    # no triangle in two quads
    rows = {tuple(sorted(t)) for t in split.tolist()}
    assert len(rows) == split.shape[0]
    # each quad's two angles opposite its diagonal sum to within 10 degrees of 180
    for s in split.reshape(-1, 2, 3):
        i, j = sorted(set(s[0]) & set(s[1]))
        apexes = sorted((set(s[0]) | set(s[1])) - {i, j})
        angles = [np.arccos(np.dot(uv[i] - uv[k], uv[j] - uv[k])
                            / np.linalg.norm(uv[i] - uv[k]) / np.linalg.norm(uv[j] - uv[k])) for k in apexes]
        assert abs(sum(angles) - np.pi) <= np.radians(10.0) + 1e-12
    assert (_signed_areas(uv, flipped) > 0).all()
    # exact ties do not happen on random points
    assert ambiguous_quads(points, faces, uv, tolerance_deg=0.0)[0].shape[0] == 0


def test_averaged_weights_do_not_depend_on_the_split_they_start_from():
    """On a bumpy grid each split's cotangent weights differ; averaged over both splits of
    every cell, starting from either split gives the same weights."""
    points, slash = _grid(diagonal="/", height=_bumps)
    _, backslash = _grid(diagonal="\\", height=_bumps)
    averaged = []
    for faces in (slash, backslash):
        split, flipped = ambiguous_quads(points, faces, points[:, :2])
        averaged.append(split_averaged_cotangent(points, mesh_weights(points, faces, "cotangent"), split, flipped))
    plain = [mesh_weights(points, f, "cotangent") for f in (slash, backslash)]
    assert abs(plain[0] - plain[1]).max() > 1e-2
    assert abs(averaged[0] - averaged[1]).max() < 1e-12
    assert abs(averaged[0] - averaged[0].T).max() < 1e-12


def test_a_plane_is_mapped_exactly_with_averaged_weights():
    """Cotangent weights reproduce linear functions on either split, so on a flat grid the
    conformal map with averaged quads is the grid itself (up to a similarity)."""
    points, faces = _grid(n=10, height=lambda x, y: 0.3 * x + 0.1 * y)
    quads = ambiguous_quads(points, faces, points[:, :2])
    problem, _, info = build_mesh_problem(MethodInput(points=points, faces=faces), StageTimer(), weights="cotangent",
                                          normalized=False, uniform_at=None, b_matrix="boundary",
                                          averaged_quads=quads)
    assert info["n_averaged_quads"] == 100
    uv = solve_with_k_rule(problem, "scp", "auto", weights="cotangent", normalized=False).uv
    frame = np.linalg.svd(points - points.mean(axis=0), full_matrices=False)[2][:2]
    exact = points @ frame.T  # the plane in an orthonormal frame of its own: an isometry
    assert rms_after_similarity(uv, exact) < 1e-3


def test_averaged_quads_refuse_other_weights():
    points, faces = _grid(n=3)
    with pytest.raises(InvalidInputError, match="cotangent"):
        build_mesh_problem(MethodInput(points=points, faces=faces), StageTimer(), weights="uniform", normalized=False,
                           uniform_at=None, b_matrix="boundary", averaged_quads=ambiguous_quads(points, faces,
                                                                                             points[:, :2]))
