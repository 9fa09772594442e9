"""Weight kinds of parambench.methods.mesh.weights: hand-computed values, symmetry, linear precision."""

from __future__ import annotations

import igl
import numpy as np
import pytest
import scipy.sparse as sp
from scipy.spatial import Delaunay

from parambench.datasets_gen.errors import InvalidInputError, UnknownNameError
from parambench.methods.mesh.weights import (WEIGHT_KINDS, laplacian, mesh_weights, negative_cotangent_vertices,
                                  negative_weight_rows, uniform_vertex_mask)


def hexagon_fan() -> tuple[np.ndarray, np.ndarray]:
    """Centre 0 and a unit regular hexagon 1..6, faces counter-clockwise."""
    ang = np.arange(6) * np.pi / 3
    pts = np.vstack([[0.0, 0.0, 0.0], np.column_stack([np.cos(ang), np.sin(ang), np.zeros(6)])])
    faces = np.array([[0, 1 + i, 1 + (i + 1) % 6] for i in range(6)], dtype=np.int64)
    return pts, faces


def random_planar(n: int = 400, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    xy = rng.uniform(-1, 1, (n, 2))
    faces = Delaunay(xy).simplices.astype(np.int64)
    return np.column_stack([xy, np.zeros(n)]), faces


def interior_mask(faces: np.ndarray, n: int) -> np.ndarray:
    mask = np.ones(n, dtype=bool)
    for loop in igl.boundary_loop_all(faces):
        mask[np.asarray(loop)] = False
    return mask


def test_cotangent_is_igl_off_diagonal():
    pts, faces = random_planar(200)
    w = mesh_weights(pts, faces, "cotangent")
    ref = sp.csr_matrix(igl.cotmatrix(pts, faces))
    ref.setdiag(0)
    assert abs(w - ref).max() < 1e-14
    assert w.diagonal().max() == 0


def test_hexagon_fan_hand_values():
    pts, faces = hexagon_fan()
    # every angle is 60 deg: cotangent (cot 60 + cot 60) / 2 = 1/sqrt(3) on spokes, half on the rim
    cot = mesh_weights(pts, faces, "cotangent").toarray()
    assert np.allclose(cot[0, 1:], 1 / np.sqrt(3))
    assert np.isclose(cot[1, 2], 0.5 / np.sqrt(3))
    # mean value at the centre: (tan 30 + tan 30) / 2 / |e| = tan 30 deg
    mv = mesh_weights(pts, faces, "mean-value").toarray()
    assert np.allclose(mv[0, 1:], np.tan(np.pi / 6))
    # rim vertex 1 towards the centre: angle at 1 is 60 deg in both faces, |e| = 1
    assert np.isclose(mv[1, 0], np.tan(np.pi / 6))
    # authalic at the centre: angles at the rim vertices are 60 deg, |e|^2 = 1
    au = mesh_weights(pts, faces, "authalic").toarray()
    assert np.allclose(au[0, 1:], 1 / np.sqrt(3))
    # uniform: centre row tan(pi/6) per spoke; rim vertices have 2 faces -> apex pi/2,
    # corner weight tan(pi/4)/2 = 1/2, spoke to the centre lies in both faces -> 1;
    # the symmetrised spoke is the mean of both rows.
    uni = mesh_weights(pts, faces, "uniform").toarray()
    assert np.allclose(uni[0, 1:], 0.5 * (np.tan(np.pi / 6) + 1.0))
    assert np.isclose(uni[1, 2], 0.5)
    assert np.allclose(uni, uni.T)


def test_uniform_equals_cotangent_on_equilateral_lattice(lattice):
    s = lattice
    cot = mesh_weights(s.points, s.faces, "cotangent").tocoo()
    uni = mesh_weights(s.points, s.faces, "uniform").toarray()
    # straight sides (3 faces) and the inside (6 faces) are regular; the parallelogram's
    # four corners (1 or 2 faces at 60 or 120 deg) use the documented corner rule
    counts = np.bincount(s.faces.ravel())
    ok = (counts[cot.row] > 2) & (counts[cot.col] > 2)
    assert ok.sum() > 0.9 * cot.nnz
    assert np.allclose(uni[cot.row[ok], cot.col[ok]], cot.data[ok], atol=1e-12)


@pytest.mark.parametrize("kind", ["cotangent", "mean-value", "authalic"])
def test_linear_precision_on_planar_mesh(kind):
    # For a flat mesh these weights reproduce linear functions at interior vertices.
    pts, faces = random_planar(300, seed=1)
    lap = laplacian(mesh_weights(pts, faces, kind))
    inner = interior_mask(faces, len(pts))
    res = lap @ pts[:, :2]
    assert np.abs(res[inner]).max() < 1e-9 * np.abs(lap.diagonal()).max()


@pytest.mark.parametrize("kind", WEIGHT_KINDS)
def test_normalized_rows_sum_to_one(kind):
    pts, faces = hexagon_fan()
    w = mesh_weights(pts, faces, kind, normalized=True)
    assert np.allclose(np.asarray(w.sum(axis=1)).ravel(), 1.0)
    lap = laplacian(w)
    assert np.allclose(lap.diagonal(), 1.0)
    assert np.allclose(np.asarray(lap.sum(axis=1)).ravel(), 0.0)


def test_symmetry_of_each_kind():
    pts, faces = random_planar(150, seed=2)
    pts[:, 2] = 0.3 * pts[:, 0] ** 2
    for kind in ("cotangent", "uniform", "hybrid"):
        w = mesh_weights(pts, faces, kind)
        assert abs(w - w.T).max() < 1e-12, kind
    for kind in ("authalic", "mean-value"):
        w = mesh_weights(pts, faces, kind)
        assert abs(w - w.T).max() > 1e-3, kind


def test_hybrid_auto_removes_negative_weights_and_keeps_the_rest():
    pts, faces = random_planar(300, seed=3)
    # a non-Delaunay retriangulation (Delaunay of a stretched copy) has negative cotangents
    faces = Delaunay(pts[:, :2] * [1.0, 5.0]).simplices.astype(np.int64)
    cot = mesh_weights(pts, faces, "cotangent")
    chosen = negative_cotangent_vertices(pts, faces)
    assert (cot.data < 0).any() and chosen.any()
    hyb = mesh_weights(pts, faces, "hybrid").tocoo()
    uni = mesh_weights(pts, faces, "uniform")
    assert hyb.data.min() > 0
    touched = chosen[hyb.row] | chosen[hyb.col]
    assert np.allclose(hyb.data[touched], np.asarray(uni[hyb.row[touched], hyb.col[touched]]).ravel())
    assert np.allclose(hyb.data[~touched], np.asarray(cot[hyb.row[~touched], hyb.col[~touched]]).ravel())


def test_hybrid_negative_rule_is_the_weights_default_and_auto_needs_a_solve():
    pts, faces = random_planar(300, seed=3)
    faces = Delaunay(pts[:, :2] * [1.0, 5.0]).simplices.astype(np.int64)
    default = mesh_weights(pts, faces, "hybrid")
    assert abs(mesh_weights(pts, faces, "hybrid", uniform_at="negative") - default).max() == 0
    assert np.array_equal(uniform_vertex_mask("negative", pts, faces), negative_cotangent_vertices(pts, faces))
    with pytest.raises(InvalidInputError, match="fold-driven"):
        mesh_weights(pts, faces, "hybrid", uniform_at="auto")


def test_hybrid_explicit_vertex_set():
    pts, faces = hexagon_fan()
    cot = mesh_weights(pts, faces, "cotangent").toarray()
    uni = mesh_weights(pts, faces, "uniform").toarray()
    for given in ("0", [0], np.array([True] + [False] * 6)):
        hyb = mesh_weights(pts, faces, "hybrid", uniform_at=given).toarray()
        assert np.allclose(hyb[0], uni[0]) and np.allclose(hyb[:, 0], uni[:, 0])
        assert np.isclose(hyb[1, 2], cot[1, 2])


def test_authalic_uniform_rows_by_hand():
    # hexagon fan with rim vertex 1 moved out to radius 2: the centre's authalic row changes,
    # its uniform authalic row is tan(60 deg / 2) / |e|^2 on every spoke (valence 6, two
    # faces per spoke, tan(theta / 2) / 2 each), so 1/sqrt(3) and 1/(4 sqrt(3)) on the long spoke
    pts, faces = hexagon_fan()
    pts[1] *= 2.0
    plain = mesh_weights(pts, faces, "authalic").toarray()
    got = mesh_weights(pts, faces, "authalic", uniform_at="0").toarray()
    expect = np.full(6, 1 / np.sqrt(3))
    expect[0] /= 4.0
    assert np.allclose(got[0, 1:], expect, rtol=1e-14)
    assert not np.allclose(plain[0, 1:], expect)
    # rows of the other vertices are the authalic ones, bit for bit
    assert np.array_equal(got[1:], plain[1:])


def test_authalic_negative_rule_switches_exactly_the_rows_with_a_negative_weight():
    pts, faces = random_planar(300, seed=3)
    faces = Delaunay(pts[:, :2] * [1.0, 5.0]).simplices.astype(np.int64)  # stretched: obtuse angles
    plain = mesh_weights(pts, faces, "authalic")
    negative = negative_weight_rows(plain)
    assert 0 < negative.sum() < len(pts)
    assert np.array_equal(uniform_vertex_mask("negative", pts, faces, kind="authalic"), negative)
    got = mesh_weights(pts, faces, "authalic", uniform_at="negative")
    assert got.data.min() > 0  # the uniform authalic rows are positive
    kept = ~negative
    assert abs(got[kept] - plain[kept]).max() == 0
    assert abs(got[negative] - plain[negative]).max() > 0
    # same sparsity: only values change
    assert np.array_equal((got != 0).toarray(), (plain != 0).toarray())
    # normalizing still gives rows summing to one
    norm = mesh_weights(pts, faces, "authalic", normalized=True, uniform_at="negative")
    assert np.allclose(np.asarray(norm.sum(axis=1)).ravel(), 1.0)


def test_bad_names_and_arguments():
    pts, faces = hexagon_fan()
    with pytest.raises(UnknownNameError, match="uniform, cotangent"):
        mesh_weights(pts, faces, "harmonic")
    with pytest.raises(InvalidInputError, match="only applies"):
        mesh_weights(pts, faces, "cotangent", uniform_at="auto")
    with pytest.raises(InvalidInputError, match="comma-separated"):
        mesh_weights(pts, faces, "hybrid", uniform_at="ears")
    with pytest.raises(InvalidInputError, match=r"\[0, 6\]"):
        mesh_weights(pts, faces, "hybrid", uniform_at=[9])
