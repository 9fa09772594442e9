"""Pictures: geometry helpers checked by hand, every figure renders to a decodable PNG."""

import base64
import io

import matplotlib.image
import PIL.Image
import numpy as np
import pandas as pd
import pytest

from parambench.reports.figures import (BoundaryPanel, LandscapeCurve, LayoutPanel, benchmark_figure, boundary_figure,
                             boundary_scores, checkerboard_figure, fit_power_law, landscape_figure,
                             negative_fractions, scaling_figure, scaling_fits, uv_layout_figure, weights_figure)
from parambench.reports.figures._common import splat, subsample_faces, view_projection
from parambench.reports.figures.boundary import classify_points
from parambench.reports.figures.checkerboard import checker_parity, subdivision_barycentrics
from parambench.reports.figures.uv_layout import shared_qc_range
from parambench.reports.figures.weights import shared_bins
from parambench.reports.labels import add_labels
from parambench.reports.load import CellArrays, normalise_rows


def decode(picture):
    kind = picture.data_uri.split(";", 1)[0].removeprefix("data:image/")
    assert kind in ("png", "jpeg") and picture.data_uri.startswith(f"data:image/{kind};base64,")
    data = base64.b64decode(picture.data_uri.split(",", 1)[1])
    image = np.asarray(PIL.Image.open(io.BytesIO(data)).convert("RGB"), dtype=np.float64) / 255.0
    assert image.shape[1] == picture.width_px and image.shape[0] == picture.height_px
    assert picture.text_overlaps == []  # no title, label or legend text on top of another
    assert picture.width_px > 100 and picture.height_px > 100
    # Not a blank canvas: some pixels differ from white.
    assert (image[..., :3] < 0.95).any()
    return image


@pytest.fixture
def cell(mesh_tools):
    points, faces, loop = mesh_tools["grid_mesh"](9, "bump")
    uv = mesh_tools["method_uv"]("ocp", points, 9, 0)
    qc = mesh_tools["per_face_qc"](points, faces, uv)
    flipped = mesh_tools["flipped_mask"](faces, uv)
    k, energy, t = mesh_tools["landscape"](3.0)
    return CellArrays(points, faces, uv, qc, flipped, [loop], [loop[::2]], {"k": k, "E": energy, "t": t})


def test_subsample_keeps_all_small_meshes_and_every_foldover():
    assert np.array_equal(subsample_faces(10, 20), np.arange(10))
    keep = np.zeros(1000, bool)
    keep[[3, 500, 999]] = True
    chosen = subsample_faces(1000, 100, keep=keep, seed=1)
    assert 100 <= len(chosen) <= 103
    assert {3, 500, 999} <= set(chosen)
    assert np.array_equal(chosen, subsample_faces(1000, 100, keep=keep, seed=1))
    assert np.all(np.diff(chosen) > 0)


def test_splat_enlarges_subsampled_triangles_about_their_centroids():
    verts = np.array([[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]], [[2.0, 2.0], [4.0, 2.0], [2.0, 5.0]]])
    assert splat(verts, 2) is verts  # nothing left out: drawn as is
    out = splat(verts, 4)  # half drawn: sqrt(8 * 2) = 4-fold in length
    assert np.allclose(out.mean(axis=1), verts.mean(axis=1))
    assert np.allclose(out - out.mean(axis=1, keepdims=True), 4.0 * (verts - verts.mean(axis=1, keepdims=True)))
    assert np.allclose(splat(verts, 1000) - splat(verts, 1000).mean(axis=1, keepdims=True),
                       5.0 * (verts - verts.mean(axis=1, keepdims=True)))  # capped


def test_view_projection_is_a_rotation_and_faces_pick_the_front(mesh_tools):
    points, faces, _ = mesh_tools["grid_mesh"](9, "bump")
    xy, depth, view = view_projection(points, faces)
    centred = points - points.mean(axis=0)
    assert np.allclose(np.hypot(np.linalg.norm(xy, axis=1), depth), np.linalg.norm(centred, axis=1))
    assert np.isclose(np.linalg.norm(view), 1.0)
    # Faces are CCW seen from +z: the camera is on the +z side, so the bump's top is nearest.
    assert view[2] > 0
    top = np.argmax(points[:, 2])
    _, depth_flipped, view_flipped = view_projection(points, faces[:, ::-1])
    assert view_flipped[2] < 0
    assert depth[top] > np.median(depth) and depth_flipped[top] < np.median(depth_flipped)


