"""The angle-distortion histogram figure, from the counts a sweep stores per cell."""

from __future__ import annotations

import base64
import io
import json

import matplotlib.image
import numpy as np
import pytest

from parambench.bench.metrics import ANGLE_HIST_EDGES_DEG, evaluate
from parambench.reports.figures.angle_histogram import angle_histogram_figure, parse_angle_hist


def _image(picture):
    png = base64.b64decode(picture.data_uri.split(",", 1)[1])
    image = matplotlib.image.imread(io.BytesIO(png), format="png")
    assert image.shape[1] == picture.width_px and image.shape[0] == picture.height_px
    return image


def _grid(n=8):
    xs = np.linspace(0, 1, n + 1)
    X, Y = np.meshgrid(xs, xs, indexing="ij")
    pts = np.column_stack([X.ravel(), Y.ravel(), np.zeros(X.size)])
    idx = np.arange(X.size).reshape(X.shape)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    return pts, np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])


def test_figure_from_stored_rows():
    pts, faces = _grid()
    stretched = json.dumps(evaluate(pts, faces, pts[:, :2] * [2.0, 1.0])["angle_hist"])
    identity = evaluate(pts, faces, pts[:, :2])["angle_hist"]
    pic = angle_histogram_figure([("stretch", stretched), ("identity", identity), ("failed", None)],
                                 ANGLE_HIST_EDGES_DEG, "grid")
    image = _image(pic)
    assert (image[..., :3] < 0.95).any()
    assert "grid" in pic.title and "within ±1°" in pic.caption


def test_a_long_legend_goes_beside_the_axes(monkeypatch):
    import parambench.reports.figures.angle_histogram as module

    drawn = []
    real = module.figure_to_picture
    monkeypatch.setattr(module, "figure_to_picture", lambda fig, *a, **k: drawn.append(fig) or real(fig, *a, **k))
    pts, faces = _grid()
    hists = [(f"method {i}", evaluate(pts, faces, pts[:, :2] * [1.0 + 0.1 * i, 1.0])["angle_hist"]) for i in range(12)]
    few = angle_histogram_figure(hists[:3], ANGLE_HIST_EDGES_DEG, "grid")
    many = angle_histogram_figure(hists, ANGLE_HIST_EDGES_DEG, "grid")
    inside, beside = drawn
    assert not inside.legends and inside.axes[0].get_legend() is not None  # three fit inside
    axes_box = beside.axes[0].get_window_extent()
    legend_box = beside.legends[0].get_window_extent()
    assert legend_box.x0 >= axes_box.x1 and beside.axes[0].get_legend() is None
    assert many.width_px > 1.3 * few.width_px


def test_nothing_to_draw_and_bad_lengths():
    assert angle_histogram_figure([("a", None), ("b", "[]"), ("c", float("nan"))], ANGLE_HIST_EDGES_DEG, "x") is None
    with pytest.raises(ValueError, match="bins"):
        angle_histogram_figure([("a", [1, 2, 3])], ANGLE_HIST_EDGES_DEG, "x")


def test_parse_angle_hist():
    assert parse_angle_hist("[1, 2]").tolist() == [1, 2]
    assert parse_angle_hist([0, 5]).dtype == np.int64
    assert parse_angle_hist(None) is None and parse_angle_hist("") is None
