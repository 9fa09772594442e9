"""A failed self-check names the cause the geometry shows: a part thinner than the sampling, or a collapse."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import Delaunay, cKDTree

from parambench.datasets_gen.registry import make_surface
from parambench.methods.pointset.failure_causes import cause_advice, describe_causes, failure_causes
from parambench.methods.pointset.selfcheck import check_pointset_map, failure_line
from parambench.methods.registry import get_method


def _sheet(n_side: int, rng, z: float = 0.0, x0: float = 0.0, width: float = 1.0) -> np.ndarray:
    h = width / n_side
    g = np.stack(np.meshgrid(np.arange(n_side), np.arange(n_side), indexing="ij"), -1).reshape(-1, 2) * h
    g = g + rng.uniform(-0.2 * h, 0.2 * h, g.shape)
    return np.column_stack([g[:, 0] + x0, g[:, 1], np.full(len(g), z)])


def _inputs(points: np.ndarray, normals: np.ndarray):
    knn = cKDTree(points).query(points, 9)[1]
    spacing = np.linalg.norm(points[knn[:, 1:]] - points[:, None], axis=2).mean(axis=1)
    return knn, spacing


@pytest.fixture(scope="module")
def flap():
    """A plane of 40 x 40 points with a flap of two sheets 0.3 spacings apart beside it (8 % of the points)."""
    rng = np.random.default_rng(0)
    h = 1.0 / 40
    plane = _sheet(40, rng)
    top = _sheet(8, rng, z=0.3 * h, x0=1.2, width=8 * h)
    bottom = _sheet(8, rng, z=0.0, x0=1.2, width=8 * h)
    points = np.vstack([plane, top, bottom])
    normals = np.tile([0.0, 0.0, 1.0], (len(points), 1))
    normals[len(plane):len(plane) + len(top)] *= -1  # the flap's outer sides face away from each other
    faces = Delaunay(points[:, :2]).simplices
    return points, normals, faces, len(plane)


def test_flips_on_a_thin_flap_are_named_and_flips_elsewhere_are_not(flap):
    points, normals, faces, n_plane = flap
    knn, spacing = _inputs(points, normals)
    uv = points[:, :2]
    on_flap = (faces >= n_plane).all(axis=1)
    zero = np.zeros(len(faces), dtype=bool)
    causes = failure_causes(points, uv, normals, knn, spacing, faces, on_flap, zero)
    assert set(causes) == {"thin"}
    assert causes["thin"]["share"] >= 0.95 and causes["thin"]["gap_spacings"] < 0.5
    assert causes["thin"]["base_share"] < 0.2
    # The same number of flips on the plane: no neighbour across, no cause.
    on_plane = np.zeros(len(faces), dtype=bool)
    on_plane[np.flatnonzero((faces < n_plane).all(axis=1))[: on_flap.sum()]] = True
    assert failure_causes(points, uv, normals, knn, spacing, faces, on_plane, zero) == {}


def test_under_normal_noise_the_flips_say_nothing_about_thin_parts():
    """Noise puts a neighbour off the tangent plane of most points: no enrichment, no cause."""
    rng = np.random.default_rng(1)
    points = _sheet(40, rng)
    points[:, 2] += rng.normal(0.0, 0.5 / 40, len(points))
    normals = np.tile([0.0, 0.0, 1.0], (len(points), 1))
    knn, spacing = _inputs(points, normals)
    faces = Delaunay(points[:, :2]).simplices
    flipped = np.zeros(len(faces), dtype=bool)
    flipped[::50] = True
    causes = failure_causes(points, points[:, :2], normals, knn, spacing, faces, flipped,
                            np.zeros(len(faces), dtype=bool))
    assert causes == {}


def test_zero_area_triangles_a_map_shrank_are_a_collapse_and_collinear_ones_are_not():
    rng = np.random.default_rng(2)
    points = _sheet(30, rng)
    normals = np.tile([0.0, 0.0, 1.0], (len(points), 1))
    knn, spacing = _inputs(points, normals)
    faces = Delaunay(points[:, :2]).simplices
    uv = points[:, :2].copy()
    # The strip x > 0.8 shrunk 1e6 times towards a point (a protrusion's image).
    tip = points[:, 0] > 0.8
    uv[tip] = np.array([0.8, 0.5]) + 1e-6 * (uv[tip] - np.array([0.8, 0.5]))
    zero = (tip[faces]).all(axis=1)
    causes = failure_causes(points, uv, normals, knn, spacing, faces, np.zeros(len(faces), dtype=bool), zero)
    assert set(causes) == {"collapse"} and causes["collapse"]["share"] == 1.0
    assert 1e-7 < causes["collapse"]["scale"] < 1e-5
    assert "shrank 1.0e+06 times" in describe_causes(causes)
    # Zero-area triangles whose corners fell in line in uv, at full size: not a collapse.
    flat = points[:, :2].copy()
    row = (faces[:, 0] % 7 == 0)
    a, b = faces[row, 0], faces[row, 1]
    flat[faces[row, 2]] = 0.5 * (flat[a] + flat[b])
    causes = failure_causes(points, flat, normals, knn, spacing, faces, np.zeros(len(faces), dtype=bool), row)
    assert "collapse" not in causes


def test_advice_replaces_the_parameter_hint_only_for_a_collapse_alone():
    collapse = {"collapse": {"share": 1.0, "scale": 1e-5}}
    advice, alone = cause_advice(collapse, ["degenerate"])
    assert alone and "cut" in advice
    assert not cause_advice(collapse, ["degenerate", "flipped"])[1]
    advice, alone = cause_advice({"thin": {"share": 0.6, "base_share": 0.01, "gap_spacings": 0.4}}, ["flipped"])
    assert not alone and "more densely" in advice
    assert cause_advice({}, ["flipped"]) == ("", False)
    check = {"reason": "3.2 % degenerate triangles", "failed": ["degenerate"], "causes": collapse}
    line = failure_line(check, {"ball_eps_factor": 2.5, "k_nn": 8}, "ocp")
    assert "--param" not in line and line.endswith("before flattening")
    check = {"reason": "8 flipped triangle(s)", "failed": ["flipped"],
             "causes": {"thin": {"share": 0.6, "base_share": 0.01, "gap_spacings": 0.4}}}
    assert failure_line(check, {"k_nn": 8}, "ocp").endswith("(--method scp); try --param k_nn=12")


def test_a_real_failed_map_names_its_thin_fingertips():
    """protrusions, 2k random points: fingertips under a spacing fold the map (see test_ocp_retry)."""
    surf = make_surface("protrusions", 2000, sampling="random", seed=0)
    result = get_method("ocp")(surf.method_input(False), refine="none")
    check = result.diagnostics["selfcheck"]
    assert not check["passed"] and "thin" in check["causes"]
    assert "thinner than the sampling" in check["reason"]
    # A passing map is not diagnosed.
    ok = get_method("ocp")(make_surface("bump", 2000, sampling="jittered", seed=0).method_input(False))
    assert ok.diagnostics["selfcheck"]["passed"] and "causes" not in ok.diagnostics["selfcheck"]


def test_the_check_itself_carries_the_causes(flap):
    points, normals, faces, n_plane = flap
    knn, spacing = _inputs(points, normals)
    # Fold the flap's top sheet over in uv: its triangles flip.
    uv = points[:, :2].copy()
    top = np.arange(n_plane, n_plane + 64)
    uv[top, 0] = 2 * uv[top, 0].mean() - uv[top, 0]
    check = check_pointset_map(points, uv, normals, None, knn_indices=knn, spacing=float(spacing.mean()))
    assert not check["passed"] and "flipped" in check["failed"]
    assert "thin" in check["causes"] and "thinner than the sampling" in check["reason"]
