"""Loops that missed a hole: the front end's boundary stage tries lower angles itself, and
a map whose check still finds one is retried with a lower angle by every point-set method
with a front end; a retry that reuses a map is checked for it too."""

from __future__ import annotations

import numpy as np
import pytest

import parambench.methods.pointset.frontend as frontend_module
from parambench.datasets_gen.surface import MethodInput
from parambench.methods.registry import get_method


def _jittered_grid_with_hole(n_side: int, radius: float, seed: int) -> np.ndarray:
    """A flat jittered n_side x n_side grid (spacing 1) without the points within ``radius`` of its centre."""
    rng = np.random.default_rng(seed)
    grid = np.stack(np.meshgrid(np.arange(n_side), np.arange(n_side)), -1).reshape(-1, 2).astype(float)
    grid += rng.uniform(-0.35, 0.35, grid.shape)
    keep = np.linalg.norm(grid - (n_side - 1) / 2, axis=1) > radius
    return np.c_[grid[keep], np.zeros(int(keep.sum()))]


def _similarity_residual(xy: np.ndarray, uv: np.ndarray) -> float:
    """RMS distance of uv from the best similarity (or mirrored similarity) image of xy, over xy's extent."""
    z, best = uv[:, 0] + 1j * uv[:, 1], np.inf
    for w in (xy[:, 0] + 1j * xy[:, 1], xy[:, 0] - 1j * xy[:, 1]):
        m = np.c_[w, np.ones(len(w))]
        coef = np.linalg.lstsq(m, z, rcond=None)[0]
        best = min(best, float(np.sqrt(np.mean(np.abs(m @ coef - z) ** 2)) / abs(coef[0])))
    return best / float(np.ptp(xy[:, 0]))


def test_missed_holes_are_retried_with_a_lower_angle():
    ocp = get_method("ocp")
    params = dict(ocp.defaults)
    changed = [{k: v for k, v in r.items() if params[k] != v} for r in ocp.retry_params(params, {"failed": ["coverage"]})]
    assert changed == [{"boundary_angle_deg": 100.0}, {"boundary_angle_deg": 90.0}, {"refine": "mesh"}]
    low = {**params, "boundary_angle_deg": 95.0}  # a user's own lower angle: only lower ones are tried
    assert [r["boundary_angle_deg"] for r in ocp.retry_params(low, {"failed": ["coverage"]})] == [90.0, 95.0]


@pytest.mark.parametrize("seed, angle", [(2, 100.0), (0, 90.0)])
@pytest.mark.parametrize("where", ["front end", "method retry"])
def test_a_hole_the_default_angle_misses_is_found_at_a_lower_angle(monkeypatch, seed, angle, where):
    """A hole 5.4 grid steps across in a flat jittered grid: at 120 degrees only some of
    its rim points pass and no loop closes. The front end sees their ring round an empty
    disk and finds the hole at a lower angle; without that (as where its loops still
    leave one), the check sees it and the method's retry does; either way the plane is
    mapped with its hole, as it is."""
    if where == "method retry":
        monkeypatch.setattr(frontend_module, "LOWER_ANGLES_DEG", ())
    points = _jittered_grid_with_hole(40, 2.7, seed)
    result = get_method("ocp")(MethodInput(points=points, faces=None, normals=None, name="grid with a hole"))
    check = result.diagnostics["selfcheck"]
    assert check["passed"] and check["turning_numbers"] == [1.0, -1.0]
    if where == "front end":
        assert result.diagnostics["boundary_angle_lowered_to"] == angle and "retry" not in check
    else:
        assert "boundary_angle_lowered_to" not in result.diagnostics
        assert "ring an empty disk on no detected loop" in check["retry"]["first_reason"]
        assert check["retry"]["params"] == {"boundary_angle_deg": angle}
    hole = min(result.diagnostics["boundary_loops"], key=len)
    assert np.all(np.linalg.norm(points[hole, :2] - 19.5, axis=1) < 2.7 + 2.0)  # within two rows of the hole
    assert _similarity_residual(points[:, :2], result.uv) < 1e-5  # measured 5e-8 and 9e-8


def test_the_front_end_keeps_the_angle_where_the_loops_cover_the_candidates():
    from parambench.methods.pointset.frontend import build_frontend

    hole = build_frontend(_jittered_grid_with_hole(40, 2.7, 2))
    plain = build_frontend(_jittered_grid_with_hole(40, 0.0, 2))
    assert hole.diagnostics["boundary"]["angle_lowered_to"] == 100.0 and len(hole.boundary_loops) == 2
    assert "angle_lowered_to" not in plain.diagnostics["boundary"] and len(plain.boundary_loops) == 1


def test_a_retry_that_reuses_the_map_is_checked_for_missed_holes_too(monkeypatch):
    """ocp's refine="mesh" retry reuses the first map and runs no front end; its check must
    still have the front end's candidates (before, it had none and a map that missed the
    hole passed)."""
    from parambench.methods.plugins.ocp import Ocp

    monkeypatch.setattr(frontend_module, "LOWER_ANGLES_DEG", ())  # the first run's loops miss the hole
    monkeypatch.setattr(Ocp, "retry_params", lambda self, params, check: [{**params, "refine": "mesh"}])
    points = _jittered_grid_with_hole(40, 2.7, 2)
    result = get_method("ocp")(MethodInput(points=points, faces=None, normals=None, name="grid with a hole"))
    check = result.diagnostics["selfcheck"]
    assert check["retry"]["params"] == {"refine": "mesh"} and not check["retry"]["passed"]
    assert check["coverage"]["empty_ring"] >= 5 and "coverage" in check["failed"]


@pytest.mark.parametrize("method", ["sdp", "fbcp-pc"])
@pytest.mark.parametrize("where", ["front end", "method retry"])
def test_other_pointset_methods_find_a_missed_hole_by_default(monkeypatch, method, where):
    """The front end is theirs too, and the retry is Method.retry_params' default
    (fbcp-pc's own retries come after it)."""
    if where == "method retry":
        monkeypatch.setattr(frontend_module, "LOWER_ANGLES_DEG", ())
    points = _jittered_grid_with_hole(40, 2.7, 2)
    result = get_method(method)(MethodInput(points=points, faces=None, normals=None, name="grid with a hole"))
    check = result.diagnostics["selfcheck"]
    assert check["passed"]
    if where == "front end":
        assert result.diagnostics["boundary_angle_lowered_to"] == 100.0 and "retry" not in check
    else:
        assert check["retry"]["params"] == {"boundary_angle_deg": 100.0}
    assert sorted(check["turning_numbers"]) == [-1.0, 1.0]
    # fbcp-pc's local Delaunay weights are exact on the plane, sdp is not conformal.
    assert _similarity_residual(points[:, :2], result.uv) < (1e-9 if method == "fbcp-pc" else 0.02)


def test_no_angle_retry_where_the_loops_are_given():
    fbcp = get_method("fbcp-pc")
    given = {**fbcp.defaults, "boundary": "given"}
    assert all("boundary_angle_deg" not in {k for k, v in r.items() if given[k] != v}
               for r in fbcp.retry_params(given, {"failed": ["coverage"]}))
