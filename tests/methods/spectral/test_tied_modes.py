"""Tied lowest modes of an annulus: the map with the longest loop outside, not a roundoff mix."""

from __future__ import annotations

import numpy as np
import pytest

from parambench.methods.spectral.tied_modes import outer_rim_mode, tied_pair


def _two_rims(n: int = 40):
    """The two pure maps of a flat annulus (radii 1 and e), sampled on its rims only."""
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    inner, outer = np.exp(1j * t), np.e * np.exp(1j * t)
    points = np.c_[np.r_[inner.real, outer.real], np.r_[inner.imag, outer.imag], np.zeros(2 * n)]
    loops = [np.arange(n), np.arange(n, 2 * n)]
    pure_outer = np.r_[inner, outer]  # the identity: the long rim outside
    pure_inner = np.e / np.r_[inner, outer]  # the inversion: the short rim outside
    return points, loops, pure_outer, pure_inner


def _aligned(a: np.ndarray, b: np.ndarray) -> float:
    """|<a, b>| / (|a| |b|): 1 when a is b up to a complex factor."""
    return float(abs(np.vdot(a, b)) / (np.linalg.norm(a) * np.linalg.norm(b)))


@pytest.mark.parametrize("angle", [0.3, 0.8, 1.3])
def test_a_mix_of_tied_maps_gives_the_one_with_the_long_rim_outside(angle):
    points, loops, pure_outer, pure_inner = _two_rims()
    mix = np.c_[np.cos(angle) * pure_outer + np.sin(angle) * 1j * pure_inner,
                -np.sin(angle) * pure_outer + np.cos(angle) * 1j * pure_inner]
    z = outer_rim_mode(mix, None, loops, points)
    assert _aligned(z, pure_outer) == pytest.approx(1.0, abs=1e-12)
    assert abs(z.mean()) < 1e-12 and np.linalg.norm(z) == pytest.approx(1.0)
    # Without the points the loop with more vertices is the outer one: here the second.
    more = [loops[0][::2], loops[1]]
    assert _aligned(outer_rim_mode(mix, None, more), pure_outer) == pytest.approx(1.0, abs=1e-12)
    # The outer loop is the long one whichever is listed first.
    assert _aligned(outer_rim_mode(mix, None, loops[::-1], points), pure_outer) == pytest.approx(1.0, abs=1e-12)


def test_tied_pair_is_measured_against_the_third_value():
    assert tied_pair(np.array([0.0, 1e-8, 1e-4]))  # a k search's crossing: both maps zero there
    assert tied_pair(np.array([1.2471e-5, 1.2477e-5, 1.261e-4]))  # an open cylinder, vertices moved
    assert not tied_pair(np.array([5.33e-6, 1.86e-5, 7.87e-5]))  # a frustum, rims 30 % apart
    assert not tied_pair(np.array([1.0, 1.0]))  # no third value to measure against


def test_jittered_points_of_an_open_cylinder_map_on_the_first_run():
    """Before: the tied pair's mix failed its self-check (coherent Beltrami 0.46, 80 points outside
    the loops) until the fourth retry, 7.9 s instead of 2.5."""
    from parambench.bench.metrics.jacobian import per_face_qc
    from parambench.datasets_gen.surface import Surface
    from parambench.methods.registry import get_method

    rng = np.random.default_rng(0)
    n_round, n_up = 100, 17
    t, h = np.meshgrid(np.linspace(0, 2 * np.pi, n_round, endpoint=False), np.linspace(0.0, 1.0, n_up), indexing="ij")
    t, h = t.ravel(), h.ravel()
    t = t + rng.uniform(-0.2, 0.2, t.size) * 2 * np.pi / n_round
    h = np.clip(h + np.where((h > 0) & (h < 1), rng.uniform(-0.2, 0.2, h.size) / (n_up - 1), 0), 0, 1)
    pts = np.c_[np.cos(t), np.sin(t), h]
    i, j = np.meshgrid(np.arange(n_round), np.arange(n_up - 1), indexing="ij")
    a, b = (i * n_up + j).ravel(), ((i + 1) % n_round * n_up + j).ravel()
    mesh = Surface(pts, np.r_[np.c_[a, b, b + 1], np.c_[a, b + 1, a + 1]], name="jittered open cylinder")

    result = get_method("ocp")(mesh.points_only())
    check = result.diagnostics["selfcheck"]
    assert check["passed"] and not check.get("retry") and not check.get("kept")
    qc = per_face_qc(mesh.points, mesh.faces, result.uv).mean()
    reference = per_face_qc(mesh.points, mesh.faces, get_method("scp")(mesh).uv).mean()
    assert qc <= 1.03 * reference  # issue #11.2's bound (measured 1.0573 against 1.0471)


def test_random_points_of_an_open_cylinder_get_round_rims():
    """2,000 random points of a cylinder 1.5 high, rims sampled densely: its exact maps are
    annuli with radii e^1.5 apart. With ties judged at 1 % of the gap, the point-set pair
    (0.7-7 % of it here over the k search) was left mixed: the map passed its self-check
    with rims 24 % off round and a radius ratio of 4.68 (the next seed raised
    ConvergenceError)."""
    from parambench.datasets_gen.surface import Surface
    from parambench.methods.registry import get_method

    rng = np.random.default_rng(2)
    n, n_rim, height = 2000, 109, 1.5
    t, h = rng.uniform(0, 2 * np.pi, n), rng.uniform(0, height, n)
    tr = np.linspace(0, 2 * np.pi, n_rim, endpoint=False)
    pts = np.r_[np.c_[np.cos(t), np.sin(t), h], np.c_[np.cos(tr), np.sin(tr), np.zeros(n_rim)],
                np.c_[np.cos(tr + 0.01), np.sin(tr + 0.01), np.full(n_rim, height)]]
    rims = [np.arange(n, n + n_rim), np.arange(n + n_rim, n + 2 * n_rim)]

    result = get_method("ocp")(Surface(pts, None, name="random open cylinder"), retry_k_nn=0)
    assert result.diagnostics["selfcheck"]["passed"]
    centre = result.uv[rims[0]].mean(axis=0)
    radii = [np.linalg.norm(result.uv[rim] - centre, axis=1) for rim in rims]
    assert max(r.std() / r.mean() for r in radii) < 0.05  # measured 0.033
    ratio = max(r.mean() for r in radii) / min(r.mean() for r in radii)
    assert ratio == pytest.approx(np.exp(height), rel=0.01)  # measured 4.4752 against 4.4817
