"""Distortion metrics against analytic answers and hand-computed cases."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.spatial import Delaunay

from parambench.bench.metrics import (
    ANGLE_HIST_EDGES_DEG,
    METRIC_KEYS,
    SELFMESH_KEYS,
    angle_differences_deg,
    angle_histogram,
    beltrami_abs,
    flipped_share,
    normalized_area_distortion,
    points_in_loops,
    self_scored,
    sigma_ratio_excess,
    uv_loop_faces,
    area_distortion,
    count_collapsed,
    count_foldovers,
    evaluate,
    exact_map_error,
    jacobian_singular_values,
    per_face_qc,
    quasi_conformal,
    similarity_align,
    turning_number,
    uv_delaunay_faces,
    weighted_quantile,
)
from parambench.datasets_gen.errors import DegenerateFacesError, InvalidInputError


# ---------------------------------------------------------------- helpers


def grid_mesh(n: int, m: int, x0=-1.0, x1=1.0, y0=-1.0, y1=1.0):
    """Planar grid in z=0, faces counter-clockwise seen from +z."""
    return grid_mesh_from_lines(np.linspace(x0, x1, n + 1), np.linspace(y0, y1, m + 1))


def grid_mesh_from_lines(xs, ys):
    """Planar grid on the given x and y lines; point index i * len(ys) + j is (xs[i], ys[j])."""
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    pts = np.column_stack([X.ravel(), Y.ravel(), np.zeros(X.size)])
    idx = np.arange(X.size).reshape(X.shape)
    a, b = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel()
    c, d = idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    faces = np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])]).astype(np.int64)
    return pts, faces


def jittered_grid(n=12, seed=0):
    pts, faces = grid_mesh(n, n)
    rng = np.random.default_rng(seed)
    interior = (np.abs(pts[:, 0]) < 1 - 1e-9) & (np.abs(pts[:, 1]) < 1 - 1e-9)
    pts[interior, :2] += rng.uniform(-0.2, 0.2, size=(interior.sum(), 2)) * (2.0 / n)
    return pts, faces


def annulus_mesh(n=20):
    """Square [-1,1]^2 with the square hole |x|,|y| < 0.4 removed."""
    pts, faces = grid_mesh(n, n)
    cen = pts[faces].mean(axis=1)
    keep = ~((np.abs(cen[:, 0]) < 0.4) & (np.abs(cen[:, 1]) < 0.4))
    faces = faces[keep]
    used = np.unique(faces)
    remap = np.full(len(pts), -1)
    remap[used] = np.arange(used.size)
    return pts[used], remap[faces]


def rot2(theta):
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s], [s, c]])


def random_rotation_3d(seed):
    q, r = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


# ---------------------------------------------------------------- identity-like maps


@pytest.mark.parametrize(
    "scale, theta, shift, mirror",
    [(1.0, 0.0, (0.0, 0.0), False), (3.7, 0.9, (5.0, -2.0), False), (0.01, -2.5, (1.0, -1.0), False),
     (2.0, 0.3, (1.0, 1.0), True)],
)
def test_similarity_of_planar_mesh_is_undistorted(scale, theta, shift, mirror):
    pts, faces = jittered_grid()
    xy = pts[:, :2].copy()
    if mirror:
        xy[:, 1] *= -1
    uv = scale * xy @ rot2(theta).T + np.asarray(shift)
    r = evaluate(pts, faces, uv, exact_uv=pts[:, :2])
    assert abs(r["qc_mean"] - 1) < 1e-12 and abs(r["qc_max"] - 1) < 1e-12 and abs(r["qc_p95"] - 1) < 1e-12
    assert r["area_distortion"] < 1e-12
    assert r["foldovers"] == 0 and r["collapsed"] == 0
    assert r["exact_error"] < 1e-12
    # Sign is relative to the majority orientation, so a mirror image still gives +1.
    assert r["turning_numbers"] == pytest.approx([1.0], abs=1e-12)
    assert r["n_eval_faces"] == len(faces)


def test_planar_mesh_rotated_in_3d_is_undistorted():
    pts, faces = jittered_grid(seed=3)
    pts3 = pts @ random_rotation_3d(7).T + np.array([1.0, 2.0, 3.0])
    r = evaluate(pts3, faces, pts[:, :2], exact_uv=pts[:, :2])
    assert abs(r["qc_max"] - 1) < 1e-12
    assert r["area_distortion"] < 1e-12 and r["exact_error"] < 1e-12 and r["foldovers"] == 0


# ---------------------------------------------------------------- hand-computed Jacobians

TRI = np.array([[0, 1, 2]])


def test_stretch_of_unit_triangle():
    pts = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    uv = np.array([[0.0, 0], [2, 0], [0, 1]])
    s1, s2, signed, area = jacobian_singular_values(pts, TRI, uv)
    assert s1 == pytest.approx([2.0], abs=1e-15) and s2 == pytest.approx([1.0], abs=1e-15)
    assert signed == pytest.approx([1.0]) and area == pytest.approx([0.5])
    assert quasi_conformal(s1, s2) == pytest.approx([2.0])


def test_shear_golden_ratio():
    # J = [[1, 1], [0, 1]]: singular values (sqrt(5) +- 1) / 2.
    pts = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    uv = np.array([[0.0, 0], [1, 0], [1, 1]])
    s1, s2, signed, _ = jacobian_singular_values(pts, TRI, uv)
    assert s1[0] == pytest.approx((np.sqrt(5) + 1) / 2, rel=1e-14)
    assert s2[0] == pytest.approx((np.sqrt(5) - 1) / 2, rel=1e-14)
    assert per_face_qc(pts, TRI, uv)[0] == pytest.approx((3 + np.sqrt(5)) / 2, rel=1e-14)
    assert signed[0] == pytest.approx(0.5)


def test_triangle_out_of_plane():
    # Legs of length 1 (along x) and sqrt(2) (along (0,1,1)), at a right angle, mapped to unit legs.
    pts = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 1]])
    uv = np.array([[0.0, 0], [1, 0], [0, 1]])
    s1, s2, signed, area = jacobian_singular_values(pts, TRI, uv)
    assert s1[0] == pytest.approx(1.0, rel=1e-14) and s2[0] == pytest.approx(1 / np.sqrt(2), rel=1e-14)
    assert area[0] == pytest.approx(np.sqrt(2) / 2, rel=1e-14) and signed[0] == pytest.approx(0.5)


@pytest.mark.parametrize("seed", range(5))
def test_random_affine_maps_match_numpy_svd(seed):
    rng = np.random.default_rng(seed)
    t2 = rng.normal(size=(3, 2))
    e1, e2 = t2[1] - t2[0], t2[2] - t2[0]
    if e1[0] * e2[1] - e1[1] * e2[0] < 0:
        t2 = t2[::-1].copy()  # CCW in its plane, so det J has the sign of det A
    pts = np.column_stack([t2, np.zeros(3)]) @ random_rotation_3d(seed).T
    A = rng.normal(size=(2, 2))
    uv = t2 @ A.T + rng.normal(size=2)
    s1, s2, signed, area = jacobian_singular_values(pts, TRI, uv)
    sv = np.linalg.svd(A, compute_uv=False)
    assert [s1[0], s2[0]] == pytest.approx(sv, rel=1e-10)
    assert np.sign(signed[0]) == np.sign(np.linalg.det(A))
    assert signed[0] == pytest.approx(np.linalg.det(A) * area[0], rel=1e-10)


def test_quasi_conformal_is_inf_on_collapsed():
    assert quasi_conformal(np.array([1.0, 0.0, 3.0]), np.array([0.0, 0.0, 1.5])).tolist() == [np.inf, np.inf, 2.0]


# ---------------------------------------------------------------- orientation


def test_count_foldovers_and_collapsed_by_hand():
    assert count_foldovers(np.array([1.0, 2.0, -1.0])) == 1
    assert count_foldovers(np.array([-1.0, -2.0, 1.0])) == 1
    assert count_foldovers(np.array([-1.0, -2.0, -3.0])) == 0
    a = np.array([1.0, 1.0, 0.0, -1.0, 1e-17])
    assert count_foldovers(a) == 1 and count_collapsed(a) == 2


def test_reflected_map_has_no_foldovers():
    pts, faces = jittered_grid()
    uv = pts[:, :2] * np.array([1.0, -1.0])
    r = evaluate(pts, faces, uv)
    assert r["foldovers"] == 0 and r["collapsed"] == 0
    _, _, signed, _ = jacobian_singular_values(pts, faces, uv)
    assert np.all(signed < 0)  # it really is reflected


def _corner_with_single_face(faces, n_points):
    counts = np.bincount(faces.ravel(), minlength=n_points)
    v = int(np.flatnonzero(counts == 1)[0])
    f = int(np.flatnonzero((faces == v).any(axis=1))[0])
    return v, faces[f][faces[f] != v]


def test_one_flipped_triangle():
    pts, faces = grid_mesh(6, 6)
    v, (a, b) = _corner_with_single_face(faces, len(pts))
    uv = pts[:, :2].copy()
    mid = 0.5 * (uv[a] + uv[b])
    uv[v] = 2 * mid - uv[v]  # mirror the corner across its opposite edge: only that face flips
    r = evaluate(pts, faces, uv)
    assert r["foldovers"] == 1 and r["collapsed"] == 0
    assert r["foldover_fraction"] == pytest.approx(1 / len(faces))
    # Mirroring a right isosceles triangle across its hypotenuse keeps its shape.
    assert r["qc_max"] == pytest.approx(1.0, abs=1e-12)


def test_one_collapsed_triangle():
    pts, faces = grid_mesh(6, 6)
    v, (a, b) = _corner_with_single_face(faces, len(pts))
    uv = pts[:, :2].copy()
    uv[v] = 0.5 * (uv[a] + uv[b])
    r = evaluate(pts, faces, uv)
    assert r["collapsed"] == 1 and r["foldovers"] == 0
    # The collapsed face is left out of the QC statistics, the rest is an isometry.
    assert r["qc_max"] == pytest.approx(1.0, abs=1e-12)
    assert np.isinf(per_face_qc(pts, faces, uv)).sum() == 1


# ---------------------------------------------------------------- turning number


def circle(n, turns=1.0, r=1.0):
    t = np.linspace(0, 2 * np.pi * turns, n, endpoint=False)
    return r * np.column_stack([np.cos(t), np.sin(t)])


def test_turning_number_polygons():
    square = np.array([[0.0, 0], [1, 0], [1, 1], [0, 1]])
    assert turning_number(square) == pytest.approx(1.0, abs=1e-12)
    assert turning_number(square[::-1]) == pytest.approx(-1.0, abs=1e-12)
    assert turning_number(circle(101, turns=2)) == pytest.approx(2.0, abs=1e-12)
    # Limacon r = 1/2 + cos t: the curve has an inner loop and turns twice.
    t = np.linspace(0, 2 * np.pi, 400, endpoint=False)
    r = 0.5 + np.cos(t)
    assert turning_number(np.column_stack([r * np.cos(t), r * np.sin(t)])) == pytest.approx(2.0, abs=1e-12)
    # Figure eight (lemniscate of Gerono): the two lobes turn opposite ways.
    assert turning_number(np.column_stack([np.sin(t), np.sin(t) * np.cos(t)])) == pytest.approx(0.0, abs=1e-12)


@pytest.mark.parametrize("mirror", [False, True])
def test_turning_numbers_of_annulus_outer_plus_hole_minus(mirror):
    pts, faces = annulus_mesh()
    uv = pts[:, :2] * (np.array([1.0, -1.0]) if mirror else 1.0)
    r = evaluate(pts, faces, uv)
    assert r["turning_numbers"] == pytest.approx([1.0, -1.0], abs=1e-12)


def test_turning_numbers_of_given_loops_in_given_order():
    pts, faces = grid_mesh(4, 4)
    # The grid's boundary counter-clockwise (x first, then y); given once clockwise, then
    # counter-clockwise twice around.
    ring = np.array([0, 5, 10, 15, 20, 21, 22, 23, 24, 19, 14, 9, 4, 3, 2, 1])
    r = evaluate(pts, faces, pts[:, :2], boundary_loops=[ring[::-1], np.concatenate([ring, ring])])
    assert r["turning_numbers"] == pytest.approx([-1.0, 2.0], abs=1e-12)


# ---------------------------------------------------------------- alignment and exact error


@pytest.mark.parametrize("reflect", [False, True])
def test_similarity_align_recovers_transform(reflect):
    rng = np.random.default_rng(1)
    x = rng.normal(size=(50, 2))
    R = rot2(1.1) @ (np.diag([1.0, -1.0]) if reflect else np.eye(2))
    y = 2.5 * x @ R.T + np.array([3.0, -4.0])
    aligned, s, Rf, t = similarity_align(x, y, allow_reflection=True, return_transform=True)
    assert np.abs(aligned - y).max() < 1e-12
    assert s == pytest.approx(2.5, rel=1e-12) and np.allclose(Rf, R, atol=1e-12) and np.allclose(t, [3, -4])
    proper = similarity_align(x, y, allow_reflection=False)
    if reflect:
        # A rotation cannot undo a mirror image of a generic point cloud.
        assert np.abs(proper - y).max() > 0.1
    else:
        assert np.abs(proper - y).max() < 1e-12


def test_similarity_align_without_reflection_is_the_best_rotation():
    rng = np.random.default_rng(2)
    x = rng.normal(size=(30, 2)) * np.array([2.0, 1.0])
    y = x * np.array([1.0, -1.0]) + 0.1 * rng.normal(size=(30, 2))
    aligned, _, R, _ = similarity_align(x, y, allow_reflection=False, return_transform=True)
    assert np.linalg.det(R) == pytest.approx(1.0)
    # Brute force: for each angle the best scale and shift are linear least squares.
    xc, yc = x - x.mean(0), y - y.mean(0)
    best = np.inf
    for th in np.linspace(0, 2 * np.pi, 20001):
        rx = xc @ rot2(th).T
        s = max(np.sum(rx * yc) / np.sum(rx * rx), 0.0)
        best = min(best, np.sum((s * rx - yc) ** 2))
    assert np.sum((aligned - y) ** 2) == pytest.approx(best, rel=1e-6)


@pytest.mark.parametrize("eps", [0.01, 0.2])
def test_exact_map_error_of_anisotropic_stretch(eps):
    # Square (+-1, +-1) stretched to ((1+e)x, (1-e)y). Best similarity back: scale 1/(1+e^2),
    # residual per point sqrt(2) e / sqrt(1+e^2); diameter of the square 2 sqrt(2).
    exact = np.array([[1.0, 1], [-1, 1], [-1, -1], [1, -1]])
    uv = exact * np.array([1 + eps, 1 - eps])
    uv = 7.0 * uv @ rot2(0.4).T + 3.0  # the error must not see an extra similarity
    expected = eps / (2 * np.sqrt(1 + eps**2))
    assert exact_map_error(uv, exact) == pytest.approx(expected, rel=1e-12)
    assert exact_map_error(uv, exact, diameter=1.0) == pytest.approx(expected * 2 * np.sqrt(2), rel=1e-12)


def test_exact_map_error_is_scale_free_in_exact_uv():
    rng = np.random.default_rng(4)
    exact = rng.normal(size=(40, 2))
    uv = exact + 0.05 * rng.normal(size=(40, 2))
    assert exact_map_error(uv, 10 * exact) == pytest.approx(exact_map_error(uv, exact), rel=1e-12)


# ---------------------------------------------------------------- area distortion


def test_area_distortion_by_hand():
    assert area_distortion([2.0, 1.0], [1.0, 1.0], [1.0, 1.0]) == pytest.approx(np.log(2) / 2, rel=1e-14)
    # Weights 3:1 -> a Bernoulli(3/4) spread of log 2: std = log 2 * sqrt(3/16).
    assert area_distortion([2.0, 1.0], [1.0, 1.0], [3.0, 1.0]) == pytest.approx(np.log(2) * np.sqrt(3) / 4, rel=1e-14)
    assert area_distortion([5.0, 5.0, 5.0], [5.0, 5.0, 5.0], [1.0, 2.0, 3.0]) == pytest.approx(0.0, abs=1e-15)


def test_half_of_the_area_stretched_by_two():
    # uv = (x, y) for x <= 0 and (2x, y) for x > 0: half the area has s1 = 2, s2 = 1.
    pts, faces = grid_mesh(8, 4)
    uv = pts[:, :2].copy()
    uv[:, 0] = np.where(uv[:, 0] > 0, 2 * uv[:, 0], uv[:, 0])
    r = evaluate(pts, faces, uv)
    assert r["area_distortion"] == pytest.approx(np.log(2) / 2, rel=1e-12)
    assert r["qc_mean"] == pytest.approx(1.5, rel=1e-12)
    assert r["qc_p95"] == pytest.approx(2.0, rel=1e-12) and r["qc_max"] == pytest.approx(2.0, rel=1e-12)
    assert r["foldovers"] == 0


def test_statistics_are_weighted_by_3d_area():
    # Half of the triangles, covering only 0.04 / 1.04 < 5 % of the area, are stretched by 2 in x.
    xs = np.concatenate([np.linspace(-0.04, 0, 9), np.linspace(0, 1, 9)[1:]])
    pts, faces = grid_mesh_from_lines(xs, np.linspace(0, 1, 5))
    uv = pts[:, :2].copy()
    uv[:, 0] = np.where(uv[:, 0] < 0, 2 * uv[:, 0], uv[:, 0])
    r = evaluate(pts, faces, uv)
    share = 0.04 / 1.04
    assert r["qc_mean"] == pytest.approx(1 + share, rel=1e-12)
    assert r["qc_p95"] == pytest.approx(1.0, rel=1e-12)  # unweighted it would be 2
    assert r["qc_max"] == pytest.approx(2.0, rel=1e-12)
    assert r["area_distortion"] == pytest.approx(np.log(2) * np.sqrt(share * (1 - share)), rel=1e-12)


def test_uniform_scaling_has_no_area_distortion():
    pts, faces = jittered_grid(seed=5)
    r = evaluate(pts, faces, 123.0 * pts[:, :2])
    assert r["area_distortion"] < 1e-12


def test_weighted_quantile_by_hand():
    v, w = np.array([1.0, 2.0, 3.0]), np.array([0.9, 0.04, 0.06])
    assert weighted_quantile(v, w, 0.95) == 3.0
    assert weighted_quantile(v, w, 0.9) == 1.0
    assert weighted_quantile(v, w, 0.93) == 2.0


# ---------------------------------------------------------------- uv Delaunay evaluation mesh


def square_with_round_hole(n=40, radius=0.25, seed=0):
    rng = np.random.default_rng(seed)
    xs = np.linspace(0, 1, n + 1)
    X, Y = np.meshgrid(xs, xs, indexing="ij")
    xy = np.column_stack([X.ravel(), Y.ravel()])
    xy += rng.uniform(-0.15, 0.15, size=xy.shape) / n
    xy = xy[np.hypot(xy[:, 0] - 0.5, xy[:, 1] - 0.5) > radius]
    return np.column_stack([xy, np.zeros(len(xy))])


def test_uv_delaunay_drops_triangles_spanning_a_hole():
    pts = square_with_round_hole()
    uv = pts[:, :2]
    full = Delaunay(uv).simplices
    dist_full = np.hypot(*(pts[full].mean(axis=1)[:, :2] - 0.5).T)
    assert (dist_full < 0.2).any()  # the plain triangulation does cover the hole
    faces = uv_delaunay_faces(pts, uv)
    cen = pts[faces].mean(axis=1)[:, :2]
    assert np.hypot(*(cen - 0.5).T).min() > 0.23
    # Every face is CCW in uv, and the kept faces tile the square minus the hole (up to a rim).
    _, _, signed, area = jacobian_singular_values(pts, faces, uv)
    assert np.all(signed > 0)
    assert area.sum() == pytest.approx(1 - np.pi * 0.25**2, abs=0.02)


def test_uv_delaunay_orients_faces_whatever_the_triangulator_returns(monkeypatch):
    import parambench.bench.metrics.eval_mesh as eval_mesh

    def scrambled(uv):  # no orientation is promised: reverse every other triangle
        faces = Delaunay(uv).simplices.copy()
        faces[::2] = faces[::2, ::-1]
        return faces

    monkeypatch.setattr(eval_mesh, "delaunay_faces", scrambled)
    pts, _ = jittered_grid(n=6)
    uv = pts[:, :2] * np.array([1.0, -1.0])
    faces = uv_delaunay_faces(pts, uv)
    _, _, signed, _ = jacobian_singular_values(pts, faces, uv)
    assert np.all(signed > 0)


def test_uv_delaunay_keeps_a_convex_patch_whole():
    pts, _ = jittered_grid(n=10)
    faces = uv_delaunay_faces(pts, pts[:, :2])
    _, _, _, area = jacobian_singular_values(pts, faces, pts[:, :2])
    assert area.sum() == pytest.approx(4.0, rel=1e-12)


def test_evaluate_point_set_builds_the_delaunay_mesh():
    pts = square_with_round_hole(n=30)
    r = evaluate(pts, None, 2.0 * pts[:, :2] @ rot2(0.3).T, exact_uv=pts[:, :2])
    assert r["qc_max"] == pytest.approx(1.0, abs=1e-12) and r["exact_error"] < 1e-12
    assert r["n_eval_faces"] == len(uv_delaunay_faces(pts, pts[:, :2]))
    assert r["turning_numbers"] == pytest.approx([1.0, -1.0], abs=1e-12)


# ---------------------------------------------------------------- output format and errors


def test_evaluate_keys_and_json():
    pts, faces = jittered_grid()
    r = evaluate(pts, faces, pts[:, :2] ** 3 + pts[:, :2], exact_uv=pts[:, :2])
    assert tuple(r) == METRIC_KEYS
    json.dumps(r, allow_nan=False)
    assert isinstance(r["foldovers"], int) and isinstance(r["collapsed"], int)
    assert all(isinstance(t, float) for t in r["turning_numbers"])
    assert r["qc_mean"] > 1 and r["exact_error"] > 0


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_non_finite_uv_is_rejected(bad):
    pts, faces = grid_mesh(3, 3)
    uv = pts[:, :2].copy()
    uv[4, 1] = bad
    with pytest.raises(InvalidInputError, match="NaN or infinite"):
        evaluate(pts, faces, uv)
    with pytest.raises(InvalidInputError):
        evaluate(pts, None, uv)


def test_bad_shapes_and_degenerate_faces():
    pts, faces = grid_mesh(3, 3)
    with pytest.raises(InvalidInputError, match="rows"):
        evaluate(pts, faces, pts[:-1, :2])
    with pytest.raises(InvalidInputError, match="boundary loop"):
        evaluate(pts, faces, pts[:, :2], boundary_loops=[np.array([0, 1, 99])])
    collinear = np.array([[0, 1, 2]])  # grid points 0, 1, 2 lie on the line x = -1
    with pytest.raises(DegenerateFacesError):
        jacobian_singular_values(pts, collinear, pts[:, :2])


# ---------------------------------------------------------------- Beltrami, angles, area, flips (issue 13)


@pytest.mark.parametrize("a", [1.5, 2.0, 4.0])
def test_affine_stretch_has_the_hand_derived_beltrami_coefficient(a):
    # u = a x, v = y: singular values a and 1 on every face, |mu| = (a - 1) / (a + 1).
    pts, faces = jittered_grid(seed=5)
    uv = pts[:, :2] * [a, 1.0]
    r = evaluate(pts, faces, uv)
    mu = (a - 1) / (a + 1)
    assert r["mu_mean"] == pytest.approx(mu, abs=1e-12) and r["mu_p95"] == pytest.approx(mu, abs=1e-12)
    assert r["mu_sd"] < 1e-12
    assert r["sigma_ratio_max"] == pytest.approx(a + 1 / a - 2, abs=1e-12)
    # the stretch scales every area by a: nothing left once both totals are normalised
    assert r["area_distortion_normalized"] < 1e-12
    assert r["flipped_share"] == 0.0


def test_beltrami_matches_qc():
    s1, s2 = np.array([3.0, 1.0, 2.0]), np.array([1.0, 1.0, 0.0])
    mu = beltrami_abs(s1, s2)
    qc = quasi_conformal(s1, s2)
    assert mu.tolist() == [0.5, 0.0, 1.0]
    assert np.allclose(mu[:2], (qc[:2] - 1) / (qc[:2] + 1))
    assert sigma_ratio_excess(s1, s2)[0] == pytest.approx(3 + 1 / 3 - 2)


@pytest.mark.parametrize("a", [2.0, 0.5])
def test_angle_error_of_a_stretched_right_triangle_grid(a):
    # Every grid face is a right isosceles triangle with its legs on the axes. Under
    # (x, y) -> (a x, y) the right angle stays, the two 45-degree corners become
    # atan(a) and atan(1/a): mean |change| per face = 2 |atan(a) - 45 deg| / 3.
    pts, faces = grid_mesh(6, 6)
    uv = pts[:, :2] * [a, 1.0]
    r = evaluate(pts, faces, uv)
    delta = abs(np.degrees(np.arctan(a)) - 45.0)
    assert r["angle_error_mean"] == pytest.approx(2 * delta / 3, abs=1e-10)
    hist = np.asarray(r["angle_hist"])
    m = len(faces)
    assert hist.sum() == 3 * m
    # one corner per face in the bins of 0, +delta and -delta (delta = 18.43 deg at a = 2)
    assert hist[np.searchsorted(ANGLE_HIST_EDGES_DEG, delta, side="right") - 1] == m
    assert hist[np.searchsorted(ANGLE_HIST_EDGES_DEG, -delta, side="right") - 1] == m
    assert hist[np.searchsorted(ANGLE_HIST_EDGES_DEG, 1e-9, side="right") - 1] + \
        hist[np.searchsorted(ANGLE_HIST_EDGES_DEG, -1e-9, side="right") - 1] == m


def test_angle_histogram_keeps_outliers_in_the_end_bins():
    counts = angle_histogram(np.array([-90.0, -29.5, 0.2, 29.9, 45.0, np.nan]))
    assert counts.sum() == 5 and counts[0] == 2 and counts[-1] == 2 and counts[30] == 1


def test_angle_differences_are_zero_for_a_similarity_and_sum_to_zero_otherwise():
    pts, faces = jittered_grid(seed=2)
    pts3 = pts @ random_rotation_3d(4).T
    assert np.abs(angle_differences_deg(pts3, faces, 2.5 * pts[:, :2] @ rot2(0.7).T)).max() < 1e-10
    d = angle_differences_deg(pts3, faces, pts[:, :2] ** 3 + pts[:, :2])
    assert np.abs(d).max() > 1 and np.abs(d.sum(axis=1)).max() < 1e-9
    r = evaluate(pts3, faces, 2.5 * pts[:, :2] @ rot2(0.7).T)
    assert r["angle_error_mean"] < 1e-10 and r["area_distortion_normalized"] < 1e-12 and r["mu_mean"] < 1e-12


def test_normalized_area_distortion_by_hand():
    # Grid on [0, 2] x [0, 1]; the right half is stretched 3x in x, the left half kept.
    # Ratios 1 and 3 on equal 3D areas: overall ratio 2, so the mean |log r| is
    # (|log 1/2| + |log 3/2|) / 2 = log(3) / 2. Scaling the whole map changes nothing.
    pts, faces = grid_mesh_from_lines(np.linspace(0, 2, 9), np.linspace(0, 1, 5))
    x = pts[:, 0]
    uv = np.column_stack([np.where(x <= 1, x, 1 + 3 * (x - 1)), pts[:, 1]])
    r = evaluate(pts, faces, uv)
    assert r["area_distortion_normalized"] == pytest.approx(np.log(3) / 2, abs=1e-12)
    assert evaluate(pts, faces, 7.0 * uv)["area_distortion_normalized"] == pytest.approx(np.log(3) / 2, abs=1e-12)
    s1, s2, _, area = jacobian_singular_values(pts, faces, uv)
    assert normalized_area_distortion(s1, s2, area) == pytest.approx(np.log(3) / 2, abs=1e-12)


def separate_triangles(n=10):
    """n disjoint unit right triangles side by side in z = 0, counter-clockwise from +z."""
    base = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    pts = np.concatenate([base + [2.0 * i, 0, 0] for i in range(n)])
    return pts, np.arange(3 * n, dtype=np.int64).reshape(n, 3)


def test_flipped_share_three_of_ten_mirrored():
    pts, faces = separate_triangles(10)
    uv = pts[:, :2].copy()
    for f in (1, 4, 8):
        uv[faces[f], 1] *= -1  # mirror three faces
    r = evaluate(pts, faces, uv)
    assert r["flipped_share"] == pytest.approx(0.3)
    assert r["foldovers"] == 3
    # a global mirror image flips the other seven: p = 0.7, min(p, 1 - p) is still 0.3
    assert evaluate(pts, faces, uv * [1.0, -1.0])["flipped_share"] == pytest.approx(0.3)
    # a mirrored triangle keeps its angles and its |mu|
    assert r["angle_error_mean"] < 1e-12 and r["mu_mean"] < 1e-12
    _, _, signed, _ = jacobian_singular_values(pts, faces, uv)
    assert flipped_share(signed) == pytest.approx(0.3)


def test_new_metrics_are_none_when_every_face_collapsed():
    pts, faces = separate_triangles(3)
    r = evaluate(pts, faces, np.zeros((len(pts), 2)))
    assert r["collapsed"] == 3
    assert all(r[k] is None for k in ("mu_mean", "mu_sd", "mu_p95", "angle_error_mean", "angle_hist",
                                      "flipped_share", "area_distortion_normalized", "sigma_ratio_max"))
    json.dumps(r, allow_nan=False)


# ---------------------------------------------------------------- self-scored point sets


def square_with_square_hole(n=10, lo=0.3, hi=0.7, seed=0):
    """Grid points of [0, 1]^2 without those strictly inside [lo, hi]^2, with the two loops.

    Points off both loops are jittered (no four cocircular points), loop points stay on
    their straight sides, so the domain has area exactly 1 - (hi - lo)^2.
    """
    xs = np.linspace(0, 1, n + 1)
    X, Y = np.meshgrid(xs, xs, indexing="ij")
    xy = np.column_stack([X.ravel(), Y.ravel()])
    tol = 1e-9
    in_hole = (xy > lo + tol).all(axis=1) & (xy < hi - tol).all(axis=1)
    xy = xy[~in_hole]
    on_outer = (np.abs(xy - 0.5) > 0.5 - tol).any(axis=1)
    on_hole = ((xy >= lo - tol) & (xy <= hi + tol)).all(axis=1) & ~on_outer
    rng = np.random.default_rng(seed)
    free = ~on_outer & ~on_hole
    xy[free] += rng.uniform(-0.15, 0.15, size=(free.sum(), 2)) / n

    def ring(mask, centre):
        idx = np.flatnonzero(mask)
        ang = np.arctan2(xy[idx, 1] - centre[1], xy[idx, 0] - centre[0])
        return idx[np.argsort(ang)]

    outer = ring(on_outer, (0.5, 0.5))
    hole = ring(on_hole, (0.5, 0.5))[::-1]
    return np.column_stack([xy, np.zeros(len(xy))]), [outer, hole]


def test_points_in_loops_by_hand():
    pts, loops = square_with_square_hole()
    q = np.array([[0.1, 0.1], [0.5, 0.5], [0.35, 0.5], [0.2, 0.5], [1.2, 0.5], [0.5, -0.1], [0.95, 0.65]])
    assert points_in_loops(q, pts[:, :2], loops).tolist() == [True, False, False, True, False, False, True]


def test_self_mesh_covers_the_domain_and_leaves_the_hole_open():
    pts, loops = square_with_square_hole()
    faces = uv_loop_faces(pts, pts[:, :2], loops)
    _, _, signed, area = jacobian_singular_values(pts, faces, pts[:, :2])
    assert area.sum() == pytest.approx(1 - 0.4 ** 2, abs=1e-12)
    assert (signed > 0).all()
    cen = pts[faces].mean(axis=1)
    assert not ((np.abs(cen[:, 0] - 0.5) < 0.2) & (np.abs(cen[:, 1] - 0.5) < 0.2)).any()


@pytest.mark.parametrize("a", [1.0, 3.0])
def test_self_scored_stretch_has_the_hand_derived_beltrami_coefficient(a):
    # Any triangle under the same affine map has the same |mu|, whatever the uv Delaunay picks.
    pts, loops = square_with_square_hole(seed=1)
    uv = pts[:, :2] * [a, 1.0] @ rot2(0.4).T
    r = self_scored(pts, uv, loops)
    assert set(r) == {f"selfmesh_{k}" for k in SELFMESH_KEYS}
    assert r["selfmesh_mu_mean"] == pytest.approx((a - 1) / (a + 1), abs=1e-12)
    assert r["selfmesh_qc_mean"] == pytest.approx(a, abs=1e-12)
    assert r["selfmesh_n_eval_faces"] == len(uv_loop_faces(pts, pts[:, :2], loops))


def test_self_scored_needs_loops():
    pts, loops = square_with_square_hole()
    with pytest.raises(InvalidInputError, match="loop"):
        self_scored(pts, pts[:, :2], [])
    with pytest.raises(InvalidInputError, match="loop"):
        self_scored(pts, pts[:, :2], [np.array([0, 1, 10_000])])


def test_point_set_cell_stores_the_new_and_self_scored_columns():
    from parambench.bench.cells import Cell
    from parambench.bench.run_cell import METRIC_COLUMNS, compute_cell

    row, _ = compute_cell(Cell("bump", 900, "jittered", 0.0, 0, "sdp"))
    assert row["status"] == "ok"
    assert all(c in row for c in METRIC_COLUMNS)
    hist = json.loads(row["angle_hist"])
    assert len(hist) == len(ANGLE_HIST_EDGES_DEG) - 1 and sum(hist) == 3 * (row["n_eval_faces"] - row["collapsed"])
    assert 0 < row["mu_mean"] < 1 and row["angle_error_mean"] > 0
    # the self mesh sees the same map: close to, but not the same as, the ground-truth mesh
    assert row["selfmesh_n_eval_faces"] > 0.9 * row["n_eval_faces"]
    assert row["selfmesh_mu_mean"] == pytest.approx(row["mu_mean"], rel=0.2)
