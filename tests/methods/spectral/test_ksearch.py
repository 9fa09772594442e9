"""The k line search on synthetic landscapes with a known optimum, and its failure paths."""

from __future__ import annotations

import numpy as np
import pytest

from parambench.datasets_gen.errors import ConvergenceError, InvalidInputError
from parambench.methods.spectral.ksearch import KPoint, line_search, penalized_energy


def staircase(k_opt: float, width: float = 0.05):
    """q = k - k_opt; the map spins (t = 2, 3, ...) below k_opt - width, regular above."""

    def evaluate(k: float) -> KPoint:
        t = 1 if k >= k_opt - width else 2 + int((k_opt - width - k) / width)
        return KPoint(k=k, energy=k - k_opt, turning=np.array([t]))

    return evaluate


@pytest.mark.parametrize("k_opt", [0.37, 0.99995, 1.0, 3.46, 40.0])
def test_finds_known_optimum_up_or_down(k_opt):
    res = line_search(staircase(k_opt, width=0.01 * k_opt))
    assert abs(res.k_opt - k_opt) <= 1e-12 * k_opt
    assert res.best.regular and abs(res.best.energy) <= 1e-12 * k_opt
    lo, hi = res.bracket
    assert lo < k_opt <= hi
    land = res.landscape
    assert len(land["k"]) == len(land["E"]) == len(land["q"]) == len(land["t"]) == res.n_evaluations
    assert np.isclose(land["E"][0], penalized_energy(staircase(k_opt, 0.01 * k_opt)(1.0)))


def test_narrow_bowl_is_found():
    # regular only within 1e-5 of the optimum, as for cotangent DNCP on a disk
    res = line_search(staircase(0.99996, width=1e-5))
    assert abs(res.k_opt - 0.99996) < 1e-12


def test_penalty_blocks_lower_spinning_bowls():
    # A spinning map (t = 2) with energy exactly zero at k = 0.5 must not win.
    def evaluate(k):
        if abs(k - 0.5) < 0.2:
            return KPoint(k=k, energy=0.0, turning=np.array([2]))
        return staircase(1.2, 0.1)(k)

    res = line_search(evaluate)
    assert abs(res.k_opt - 1.2) < 1e-10


def test_bracket_without_crossing_raises():
    with pytest.raises(ConvergenceError, match="no t = 1 crossing in the k bracket"):
        line_search(staircase(2.0), bracket=(0.5, 1.0))
    with pytest.raises(ConvergenceError, match="lower the bracket"):
        line_search(staircase(2.0), bracket=(2.5, 3.0))
    res = line_search(staircase(2.0), bracket=(1.0, 3.0))
    assert abs(res.k_opt - 2.0) < 1e-12


def test_no_crossing_anywhere_raises():
    def always_spinning(k):
        return KPoint(k=k, energy=-1.0, turning=np.array([3]))

    with pytest.raises(ConvergenceError, match="no t = 1 crossing found stepping up"):
        line_search(always_spinning, max_steps=10)


def test_bad_arguments():
    with pytest.raises(InvalidInputError):
        line_search(staircase(1.0), k0=0.0)
    with pytest.raises(InvalidInputError):
        line_search(staircase(1.0), growth=1.0)
    with pytest.raises(InvalidInputError):
        line_search(staircase(1.0), bracket=(2.0, 1.0))


def test_good_region_narrower_than_a_step_above_a_regular_start():
    # Regular with q < 0 at k = 1, regular only up to 1.0005 above k_opt = 1.0002, then
    # spinning: the geometric step (x1.25) jumps over the good region, so it is bisected.
    def evaluate(k):
        t = 1 if k <= 1.0005 else 3
        return KPoint(k=k, energy=k - 1.0002, turning=np.array([t, -1]))

    res = line_search(evaluate)
    assert abs(res.k_opt - 1.0002) < 1e-12
    assert res.best.turning.tolist() == [1, -1]


def test_root_search_near_finds_the_zero_of_line_search_in_few_evaluations():
    from parambench.methods.spectral.ksearch import root_search_near

    # q slightly curved, k_opt moved by 3e-5 relative from the estimate: the answer is
    # line_search's to its polish tolerance, in a handful of evaluations instead of ~20.
    def evaluate(k):
        return KPoint(k=k, energy=8e-3 * (k - 1.00003) + 0.05 * (k - 1.00003) ** 2, turning=np.array([1]))

    full = line_search(evaluate)
    for start in (1.0, 1.0001, 1.00003):
        near = root_search_near(evaluate, start)
        assert near is not None and near.best.regular
        assert abs(near.k_opt / full.k_opt - 1) < 1e-12
        assert near.n_evaluations <= 7 < full.n_evaluations
        assert near.bracket[0] <= near.k_opt <= near.bracket[1]
        assert len(near.landscape["k"]) == near.n_evaluations


def test_root_search_near_hands_back_what_it_cannot_settle():
    from parambench.methods.spectral.ksearch import root_search_near

    # Spinning at the estimate, spinning before q changes sign, no sign change within
    # the width: None, so the caller runs the full line search.
    assert root_search_near(staircase(1.0, width=0.01), 0.95) is None
    assert root_search_near(staircase(1.0, width=1e-6), 1.0 + 1e-6, width=1e-3) is not None
    assert root_search_near(staircase(1.0, width=1e-7), 1.0 + 1e-6, first_step=1e-4) is None
    assert root_search_near(staircase(1.1), 1.0, width=1e-3) is None
    # An exact zero at the estimate is the answer.
    res = root_search_near(staircase(1.0), 1.0)
    assert res.k_opt == 1.0 and res.n_evaluations == 1
