"""Scan lines: points on rows sampled several times further apart than along them.

Rows 3 spacings apart look like slots everywhere (the slot search gave up after 77 s of
linking crossings, and every cut was undone); rows 10 apart fall apart into one piece per
row at the default K (``--repair`` kept one row of 31), while a larger K maps them exactly.
"""
from __future__ import annotations

import numpy as np
import pytest

from parambench.bench.cli import main
from parambench.datasets_gen.errors import DisconnectedError, TopologyError
from parambench.datasets_gen.knn_pieces import (comparable_pieces, connecting_k, disconnected_error,
                                                pieces_are_curves, suggested_k)
from parambench.datasets_gen.registry import make_surface
from parambench.datasets_gen.repair import repair_surface
from parambench.datasets_gen.surface import MethodInput, Surface
from parambench.methods import get_method
from parambench.methods.mesh.holes import solve_with_holes
from parambench.methods.pointset.frontend import build_frontend
from parambench.methods.pointset.slot_cuts import MAX_EXAMINED_SHARE


def _scan_lines(gap: float, n: int, seed: int = 0) -> np.ndarray:
    """Rows along x on a 2 x 1 plane, ``gap`` times further apart than the spacing along them."""
    rng = np.random.default_rng(seed)
    dx = np.sqrt(2.0 / (n * gap))
    x, y = np.meshgrid(np.arange(0.0, 2.0, dx), np.arange(0.0, 1.0, gap * dx))
    jitter = rng.normal(0.0, 0.05 * dx, (x.size, 2))
    return np.column_stack([x.ravel() + jitter[:, 0], y.ravel() + jitter[:, 1], np.zeros(x.size)])


def _similarity_error(uv: np.ndarray, xy: np.ndarray) -> float:
    """RMS distance after the best similarity (mirror allowed), over the diameter of ``xy``."""
    a = uv[:, 0] + 1j * uv[:, 1]
    b = xy[:, 0] + 1j * xy[:, 1]
    a, b = a - a.mean(), b - b.mean()
    best = np.inf
    for z in (a, np.conj(a)):
        s = (np.conj(z) @ b) / (np.conj(z) @ z)
        best = min(best, float(np.sqrt(np.mean(np.abs(s * z - b) ** 2))))
    return best / float(np.ptp(np.abs(b)))


def test_rows_three_spacings_apart_are_not_searched_for_slots():
    pts = _scan_lines(3.0, 3000)
    slots = build_frontend(pts).diagnostics["neighbours"]["slots"]
    assert slots["widespread"] and slots["n_slot_edges"] == 0
    assert slots["n_examined_points"] == 0  # given up before screen 2, the step that took the time
    uv = get_method("ocp")(MethodInput(pts)).uv
    assert _similarity_error(uv, pts[:, :2]) < 1e-8


def test_a_slot_is_still_cut_below_the_share():
    """The generated slit's cuts stay: its examined points are far below the share."""
    surface = make_surface("slit", 2000, sampling="random", seed=0)
    slots = build_frontend(surface.points).diagnostics["neighbours"]["slots"]
    assert not slots["widespread"] and slots["n_slot_edges"] > 0
    assert slots["n_examined_points"] < 0.5 * MAX_EXAMINED_SHARE * len(surface.points)


def test_rows_ten_spacings_apart_name_the_k_that_maps_them(tmp_path, capsys):
    pts = _scan_lines(10.0, 3000)
    with pytest.raises(DisconnectedError, match=r"\(13 in all\); the points lie on lines .* try k_nn=24 "
                                                r"\(k_nn=12 joins them") as info:
        build_frontend(pts)
    assert not getattr(info.value, "repairable", False)  # keeping one row of 13 is no repair
    assert "keeping the largest piece would drop 2940 of 3185 points" in str(info.value)
    uv = get_method("ocp")(MethodInput(pts), k_nn=24).uv
    assert _similarity_error(uv, pts[:, :2]) < 1e-8

    src = tmp_path / "rows.xyz"
    np.savetxt(src, pts)
    assert main(["flatten", str(src), "-o", str(tmp_path / "uv.csv")]) == 2
    err = capsys.readouterr().err
    assert "try k_nn=24" in err and "--repair" not in err
    assert main(["flatten", str(src), "--repair", "-o", str(tmp_path / "uv.csv")]) == 2
    assert "try k_nn=24" in capsys.readouterr().err and not (tmp_path / "uv.csv").exists()


