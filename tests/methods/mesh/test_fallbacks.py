"""The mesh methods' fallbacks: other pin pairs (by hand on a polygon) and the order attempts run in."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from parambench.datasets_gen.errors import ConvergenceError, SolverError
from parambench.datasets_gen.surface import MethodInput
from parambench.methods.hints import Hint, hinted
from parambench.methods.mesh.fallbacks import PIN_ALTERNATIVES, Attempt, first_regular, mesh_attempts
from parambench.methods.mesh.pins import farthest_pair, opposite_pairs


def polygon(n: int, radii=None) -> np.ndarray:
    ang = 2 * np.pi * np.arange(n) / n
    r = np.ones(n) if radii is None else np.asarray(radii, dtype=float)
    return np.column_stack([r * np.cos(ang), r * np.sin(ang), np.zeros(n)])


@pytest.mark.parametrize("nudge", [0.0, 1e-15, -1e-15])
def test_farthest_pair_breaks_rounding_ties_by_candidate_order(nudge):
    # a square's two diagonals tie; a last-bit difference (as different scipy releases
    # round) must not decide which one is taken: the first pair in candidate order wins
    square = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0 + nudge, 0.0], [0.0, 1.0, 0.0]])
    assert farthest_pair(square, np.array([0, 1, 2, 3])) == (0, 2)
    assert farthest_pair(square, np.array([1, 3, 0, 2])) == (1, 3)
    assert farthest_pair(square, np.array([3, 0, 1, 2]), chunk=1) == (3, 1)


def test_farthest_pair_breaks_ties_by_the_points_where_they_differ():
    """A square whose inside is not symmetric: of its two tied diagonals, the one the points favour
    (the smaller sum of distances to the nearer pin), whatever the order of the candidates (the
    first in candidate order was taken: lscm-igl on a shuffled copy of a jittered grid gave
    another map)."""
    square = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]])
    inside = np.array([[0.2, 0.25, 0.0], [0.3, 0.2, 0.0]])  # near corner 0: its diagonal serves them better
    points = np.vstack([square, inside])
    for order in ([0, 1, 2, 3], [1, 3, 0, 2], [3, 2, 1, 0]):
        assert set(farthest_pair(points, np.array(order), chunk=1 if order[0] == 3 else 2048)) == {0, 2}
    moved = np.vstack([square, [[0.8, 0.25, 0.0], [0.7, 0.2, 0.0]]])  # now the inside lies near corner 1
    assert set(farthest_pair(moved, np.array([0, 1, 2, 3]))) == {1, 3}


def test_farthest_pair_finds_a_clear_maximum_across_chunks():
    rng = np.random.default_rng(0)
    pts = rng.random((300, 3))
    d = np.linalg.norm(pts[:, None] - pts[None], axis=2)
    i, j = np.unravel_index(np.argmax(d), d.shape)
    assert set(farthest_pair(pts, np.arange(300), chunk=7)) == {int(i), int(j)}


def test_opposite_pairs_on_a_regular_polygon_by_hand():
    # 16 equal sides, start at vertex 0, 3 pairs: shifts of 1/8, 2/8, 3/8 of the perimeter
    # (2, 4, 6 sides), each paired with the vertex half the perimeter (8 sides) further
    pts = polygon(16)
    loop = np.arange(16)
    assert opposite_pairs(pts, loop, 0, 3) == [(2, 10), (4, 12), (6, 14)]
    # the shifts start at `start`, wherever it sits in the loop order
    assert opposite_pairs(pts, np.roll(loop, 5), 3, 3) == [(5, 13), (7, 15), (9, 1)]


def test_opposite_pairs_follow_arc_length_not_vertex_count():
    # vertices 0..7 on the upper half of the circle (8 short sides up to vertex 8), 8..11 on
    # the lower half (4 long sides): a quarter of the perimeter from 0 is vertex 4, and half
    # the perimeter further vertex 10; counting vertices would give (3, 9)
    ang = np.concatenate([np.linspace(0, np.pi, 9)[:-1], np.linspace(np.pi, 2 * np.pi, 5)[:-1]])
    pts = np.column_stack([np.cos(ang), np.sin(ang), np.zeros_like(ang)])
    assert opposite_pairs(pts, np.arange(12), 0, 1) == [(4, 10)]


def test_opposite_pairs_drop_repeats_on_short_loops():
    pts = polygon(4)
    pairs = opposite_pairs(pts, np.arange(4), 0, 6)
    assert len(pairs) == len({frozenset(p) for p in pairs}) and all(a != b for a, b in pairs)
    assert len(pairs) <= 2


def fake(turning, regular_boundary=True):
    """What solve_with_holes returns, reduced to what first_regular reads."""
    sol = SimpleNamespace(turning=np.array(turning), diagnostics={"regular_boundary": regular_boundary})
    return ((None, sol, None, {}), None, 0)


def failing(message="no regular scp map at any k: the line search failed"):
    def run():
        raise hinted(ConvergenceError, message, Hint("try other weights", "weights"))
    return run


def test_first_regular_returns_the_first_attempt_untouched_when_it_is_regular():
    calls = []
    first = fake([1, -1])
    out, diag = first_regular([Attempt("as asked", lambda: first),
                               Attempt("b", lambda: calls.append("b") or fake([1]), {"x": 1})])
    assert out is first and diag == {} and calls == []


def test_first_regular_skips_failing_and_irregular_attempts():
    good = fake([1])
    out, diag = first_regular([Attempt("as asked", failing()),
                               Attempt("b", lambda: fake([2]), {"which": "b"}),
                               Attempt("c", failing("also bad")),
                               Attempt("d", lambda: good, {"which": "d"}),
                               Attempt("e", lambda: fake([1]), {"which": "e"})])
    assert out is good
    assert diag == {"which": "d", "fallback_reason": "no regular scp map at any k: the line search failed"}


def test_first_regular_keeps_an_irregular_first_map_when_nothing_is_regular():
    first = fake([1], regular_boundary=False)
    out, diag = first_regular([Attempt("as asked", lambda: first), Attempt("b", failing())])
    assert out is first and diag == {}
    # an irregular first map is replaced by a regular fallback, which says why
    out, diag = first_regular([Attempt("as asked", lambda: fake([3])), Attempt("b", lambda: fake([1]), {"b": 1})])
    assert diag["b"] == 1 and "turning numbers [3]" in diag["fallback_reason"]


def test_first_regular_raises_the_first_error_naming_the_fallbacks():
    with pytest.raises(ConvergenceError) as info:
        first_regular([Attempt("as asked", failing()), Attempt("pins=1,2", failing("x")),
                       Attempt("uniform_at='negative'", lambda: (_ for _ in ()).throw(SolverError("y")))])
    msg = str(info.value)
    assert msg.startswith("no regular scp map at any k")
    assert "also without a regular map: pins=1,2, uniform_at='negative'" in msg
    assert msg.endswith("; try other weights.")
    # a single attempt re-raises its own error unchanged
    with pytest.raises(ConvergenceError, match=r"^no regular scp map at any k: the line search failed; try"):
        first_regular([Attempt("as asked", failing())])


def fan_disk(n: int = 16) -> MethodInput:
    """A regular n-gon fanned around its centre (vertex n): one boundary loop 0..n-1."""
    pts = np.vstack([polygon(n), [[0.0, 0.0, 0.0]]])
    faces = np.array([[i, (i + 1) % n, n] for i in range(n)], dtype=np.int64)
    return MethodInput(pts, faces, name="fan")


def recorder(regular_when):
    calls = []

    def solve(uniform_at, pair):
        calls.append((uniform_at, pair))
        return fake([1] if regular_when(uniform_at, pair) else [2])
    return solve, calls


def test_mesh_attempts_order_weights_then_pins():
    s = fan_disk()
    solve, calls = recorder(lambda ua, pair: pair is not None and ua == "negative" and pair == (5, 13))
    out, diag = first_regular(mesh_attempts(solve, s, weights="authalic", uniform_at=None, pins="farthest"))
    farthest = [0, 8]   # the first pair of equal distances on a regular 16-gon
    pairs = opposite_pairs(s.points, np.arange(16), farthest[0], PIN_ALTERNATIVES)
    assert len(pairs) == PIN_ALTERNATIVES
    # as asked, the authalic rows, every other pair as asked, then the pairs with the rows
    expect = [(None, None), ("negative", None)] + [(None, p) for p in pairs]
    expect += [("negative", p) for p in pairs[: pairs.index((5, 13)) + 1]]
    assert calls == expect
    assert diag["authalic_fallback"] == "negative" and diag["pins_farthest"] == farthest
    assert diag["pins_fallback"] == pairs.index((5, 13)) + 1


def test_mesh_attempts_keep_given_pins_and_given_rows():
    s = fan_disk()
    assert [a.label for a in mesh_attempts(lambda *a: None, s, weights="authalic", uniform_at=None,
                                           pins="3,11")] == ["as asked", "uniform_at='negative'"]
    assert [a.label for a in mesh_attempts(lambda *a: None, s, weights="authalic", uniform_at="negative",
                                           pins="farthest")][:2] == ["as asked", "6 other pin pairs"]
    # scp: no pins, and no fallback for weights other than authalic
    assert len(mesh_attempts(lambda *a: None, s, weights="mean-value", uniform_at=None)) == 1
