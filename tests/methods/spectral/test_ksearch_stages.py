"""The stages of line_search on their own: memoised landscape, bracketing, narrowing, minimising, best map."""

from __future__ import annotations

import numpy as np
import pytest

from parambench.datasets_gen.errors import ConvergenceError, InvalidInputError
from parambench.methods.spectral.ksearch import (KPoint, _best_regular, _check_bracket, _find_bracket, _Landscape, _minimise,
                                      _narrow_bracket, penalized_energy)


def staircase(k_opt: float, width: float = 0.05):
    """q = k - k_opt; the map spins (t = 2, 3, ...) below k_opt - width, regular above."""

    def evaluate(k: float) -> KPoint:
        t = 1 if k >= k_opt - width else 2 + int((k_opt - width - k) / width)
        return KPoint(k=k, energy=k - k_opt, turning=np.array([t]))

    return evaluate


class Counting:
    def __init__(self, evaluate):
        self.evaluate, self.calls = evaluate, []

    def __call__(self, k):
        self.calls.append(k)
        return self.evaluate(k)


def test_landscape_memoises_and_records_in_order():
    counting = Counting(staircase(2.0))
    ev = _Landscape(counting, r=3.0)
    a = ev(1.0)
    assert ev(np.float64(1.0)) is a and ev(1) is a  # one key per float value
    ev(2.5)
    assert counting.calls == [1.0, 2.5] and all(type(k) is float for k in counting.calls)
    assert ev.record["k"] == [1.0, 2.5] and ev.record["q"] == [-1.0, 0.5]
    assert ev.record["t"] == [[20], [1]] and a.turning.tolist() == [20]
    assert ev.record["E"] == [penalized_energy(a, 3.0), 0.25]
    assert list(ev.points) == [1.0, 2.5]


def test_check_bracket():
    ev = _Landscape(staircase(2.0), 10.0)
    lo, hi = _check_bracket(ev, (np.float32(1.5), 3))
    assert (lo, hi) == (1.5, 3.0) and type(lo) is float
    with pytest.raises(InvalidInputError, match="0 < lower < upper"):
        _check_bracket(ev, (3.0, 1.0))
    with pytest.raises(ConvergenceError, match="at k = 1.8 the boundary turning"):
        _check_bracket(ev, (1.0, 1.8))
    with pytest.raises(ConvergenceError, match="lower the bracket"):
        _check_bracket(ev, (2.5, 3.0))


@pytest.mark.parametrize("k_opt", [0.37, 1.0, 3.46])
def test_find_bracket_steps_towards_the_transition(k_opt):
    ev = _Landscape(staircase(k_opt, 0.01 * k_opt), 10.0)
    lo, hi = _find_bracket(ev, 1.0, 1.25, 40)
    assert not ev(lo).good and ev(hi).good
    assert np.isclose(hi / lo, 1.25)  # adjacent geometric steps
    # only k0 and the steps were evaluated, all on the geometric grid
    assert np.allclose(np.log(ev.record["k"]) / np.log(1.25), np.round(np.log(ev.record["k"]) / np.log(1.25)))


def test_find_bracket_bisects_a_good_region_narrower_than_a_step():
    def evaluate(k):  # regular with q < 0 below 1.3, good on [1.3, 1.3005), spinning above
        return KPoint(k=k, energy=k - 1.3, turning=np.array([1 if k < 1.3005 else 2]))

    ev = _Landscape(evaluate, 10.0)
    lo, hi = _find_bracket(ev, 1.0, 1.25, 40)
    assert not ev(lo).good and ev(hi).good and 1.3 <= hi < 1.3005


def test_find_bracket_gives_up_after_max_steps():
    with pytest.raises(ConvergenceError, match="stepping up from k = 1 to k = 1.25 in 1 steps"):
        _find_bracket(_Landscape(staircase(1e9), 10.0), 1.0, 1.25, 1)


def test_narrow_bracket_keeps_the_transition_inside():
    ev = _Landscape(staircase(1.0, width=1e-5), 10.0)
    lo, hi = _narrow_bracket(ev, 0.8, 1.0, 1e-4, 40)
    assert hi / lo - 1 <= 1e-4 and not ev(lo).good and ev(hi).good
    assert _narrow_bracket(ev, 0.8, 1.0, 1e-4, 0) == (0.8, 1.0)


def test_minimise_leaves_its_evaluations_in_the_landscape():
    ev = _Landscape(staircase(2.0), 10.0)
    _minimise(ev, 1.99, 2.2, 10.0, 1e-9, 100)
    assert len(ev.points) > 5 and min(abs(k - 2.0) for k in ev.points) < 1e-6
    with pytest.raises(ConvergenceError, match="did not converge"):
        _minimise(_Landscape(staircase(2.0), 10.0), 1.9, 2.2, 10.0, 1e-12, 2)


def test_best_regular_polishes_to_the_zero_of_q():
    ev = _Landscape(staircase(2.0, width=0.5), 10.0)
    for k in (1.6, 1.9, 2.3):  # regular maps with q < 0 and q > 0 straddle k_opt = 2
        ev(k)
    best = _best_regular(ev, 1.6, 2.3, 10.0)
    assert best.regular and abs(best.k - 2.0) < 1e-14 and abs(best.energy) < 1e-14


def test_best_regular_refuses_an_all_spinning_landscape():
    ev = _Landscape(staircase(2.0), 10.0)
    ev(1.0)
    ev(1.5)
    with pytest.raises(ConvergenceError, match=r"every map evaluated in \[1, 1.5\] spins"):
        _best_regular(ev, 1.0, 1.5, 10.0)
