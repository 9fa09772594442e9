"""Boundary detection scored against a rim curve (scattered points have no point on it)."""

from __future__ import annotations

import numpy as np
import pytest

from parambench.bench.metrics.rim import rim_recall_precision, rim_samples

# A unit square's rim, as a mesh's boundary loop of 4 vertices.
SQUARE = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], dtype=float)
LOOP = [np.arange(4)]


def test_rim_samples_follow_the_loop_at_most_a_step_apart():
    samples = rim_samples(SQUARE, LOOP, 0.1)
    assert samples.shape == (40, 3)
    gaps = np.linalg.norm(np.diff(np.vstack([samples, samples[:1]]), axis=0), axis=1)
    assert gaps.max() <= 0.1 + 1e-12
    assert all(any(np.allclose(s, v) for s in samples) for v in SQUARE)  # every corner kept
    on_an_edge = (np.isclose(samples[:, 0], 0) | np.isclose(samples[:, 0], 1)
                  | np.isclose(samples[:, 1], 0) | np.isclose(samples[:, 1], 1))
    assert on_an_edge.all()


def test_points_along_the_rim_score_one_and_points_inside_score_zero():
    spacing = 0.02
    t = np.linspace(0, 1, 50, endpoint=False)
    rim_points = np.vstack([np.c_[t, 0.01 + 0 * t], np.c_[1 - 0.01 + 0 * t, t], np.c_[1 - t, 1 - 0.01 + 0 * t],
                            np.c_[0.01 + 0 * t, 1 - t]])  # half a spacing inside the rim, all round
    inner = 0.2 + 0.6 * np.random.default_rng(0).random((300, 2))  # 10+ spacings inside
    points = np.c_[np.vstack([rim_points, inner]), np.zeros(len(rim_points) + 300)]
    detected = np.zeros(len(points), dtype=bool)
    detected[: len(rim_points)] = True
    assert rim_recall_precision(points, detected, SQUARE, LOOP, spacing) == (1.0, 1.0)
    detected_inner = ~detected
    recall, precision = rim_recall_precision(points, detected_inner, SQUARE, LOOP, spacing)
    assert recall == 0.0 and precision == 0.0
    # Half the rim found (the bottom and right sides): recall one half, precision one.
    half = np.zeros(len(points), dtype=bool)
    half[:100] = True
    recall, precision = rim_recall_precision(points, half, SQUARE, LOOP, spacing)
    assert recall == pytest.approx(0.5, abs=0.05) and precision == 1.0
    assert rim_recall_precision(points, np.zeros(len(points), bool), SQUARE, LOOP, spacing) == (0.0, None)
