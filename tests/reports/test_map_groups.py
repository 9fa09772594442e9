"""Near-identical maps share a panel: the similarity distance and the grouping rule."""

import numpy as np
import pytest

from parambench.reports.map_groups import SAME_MAP_TOLERANCE, MapGroup, group_maps, similarity_distance

SQUARE = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])


def similar(uv, angle=0.7, scale=3.0, shift=(5.0, -2.0), mirror=False):
    rot = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    out = uv @ rot.T * scale + np.asarray(shift)
    return out * np.array([-1.0, 1.0]) if mirror else out


def test_similar_maps_are_at_distance_zero():
    rng = np.random.default_rng(0)
    uv = rng.normal(size=(50, 2))
    assert similarity_distance(uv, similar(uv)) == pytest.approx(0.0, abs=1e-7)
    assert similarity_distance(uv, similar(uv, mirror=True)) == pytest.approx(0.0, abs=1e-7)


def test_shear_distance_matches_the_hand_computed_value():
    # Corners of a square (A^T A = 4 I) sheared by S = [[1, s], [0, 1]]: the singular values of
    # S have product 1 and squares summing to 2 + s^2, so d^2 = s^2 / (2 (2 + s^2)).
    for s in (0.01, 0.3, 2.0):
        sheared = SQUARE @ np.array([[1.0, s], [0.0, 1.0]])
        expected = s / np.sqrt(2.0 * (2.0 + s * s))
        assert similarity_distance(SQUARE, sheared) == pytest.approx(expected, rel=1e-9)
        assert similarity_distance(sheared, SQUARE) == pytest.approx(expected, rel=1e-9)


def test_degenerate_or_mismatched_maps_are_never_close():
    assert similarity_distance(SQUARE, SQUARE[:3]) == np.inf
    assert similarity_distance(SQUARE, np.zeros_like(SQUARE)) == np.inf
    broken = SQUARE.copy()
    broken[0, 0] = np.nan
    assert similarity_distance(SQUARE, broken) == np.inf


def test_group_maps_joins_similar_maps_and_keeps_the_rest_apart():
    rng = np.random.default_rng(1)
    points = rng.normal(size=(40, 3))
    uv = points[:, :2]
    sheared = uv @ np.array([[1.0, 0.2], [0.0, 1.0]])
    labels = ["scp", "ocp", "scp-igl", "lle"]
    groups = group_maps(labels, [points] * 4, [uv, sheared, similar(uv), sheared + 1e-9])
    assert [g.members for g in groups] == [["scp", "scp-igl"], ["ocp", "lle"]]
    assert [g.indices for g in groups] == [[0, 2], [1, 3]]


def test_group_maps_needs_equal_keys_and_equal_points():
    rng = np.random.default_rng(2)
    points = rng.normal(size=(30, 3))
    uv = points[:, :2]
    groups = group_maps(["a", "b"], [points, points], [uv, uv], keys=[(0, "ok"), (3, "ok")])
    assert len(groups) == 2  # different foldover counts: their panel titles would differ
    moved = points + np.array([0.0, 0.0, 1.0])
    assert len(group_maps(["a", "b"], [points, moved], [uv, uv])) == 2


def test_groups_do_not_chain():
    # b is within the tolerance of a and c of b, but c is not of a: c starts its own group.
    uv = SQUARE
    step = 1.4 * SAME_MAP_TOLERANCE  # a small shear s is at distance about s / 2: 0.7 of the tolerance
    b = uv @ np.array([[1.0, step], [0.0, 1.0]])
    c = uv @ np.array([[1.0, 2 * step], [0.0, 1.0]])
    assert similarity_distance(uv, b) <= SAME_MAP_TOLERANCE < similarity_distance(uv, c)
    assert similarity_distance(b, c) <= SAME_MAP_TOLERANCE
    points = np.column_stack([uv, np.zeros(4)])
    groups = group_maps(["a", "b", "c"], [points] * 3, [uv, b, c])
    assert [g.members for g in groups] == [["a", "b"], ["c"]]


def test_group_maps_refuses_sequences_of_different_lengths():
    with pytest.raises(ValueError, match="one of each per map"):
        group_maps(["a", "b"], [SQUARE], [SQUARE, SQUARE])


def test_group_label_names_members_and_counts_the_rest():
    assert MapGroup(["scp", "scp-igl"], [0, 1]).label() == "scp = scp-igl"
    long = MapGroup(["bff-mouette", "dncp-opt", "fbcp-pc", "fbcp-pc [boundary=given]", "ocp", "scp"], list(range(6)))
    label = long.label(max_chars=30)
    assert label == "bff-mouette = dncp-opt (+4 more)"
