"""A failed self-check names the cause the geometry shows: a thin part, a collapse, stray points off the surface."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import Delaunay, cKDTree

from parambench.datasets_gen.registry import make_surface
from parambench.datasets_gen.errors import ConvergenceError
from parambench.methods.hints import Hint, hinted
from parambench.methods.pointset import failure_causes as causes_module
from parambench.methods.pointset.failure_causes import (NOISY_FIT_DEG, cause_advice, describe_causes, failure_causes,
                                                         noisy_cause, noisy_points_note,
                                                        harmonic_scale, protrusion_shrink)
from parambench.methods.pointset.frontend import build_frontend
from parambench.methods.pointset.params import frontend_params
from parambench.methods.pointset.plugin_support import FRONTEND_DEFAULTS, with_shape_cause
from parambench.methods.pointset.selfcheck import check_pointset_map
from parambench.methods.pointset.selfcheck_advice import failure_line
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


@pytest.mark.parametrize("share,failed,hinted", [(0.75, ["flipped"], False), (1.0, ["flipped", "degenerate"], False),
                                                 (0.74, ["flipped"], True), (1.0, ["flipped", "coverage"], True)])
def test_a_part_thinner_than_the_sampling_gets_no_parameter_hint(share, failed, hinted):
    """Three quarters of the flipped triangles at a thin part, and nothing but folds failing:
    no parameter separates the part's sides (the cow: k_nn=16 folds more), so the line
    stops at the advice; a missed loop (coverage) or fewer thin flips keep the hint."""
    check = {"reason": "8 flipped triangle(s)", "failed": failed,
             "causes": {"thin": {"share": share, "base_share": 0.01, "gap_spacings": 0.5}}}
    line = failure_line(check, {"k_nn": 8}, "ocp")
    assert ("--param" in line) == hinted
    assert line.endswith("(--method scp)") != hinted


def test_flips_at_points_lifted_off_the_surface_are_stray_and_a_thin_flap_is_not(flap):
    rng = np.random.default_rng(4)
    points = _sheet(40, rng)
    lifted = np.arange(len(points)).reshape(40, 40)[5::10, 5::10].ravel()  # 16, 10 steps apart
    points[lifted, 2] += 3.0 / 40  # 3 grid steps off the plane in which all their neighbours lie
    normals = np.tile([0.0, 0.0, 1.0], (len(points), 1))
    knn, spacing = _inputs(points, normals)
    faces = Delaunay(points[:, :2]).simplices
    zero = np.zeros(len(faces), dtype=bool)
    at_lifted = np.isin(faces, lifted).any(axis=1)
    causes = failure_causes(points, points[:, :2], normals, knn, spacing, faces, at_lifted, zero)
    assert set(causes) == {"stray"}
    assert causes["stray"]["points"] == 16 and causes["stray"]["share"] == 1.0
    assert 2.0 < causes["stray"]["offset_spacings"] < 2.5  # 3 grid steps over the mean 8-NN distance, ~1.35 steps
    assert "16 stray point(s) in all" in describe_causes(causes)
    advice, alone = cause_advice(causes, ["flipped"])
    assert alone and "remove the stray points" in advice
    # The same number of flips elsewhere on the plane: no cause.
    elsewhere = np.zeros(len(faces), dtype=bool)
    elsewhere[np.flatnonzero(~at_lifted)[: at_lifted.sum()]] = True
    assert failure_causes(points, points[:, :2], normals, knn, spacing, faces, elsewhere, zero) == {}
    # A flap of two sheets 0.3 spacings apart: each point lies in the planes of its own
    # sheet's neighbours, so it is thin, not stray.
    points, normals, faces, n_plane = flap
    knn, spacing = _inputs(points, normals)
    on_flap = (faces >= n_plane).all(axis=1)
    assert "stray" not in failure_causes(points, points[:, :2], normals, knn, spacing, faces, on_flap,
                                         np.zeros(len(faces), dtype=bool))


def test_ocp_on_a_cloud_with_outliers_says_to_remove_them():
    """bump 3k with 4 points at random in its bounding box: the map folds there, and the check says why."""
    surf = make_surface("bump", 3000, sampling="jittered", seed=0)
    rng = np.random.default_rng(0)
    low, high = surf.points.min(axis=0), surf.points.max(axis=0)
    points = np.vstack([surf.points, low + (high - low) * rng.random((4, 3))])
    from parambench.methods.base import MethodInput
    result = get_method("ocp")(MethodInput(points, None, None, "bump with outliers"), retry_k_nn=0, refine="none")
    check = result.diagnostics["selfcheck"]
    assert not check["passed"] and "stray" in check["causes"]
    assert 1 <= check["causes"]["stray"]["points"] <= 4
    assert "remove the stray points" in failure_line(check, {"k_nn": 8}, "ocp")


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


def _tube(length: float, per_turn: int = 48):
    """An open cylinder of girth 1 and ``length`` on a grid, its rim z = 0 first (points 0..per_turn-1)."""
    theta, z = np.meshgrid(np.arange(per_turn) / per_turn * 2 * np.pi, np.arange(int(length * per_turn) + 1) / per_turn)
    r = 1.0 / (2 * np.pi)
    points = np.column_stack([r * np.cos(theta.ravel()), r * np.sin(theta.ravel()), z.ravel()])
    return points, cKDTree(points).query(points, 9)[1], np.arange(per_turn)


def test_harmonic_scale_decays_along_a_tube_as_the_first_fourier_mode():
    """Pinned at one rim, the free rim shrinks like 1 / cosh(pi L) against the middle: e^-pi per unit length."""
    smallest = {length: harmonic_scale(*_tube(length)).min() for length in (2.0, 3.0)}
    rate = -np.log(smallest[3.0] / smallest[2.0])
    assert rate == pytest.approx(np.pi, rel=0.05)
    assert protrusion_shrink(*_tube(3.0))["protrusion"]["scale"] < causes_module.PROTRUSION_SCALE
    assert protrusion_shrink(*_tube(1.0)) == {}


def test_harmonic_scale_of_a_flat_disc_is_near_one():
    """A disc's harmonic map with its rim on a circle by arc length is the identity up to scale."""
    rng = np.random.default_rng(1)
    g = np.stack(np.meshgrid(np.linspace(-1, 1, 61), np.linspace(-1, 1, 61)), -1).reshape(-1, 2)
    g = g[np.hypot(*g.T) < 0.97]
    g = g + rng.uniform(-0.005, 0.005, g.shape)
    rim_angles = np.arange(180) / 180 * 2 * np.pi
    flat = np.vstack([np.column_stack([np.cos(rim_angles), np.sin(rim_angles)]), g])
    points = np.column_stack([flat, np.zeros(len(flat))])
    knn = cKDTree(points).query(points, 9)[1]
    scale = harmonic_scale(points, knn, np.arange(180))
    assert 0.3 < scale.min() and scale.max() < 3.0
    assert protrusion_shrink(points, knn, np.arange(180)) == {}


