"""Where a surface comes nearer itself than its sampling resolves: noise past a gap's middle, touching parts."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import norm

from parambench.bench.metrics.surface_contact import misplaced_by_noise, touching_points
from parambench.datasets_gen.registry import make_surface
from parambench.datasets_gen.surface import Surface

SPACING = 0.1
GAP = 0.3  # 3 spacings between the sheets: the middle of the gap is 0.15 from either


def _sheet(z: float) -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(11) * SPACING
    x, y = np.meshgrid(t, t, indexing="ij")
    points = np.c_[x.ravel(), y.ravel(), np.full(x.size, z)]
    idx = np.arange(x.size).reshape(11, 11)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    return points, np.vstack([np.c_[a, b, c], np.c_[a, c, d]])


def _two_sheets(gap: float = GAP) -> Surface:
    lower, faces = _sheet(0.0)
    upper, _ = _sheet(gap)
    return Surface(points=np.vstack([lower, upper]), faces=np.vstack([faces, faces + len(lower)]))


def test_exactly_the_points_moved_past_the_middle_of_the_gap_are_misplaced():
    clean = _two_sheets()
    n = len(clean.points) // 2
    shift = np.zeros(2 * n)
    shift[:n:3] = 0.2  # lower sheet, towards the upper one past the middle (0.15): misplaced
    shift[1:n:3] = 0.1  # towards it, short of the middle: not
    shift[2:n:3] = -0.25  # away from it: not, however far
    shift[n::2] = -0.2  # upper sheet, towards the lower one past the middle: misplaced
    noisy = Surface(points=clean.points + np.c_[np.zeros((2 * n, 2)), shift], faces=clean.faces)
    expected = np.zeros(2 * n, dtype=bool)
    expected[:n:3] = True
    expected[n::2] = True
    assert np.array_equal(misplaced_by_noise(noisy, clean), expected)


def test_a_clean_surface_and_a_single_noisy_sheet_have_no_misplaced_point():
    fold = make_surface("fold", 2000, sampling="jittered", seed=0, noise=0.0)
    assert not misplaced_by_noise(fold, fold).any()
    bump = [make_surface("bump", 2000, sampling="jittered", seed=0, noise=s) for s in (0.5, 0.0)]
    assert not misplaced_by_noise(*bump).any()


def test_the_noisy_fold_loses_the_share_its_gap_and_noise_predict():
    # Gaussian noise of 0.5 spacings along the normal against sheets 2 to 2.5 spacings
    # apart: a sheet point crosses the middle with probability Phi(-2.5) to Phi(-2)
    # (0.6 % to 2.3 %); the bend's points (a few per cent of all) cannot cross.
    for sampling in ("jittered", "random"):
        noisy, clean = (make_surface("fold", 2000, sampling=sampling, seed=1, noise=s) for s in (0.5, 0.0))
        share = misplaced_by_noise(noisy, clean).mean()
        assert norm.cdf(-2.5) * 0.5 < share < norm.cdf(-2.0) * 1.5


def test_sheets_nearer_than_half_their_edge_length_touch_and_farther_ones_do_not():
    # Edge lengths: 0.1 along the grid, 0.141 on the diagonals; a vertex's mean lies
    # between 0.1 (two corners have no diagonal) and (4 x 0.1 + 2 x 0.141) / 6 = 0.114.
    assert touching_points(_two_sheets(0.045)).all()  # 0.045 < 0.5 x 0.1
    assert not touching_points(_two_sheets(0.06)).any()  # 0.06 > 0.5 x 0.114
    assert not touching_points(_two_sheets(0.045), touch=0.35).any()  # 0.045 > 0.35 x 0.114
    # One sheet bent back on itself is one part where its layers join and two elsewhere:
    # only vertices beyond 3 edge lengths of the bend along the sheet count.
    single = _two_sheets(0.045)
    seam = Surface(points=single.points, faces=np.vstack([single.faces, [[0, 121, 1]]]))  # one face bridges them
    touching = touching_points(seam)
    corner = np.linalg.norm(seam.points[:, :2], axis=1)
    assert not touching[corner < 0.1].any() and touching[corner > 0.5].all()


def test_generated_gaps_of_two_spacings_do_not_touch_and_the_camel_s_lips_do():
    for name in ("fold", "slit"):
        assert not touching_points(make_surface(name, 2000, sampling="random", seed=0)).any()
    assert touching_points(make_surface("real/camelhead", seed=0)).sum() > 50


def test_mismatched_surfaces_are_refused():
    clean = _two_sheets()
    with pytest.raises(ValueError, match="not one sampling"):
        misplaced_by_noise(Surface(points=clean.points[:-1]), clean)
    with pytest.raises(ValueError, match="faces"):
        misplaced_by_noise(clean, Surface(points=clean.points))
    with pytest.raises(ValueError, match="positive"):
        misplaced_by_noise(clean, clean, far=0.0)
    with pytest.raises(ValueError, match="faces"):
        touching_points(Surface(points=clean.points))
    with pytest.raises(ValueError, match="touch=0"):
        touching_points(clean, touch=0.0)