def test_pieces_that_are_patches_get_no_k():
    """Two patches far apart: a longer reach would only bridge them; one much smaller piece stays repairable."""
    x, y = np.meshgrid(np.arange(20.0), np.arange(20.0))
    patch = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])
    both = np.vstack([patch, patch + [30.0, 0.0, 0.0]])
    assert not pieces_are_curves(both, 8)
    assert pieces_are_curves(_scan_lines(10.0, 3000), 8)
    exc = disconnected_error(np.array([400, 400]), 8, both)
    assert "flatten each separately or increase k_nn" in str(exc) and "k_nn=" not in str(exc)
    assert not getattr(exc, "repairable", False)
    small = disconnected_error(np.array([400, 36]), 8, np.vstack([patch, patch[:36] + [30.0, 0.0, 0.0]]))
    assert small.repairable and "would drop" not in str(small)


def test_connecting_k_and_its_suggestion():
    pts = _scan_lines(10.0, 3000)
    assert connecting_k(pts, 8) == 12
    assert connecting_k(pts, 64) is None  # nothing above the largest tried
    assert [suggested_k(k) for k in (12, 16, 24, 40)] == [24, 32, 48, 80]
    assert comparable_pieces([10, 5]) and not comparable_pieces([10, 4]) and not comparable_pieces([10])


def test_repair_keeps_a_largest_piece_only_when_the_others_are_small():
    pts = _scan_lines(10.0, 3000)
    with pytest.raises(DisconnectedError, match="try k_nn=24"):
        repair_surface(Surface(points=pts, name="rows"))
    big = np.vstack([pts[pts[:, 1] < 0.05], pts[pts[:, 1] < 0.05][:50] + [0.0, 0.0, 5.0]])
    kept, facts = repair_surface(Surface(points=big, name="one row and a bit"))
    assert facts["pieces"] == 2 and len(kept.points) == len(big) - 50


def test_a_filled_attempt_that_splits_the_graph_falls_back_to_the_free_one():
    """Fill points are ours: their input errors are the fallback failing, not advice about the input."""
    surface = MethodInput(np.eye(4, 3))
    free_result = (None, type("Sol", (), {"turning": [1.0, 1.0], "diagnostics": {}})())

    def attempt(work):
        if work is surface:
            return free_result
        raise DisconnectedError("the fill points split the graph")

    def fill(work):
        return MethodInput(np.eye(5, 3)), 1

    result, work, n = solve_with_holes(surface, "auto", attempt, fill)
    assert result is free_result and work is surface and n == 0

    def attempt_failing(work):
        if work is surface:
            raise TopologyError("free attempt failed")  # not a solver failure: raised as it is
        return free_result

    with pytest.raises(TopologyError, match="free attempt failed"):
        solve_with_holes(surface, "auto", attempt_failing, fill)


def test_a_cut_that_splits_the_graph_is_not_made(monkeypatch):
    """Cuts along a sampling's rows that leave pieces: the uncut graph is kept (before: DisconnectedError)."""
    import parambench.methods.pointset.frontend as frontend
    from parambench.methods.pointset.neighbourhoods import KnnGraph

    nb = frontend.knn_stage(_scan_lines(2.0, 800), 8)
    lower = nb.points[:, 1] < np.median(nb.points[:, 1])
    indices = nb.graph.indices.copy()
    for rows in (np.flatnonzero(lower), np.flatnonzero(~lower)):  # each half linked to itself only
        indices[rows] = rows[np.argsort(np.linalg.norm(nb.points[rows][:, None] - nb.points[rows][None], axis=2),
                                        axis=1)[:, 1:9]]
    split = KnnGraph(indices=indices, distances=nb.graph.distances, mean_spacing=nb.graph.mean_spacing)
    facts = {"n_slot_edges": 40}
    monkeypatch.setattr(frontend, "slot_cut_graph", lambda *args: (split, dict(facts), lower))
    out = frontend.slot_stage(nb, np.tile([0.0, 0.0, 1.0], (len(nb.points), 1)), 8)
    assert out.graph is nb.graph and out.adjacency is nb.adjacency
    assert out.neighbour_diagnostics["slots"] == {"n_slot_edges": 0, "disconnected": True}