def _front(points):
    return build_frontend(points, None, frontend_params(dict(FRONTEND_DEFAULTS)))


def test_a_failed_solve_names_the_protrusion_first_and_keeps_its_hints():
    front = _front(make_surface("protrusions", 2000, sampling="random", seed=0).points)
    exc = hinted(ConvergenceError, "no regular scp map at any k", Hint("raise k_nn (e.g. 12)", "k_nn", 12))
    named = with_shape_cause(exc, front)
    assert type(named) is ConvergenceError and named is not exc
    message = str(named)
    assert "protrusion" in message
    assert message.index("cut the shrunk protrusion off") < message.index("raise k_nn")
    assert named.parambench_causes["protrusion"]["scale"] < causes_module.PROTRUSION_SCALE


def test_a_failed_solve_without_a_protrusion_is_left_alone(monkeypatch):
    front = _front(make_surface("bump", 2000, seed=0).points)
    exc = hinted(ConvergenceError, "no regular scp map at any k", Hint("raise k_nn (e.g. 12)", "k_nn", 12))
    assert with_shape_cause(exc, front) is exc
    assert with_shape_cause(exc, None) is exc
    # Past the size limit the factorisation is not paid, and nothing is claimed.
    monkeypatch.setattr(causes_module, "PROTRUSION_MAX_POINTS", 100)
    protruding = _front(make_surface("protrusions", 2000, sampling="random", seed=0).points)
    assert with_shape_cause(exc, protruding) is exc


