"""Local self-crossings of boundary loops are undone; everything else is left alone."""

from __future__ import annotations

import numpy as np
import pytest

from parambench.methods.geometry2d import turning_number
from parambench.methods.pointset.loop_untangle import MAX_OFFSET, local_crossings, untangle_loop, untangle_loops


def _wavy_loop(n: int = 60, seed: int = 0, wave: float = 0.15):
    """Points of a star-shaped closed curve in the z = 0 plane, in order, with +z normals.

    Unevenly spaced; ``wave=0`` gives a circle, where a reversed run has one order
    without crossings (the original), so the untangled loop can be compared exactly.
    """
    rng = np.random.default_rng(seed)
    theta = np.sort(rng.uniform(0, 2 * np.pi, n))
    r = 1.0 + wave * np.sin(5 * theta)
    points = np.c_[r * np.cos(theta), r * np.sin(theta), np.zeros(n)]
    normals = np.tile([0.0, 0.0, 1.0], (n, 1))
    return points, normals, np.arange(n, dtype=np.int64)


def _crossing_count(points, loop):
    """All proper self-crossings of the closed polygon (brute force, any offset)."""
    z = points[loop, :2]
    a, b = z, np.roll(z, -1, axis=0)
    count = 0
    for i in range(len(z)):
        for j in range(i + 2, len(z) - (i == 0)):
            d1, d2 = b[i] - a[i], b[j] - a[j]
            den = d1[0] * d2[1] - d1[1] * d2[0]
            if den == 0:
                continue
            q = a[j] - a[i]
            s = (q[0] * d2[1] - q[1] * d2[0]) / den
            t = (q[0] * d1[1] - q[1] * d1[0]) / den
            count += bool(0 < s < 1 and 0 < t < 1)
    return count


def test_a_clean_loop_is_left_as_it_is():
    points, normals, loop = _wavy_loop()
    assert _crossing_count(points, loop) == 0
    fixed, moves = untangle_loop(points, normals, loop)
    assert moves == 0 and np.array_equal(fixed, loop)


@pytest.mark.parametrize("span", [2, 3, MAX_OFFSET])
def test_reversed_runs_are_put_back_in_order(span):
    points, normals, loop = _wavy_loop(wave=0.0)
    tangled = loop.copy()
    starts = [3, 20, 41]
    for s in starts:
        tangled[s:s + span] = tangled[s:s + span][::-1]
    assert _crossing_count(points, tangled) >= len(starts)
    assert len(local_crossings(points, normals, tangled)) >= len(starts)
    fixed, moves = untangle_loop(points, normals, tangled)
    assert np.array_equal(fixed, loop) and moves == len(starts)
    assert _crossing_count(points, fixed) == 0
    assert turning_number(points[fixed, :2]) == pytest.approx(1.0)


def test_a_curl_across_the_loops_start_is_undone():
    points, normals, loop = _wavy_loop(wave=0.0)
    tangled = loop.copy()
    tangled[[0, -1]] = tangled[[-1, 0]]  # the last and first point swapped
    assert _crossing_count(points, tangled) == 1
    fixed, _ = untangle_loop(points, normals, tangled)
    assert _crossing_count(points, fixed) == 0
    assert sorted(fixed.tolist()) == loop.tolist()


def test_a_far_crossing_is_not_hidden():
    # A figure eight: its crossing is between edges half a loop apart, a surface the
    # sampling does not resolve, not a curl; it must stay for the self-check to see.
    t = np.linspace(0, 2 * np.pi, 40, endpoint=False) + np.pi / 40  # no sample at the crossing
    points = np.c_[np.sin(t), np.sin(t) * np.cos(t), np.zeros_like(t)]
    normals = np.tile([0.0, 0.0, 1.0], (t.size, 1))
    loop = np.arange(t.size, dtype=np.int64)
    assert _crossing_count(points, loop) == 1
    fixed, moves = untangle_loop(points, normals, loop)
    assert moves == 0 and np.array_equal(fixed, loop)


def test_crossings_are_seen_in_each_points_tangent_plane():
    # The same tangled loop tilted out of the xy plane, normals tilted with it: the
    # crossings are found and undone as before.
    points, normals, loop = _wavy_loop(wave=0.0)
    c, s = np.cos(0.7), np.sin(0.7)
    rot = np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    tangled = loop.copy()
    tangled[10:13] = tangled[10:13][::-1]
    fixed, moves = untangle_loop(points @ rot.T, normals @ rot.T, tangled)
    assert moves == 1 and np.array_equal(fixed, loop)


def test_every_loop_is_untangled_and_moves_are_counted():
    points, normals, loop = _wavy_loop(wave=0.0)
    a = loop.copy()
    a[5:7] = a[5:7][::-1]
    out, moves = untangle_loops(points, normals, [a, loop])
    assert np.array_equal(out[0], loop) and np.array_equal(out[1], loop) and moves == 1


def test_the_rims_of_a_fold_are_not_taken_for_a_curl():
    # Around the crease of ``fold`` the loop bends out of every tangent plane within a few
    # steps, and the two sheets' rims project across each other. Unguarded, 16 moves
    # reordered that loop and ocp found no map; the normals' and the 3D-length guards keep it.
    from parambench.datasets_gen.registry import make_surface
    from parambench.methods.pointset.frontend import build_frontend

    fold = make_surface("fold", 5000, sampling="jittered", seed=0)
    front = build_frontend(fold.points)
    assert front.diagnostics["boundary"]["n_untangled"] == 0
    assert len(front.boundary_loops) == len(fold.boundary_loops) == 1


def test_segments_cross_only_properly():
    from parambench.methods.geometry2d import segments_cross

    p, q = np.array([0.0, 0.0]), np.array([2.0, 0.0])
    assert segments_cross(p, q, np.array([1.0, -1.0]), np.array([1.0, 1.0]))
    assert not segments_cross(p, q, np.array([3.0, -1.0]), np.array([3.0, 1.0]))  # beyond q
    assert not segments_cross(p, q, q, np.array([3.0, 1.0]))  # a shared end only touches
    assert not segments_cross(p, q, np.array([1.0, 0.0]), np.array([1.0, 1.0]))  # an end on pq touches
    # Broadcast: one segment against a (2, 3) grid of others.
    a = np.array([[[0.5, -1.0], [1.5, 1.0], [5.0, -1.0]], [[0.5, 1.0], [0.5, 0.5], [1.0, -2.0]]])
    b = a + np.array([0.0, 2.0]) * np.where(a[..., 1:] < 0, 1.0, -1.0)  # vertical, across y = 0 or onto it
    np.testing.assert_array_equal(segments_cross(p, q, a, b), [[True, True, False], [True, True, False]])