def test_subdivision_tiles_the_triangle_with_equal_same_oriented_pieces():
    for level in (1, 2, 5):
        bary = subdivision_barycentrics(level)
        assert bary.shape == (level**2, 3, 3)
        assert np.allclose(bary.sum(axis=2), 1.0) and (bary >= -1e-12).all()
        corners = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
        xy = bary @ corners
        e1, e2 = xy[:, 1] - xy[:, 0], xy[:, 2] - xy[:, 0]
        areas = 0.5 * (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
        assert np.allclose(areas, 0.5 / level**2)


def test_checker_parity_by_hand():
    uv = np.array([[0.05, 0.05], [0.15, 0.05], [0.15, 0.15], [0.95, 0.05], [0.0, 0.0], [1.0, 1.0]])
    # 10 checks on the unit square: cells (0,0), (1,0), (1,1), (9,0); corner (1,1) lands in cell (10,10).
    assert list(checker_parity(uv, 10)) == [0, 1, 0, 1, 0, 0]
    assert list(checker_parity(np.zeros((3, 2)), 8)) == [0, 0, 0]  # degenerate map: no crash


def test_shared_qc_range_starts_at_one_and_ignores_infinities():
    lo, hi = shared_qc_range([np.array([1.0, 1.1, np.inf]), np.array([1.2, np.nan])], upper_quantile=1.0)
    assert (lo, hi) == (1.0, pytest.approx(1.2))
    assert shared_qc_range([np.ones(5)]) == (1.0, 1.05)
    assert shared_qc_range([np.array([np.nan])]) == (1.0, 2.0)


def test_boundary_scores_by_hand():
    gt = [np.array([0, 1, 2, 3])]
    mask = np.zeros(10, bool)
    mask[[0, 1, 2, 7]] = True
    s = boundary_scores(10, gt, det_mask=mask)
    assert (s["n_true"], s["n_detected"], s["n_hit"]) == (4, 4, 3)
    assert s["precision"] == pytest.approx(0.75) and s["recall"] == pytest.approx(0.75)
    s = boundary_scores(10, gt, det_loops=[np.array([0, 1]), np.array([8])])
    assert s["precision"] == pytest.approx(2 / 3) and s["recall"] == pytest.approx(0.5)
    assert s["n_det_loops"] == 2 and s["n_gt_loops"] == 1
    assert np.isnan(boundary_scores(10, gt, det_mask=np.zeros(10, bool))["precision"])


def test_classify_points_by_hand():
    mask = np.zeros(6, bool)
    mask[[0, 1, 4]] = True
    hit, false_alarm, missed = classify_points(6, [np.array([0, 1, 2])], mask)
    assert list(np.flatnonzero(hit)) == [0, 1]
    assert list(np.flatnonzero(false_alarm)) == [4]
    assert list(np.flatnonzero(missed)) == [2]
    hit, false_alarm, missed = classify_points(6, None, mask)
    assert list(np.flatnonzero(hit)) == [0, 1, 4] and not false_alarm.any() and not missed.any()


def test_fit_power_law_recovers_exponent():
    n = np.array([1e3, 2e3, 4e3, 8e3])
    p, c = fit_power_law(n, 3e-6 * n**1.37)
    assert p == pytest.approx(1.37) and c == pytest.approx(3e-6)
    assert np.isnan(fit_power_law(np.array([100.0, 100.0]), np.array([1.0, 2.0]))[0])
    assert np.isnan(fit_power_law(np.array([100.0, 200.0]), np.array([0.0, 1.0]))[0])  # t=0 dropped


def test_scaling_fits_from_rows(make_results, mesh_tools, tmp_path, spec_type):
    rows = add_labels(normalise_rows(pd.DataFrame(make_results(tmp_path / "r", spec_type(
        datasets={"bump": [100, 400, 1600]}, seeds=(0,), failed=())))))
    fits = scaling_fits(rows).set_index("variant")
    for method, expected in mesh_tools["time_exponents"].items():
        assert fits.loc[method, "exponent"] == pytest.approx(expected, abs=1e-6)
        assert fits.loc[method, "n_sizes"] == 3
    decode(scaling_figure(rows))
    single = rows[rows["size"] == 100]
    assert scaling_fits(single).empty and scaling_figure(single) is None


def test_negative_fractions_and_bins():
    arrays = {"w_cot_interior": np.array([-1.0, 1.0, 2.0, 3.0]), "w_tan_boundary": np.array([0.5, np.nan])}
    assert negative_fractions(arrays) == {("cot", "interior"): 0.25, ("tan", "boundary"): 0.0}
    bins = shared_bins([np.array([1.0, 2.0, 3.0])], n_bins=4, quantiles=(0.0, 1.0))
    assert bins[0] == 0.0 and bins[-1] == 3.0 and len(bins) == 5  # always includes 0


def test_uv_layout_and_checkerboard_render(cell):
    panels = [LayoutPanel("ocp", cell, 1.2, 2.0), LayoutPanel("copy", cell)] * 5  # 10 panels: two rows of 8
    picture = uv_layout_figure(panels, "bump")
    decode(picture)
    assert picture.rows == 2
    decode(checkerboard_figure([("ocp", cell)], "bump"))


def test_uv_layout_draws_foldovers_in_red(cell):
    image = decode(uv_layout_figure([LayoutPanel("ocp", cell)], "bump"))
    red = (image[..., 0] > 0.8) & (image[..., 1] < 0.25) & (image[..., 2] > 0.25) & (image[..., 2] < 0.5)
    assert red.sum() > 20
    no_fold = CellArrays(cell.points, cell.faces, cell.uv, cell.qc, np.zeros_like(cell.flipped))
    image = decode(uv_layout_figure([LayoutPanel("ocp", no_fold)], "bump"))
    red = (image[..., 0] > 0.8) & (image[..., 1] < 0.25) & (image[..., 2] > 0.25) & (image[..., 2] < 0.5)
    assert red.sum() == 0


def test_non_finite_uv_is_reported_not_drawn(cell):
    bad = CellArrays(cell.points, cell.faces, np.full_like(cell.uv, np.nan), cell.qc, cell.flipped)
    decode(uv_layout_figure([LayoutPanel("broken", bad)], "bump"))
    decode(checkerboard_figure([("broken", bad)], "bump"))


def test_large_mesh_is_subsampled_quickly(mesh_tools):
    points, faces, _ = mesh_tools["grid_mesh"](120, "bump")  # 28k faces
    uv = points[:, :2]
    arrays = CellArrays(points, faces, uv, np.ones(len(faces)), np.zeros(len(faces), bool))
    decode(uv_layout_figure([LayoutPanel("big", arrays)], "bump", max_faces=5000))
    decode(checkerboard_figure([("big", arrays)], "bump", max_faces=5000))


def test_boundary_landscape_weights_benchmark_render(cell):
    mask = np.zeros(len(cell.points), bool)
    mask[cell.gt_loops[0][::3]] = True
    decode(boundary_figure([BoundaryPanel("front end", cell.points, cell.gt_loops, mask, cell.det_loops),
                            BoundaryPanel("no truth", cell.points, None, mask, None)], "bump"))
    land = cell.landscape
    decode(landscape_figure([LandscapeCurve("ocp", land["k"], land["E"], land["t"], 3.0),
                             LandscapeCurve("no k_opt", land["k"], -land["E"], land["t"])], "bump"))
    rng = np.random.default_rng(0)
    decode(weights_figure({"w_tan_interior": rng.normal(0.2, 0.1, 500), "w_cot_boundary": rng.normal(0, 1, 50)},
                          "bump"))
    assert weights_figure({"points": np.zeros((3, 3))}, "bump") is None
    stats = pd.DataFrame([{"group": "g", "name": f"t{i}", "min": 0.01 * i, "max": 0.03 * i, "median": 0.02 * i,
                           "mean": 0.02 * i, "stddev": 0.001, "rounds": 5, "extra": "{}"} for i in range(1, 4)])
    decode(benchmark_figure(stats))
    assert benchmark_figure(stats.assign(median=np.nan)) is None


def test_figures_need_panels():
    with pytest.raises(ValueError):
        uv_layout_figure([], "x")
    with pytest.raises(ValueError):
        landscape_figure([], "x")


def test_seeds_of_one_requested_size_are_one_size():
    """A 500-point bump sampled with two seeds has 492 and 493 points: two "sizes" to a fit of
    the measured counts, exponent in the hundreds, and the report stopped on an overflow."""
    base = {"dataset": "bump", "sampling": "jittered", "noise": 0.0, "variant": "ocp", "status": "ok"}
    one = pd.DataFrame([{**base, "size": 500, "n_points": 492, "time_total": 0.31},
                        {**base, "size": 500, "n_points": 493, "time_total": 0.02}])
    assert scaling_fits(one).empty and scaling_figure(one) is None
    two = pd.concat([one, pd.DataFrame([{**base, "size": 2000, "n_points": 1990, "time_total": 0.66},
                                        {**base, "size": 2000, "n_points": 2004, "time_total": 0.66}])])
    fit = scaling_fits(two).iloc[0]
    assert fit["n_sizes"] == 2 and fit["n_min"] == 492.5 and fit["n_max"] == 1997.0
    assert fit["exponent"] == pytest.approx(np.log(0.66 / 0.165) / np.log(1997.0 / 492.5))