def test_parts_hanging_by_a_single_point_are_named_apart_from_a_protrusion():
    """A flat disc with a small cluster whose neighbours reach the disc through one point
    only: the harmonic map is constant on the cluster (scale ~1e-16, as on a range scan's
    loose flaps), which is no protrusion; the disc alone stays free of causes."""
    rng = np.random.default_rng(1)
    g = np.stack(np.meshgrid(np.linspace(-1, 1, 41), np.linspace(-1, 1, 41)), -1).reshape(-1, 2)
    g = g[np.hypot(*g.T) < 0.97] + rng.uniform(-0.005, 0.005, (np.sum(np.hypot(*g.T) < 0.97), 2))
    rim_angles = np.arange(120) / 120 * 2 * np.pi
    flat = np.vstack([np.column_stack([np.cos(rim_angles), np.sin(rim_angles)]), g])
    disc = np.column_stack([flat, np.zeros(len(flat))])
    knn_disc = cKDTree(disc).query(disc, 9)[1]
    anchor = len(disc) // 2
    flap = disc[anchor] + np.column_stack([np.zeros(12), np.zeros(12), 0.02 * np.arange(1, 13)])
    points = np.vstack([disc, flap])
    ids = len(disc) + np.arange(12)
    flap_knn = np.array([np.r_[i, [anchor], ids[ids != i][:7]] for i in ids])  # the flap sees the disc at one point
    knn = np.vstack([knn_disc, flap_knn])
    causes = protrusion_shrink(points, knn, np.arange(120))
    assert causes == {"hanging": {"points": 12}}
    assert "12 points hang on the rest by single points" in describe_causes(causes)
    assert "remove the parts that hang on by single points" in cause_advice(causes, [])[0]
    assert protrusion_shrink(disc, knn_disc, np.arange(120)) == {}


def test_ocp_after_failed_retries_also_offers_sdp_and_isolated_points_stand_alone():
    check = {"reason": "7 flipped triangle(s)", "failed": ["flipped", "distorted"],
             "retry": {"params": {"k_nn": 12}, "passed": False, "first_reason": "7 flipped triangle(s)"}}
    line = failure_line(check, {"k_nn": 8}, "ocp")
    assert "--param k_nn=16" in line and line.endswith("or try --method sdp (the spectral Dirichlet map: no k "
                                                         "search, less conformal)")
    assert "--method sdp" not in failure_line({**check, "retry": {}}, {"k_nn": 8}, "ocp")
    assert "--method sdp" not in failure_line(check, {"k_nn": 8}, "fbcp-pc")
    far = {"reason": "1 point(s) lie far from all the others", "failed": ["isolated", "flipped"]}
    line = failure_line(far, {"k_nn": 8}, "ocp")
    assert line.endswith("before flattening") and "--param" not in line


@pytest.mark.parametrize("noise, named", [(0.0, False), (0.25, False), (0.6, True)])
def test_a_failed_map_of_noisy_points_says_to_thin_them(noise, named):
    """Noise of about half the spacing or more (laspy's plane.laz tile: heights rounded to
    steps about the size of the spacing) is named, with thinning as the advice; the
    check's verdict is the triangles', not the noise's."""
    rng = np.random.default_rng(1)
    points = _sheet(40, rng)
    spacing = 1.0 / 40
    points[:, 2] += rng.normal(0.0, noise * spacing, len(points))
    normals = np.tile([0.0, 0.0, 1.0], (len(points), 1))
    uv = points[:, :2].copy()
    fold = np.linalg.norm(uv - 0.5, axis=1) < 0.1
    uv[fold] = 0.5 + (0.5 - uv[fold]) * [1.0, -1.0] * 0.8  # a mirrored patch: flipped triangles
    check = check_pointset_map(points, uv, normals, None)
    assert not check["passed"] and "flipped" in check["failed"]
    assert ("noisy" in check.get("causes", {})) is named
    line = failure_line(check, dict(FRONTEND_DEFAULTS), "ocp")
    assert ("thin the points to a spacing several times their noise" in line) is named
    clean = check_pointset_map(points, points[:, :2], normals, None)
    assert "noisy" not in clean.get("causes", {})  # a map that passes has no causes to name


def test_noisy_cause_is_judged_as_on_eight_neighbours():
    """Fit errors fall as 1/K with K neighbours: 10 degrees on 12 is 15 on 8 (noisy), 10
    on 8 is not; an unknown error names nothing."""
    assert noisy_cause(10.0, 12) == {"normal_fit_error_deg": 15.0}
    assert noisy_cause(10.0, 8) is None
    assert noisy_cause(NOISY_FIT_DEG, 8) == {"normal_fit_error_deg": NOISY_FIT_DEG}
    assert noisy_cause(None, 8) is None
    note = noisy_points_note(17.94, 8)
    assert note.startswith("The points are noisy: plane fits on 8 neighbours err by 17.9 degrees")
    assert note.endswith("or smooth them before flattening.")
    assert noisy_points_note(1.5, 8) == "" and noisy_points_note(None, 8) == ""
