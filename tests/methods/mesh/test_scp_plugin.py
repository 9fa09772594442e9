"""The ``scp`` plugin: agreement with scp-igl, analytic maps, weights, failure paths."""

from __future__ import annotations

import numpy as np
import pytest

from parambench.datasets_gen.errors import MissingFacesError, SolverError, UnknownNameError
from parambench.datasets_gen.registry import make_surface
from parambench.methods.geometry2d import signed_area_2d
from parambench.methods.registry import get_method

SCP = get_method("scp")
SCP_IGL = get_method("scp-igl")


@pytest.mark.parametrize("name", ["saddle", "cap", "cylinder", "holes", "bump"])
def test_mass_b_matches_scp_igl(surfaces, rms, name):
    # igl.spectra.lscm solves the same pencil with the Voronoi mass matrix as B; the
    # cylinder patch is developable (four zero eigenvalues in the real 2V form).
    s = surfaces[name]
    ours = SCP(s, b_matrix="mass")
    ref = SCP_IGL(s)
    assert rms(ours.uv, ref.uv) <= 1e-6
    assert ours.diagnostics["regular_boundary"]


def test_cap_is_close_to_stereographic(surfaces, rms):
    s = surfaces["cap"]
    assert s.exact_map_kind == "conformal"
    assert rms(SCP(s).uv, s.exact_uv) < 5e-4


def test_cylinder_is_close_to_the_unrolling(surfaces, rms):
    s = surfaces["cylinder"]
    assert s.exact_map_kind == "isometric"
    res = SCP(s)
    assert rms(res.uv, s.exact_uv) < 1e-4
    # output scale: the boundary encloses the 3D area, pi * radius * height for a half cylinder
    assert np.isclose(signed_area_2d(res.uv[s.boundary_loops[0]]), 2 * np.pi, rtol=1e-3)


def test_holes_is_the_identity(surfaces, rms):
    s = surfaces["holes"]
    res = SCP(s)
    assert rms(res.uv, s.exact_uv) < 1e-9
    assert res.diagnostics["n_boundary_loops"] == 4
    assert sorted(res.diagnostics["turning_numbers"]) == [-1, -1, -1, 1]


@pytest.mark.parametrize("k_search", ["line", "direct"])
def test_k_search_on_cotangent_stays_at_one(surfaces, rms, k_search):
    s = surfaces["saddle"]
    res = SCP(s, k_search=k_search)
    assert abs(res.diagnostics["k_opt"] - 1.0) < 1e-3
    assert rms(res.uv, SCP(s).uv) < 1e-3


@pytest.mark.parametrize("weights,normalized", [("uniform", False), ("uniform", True), ("hybrid", False),
                                                pytest.param("cotangent", True, marks=pytest.mark.slow),
                                                pytest.param("authalic", True, marks=pytest.mark.slow),
                                                pytest.param("mean-value", True, marks=pytest.mark.slow)])
def test_other_weights_give_regular_maps(surfaces, fold_count, weights, normalized):
    s = surfaces["saddle-jittered"]
    res = SCP(s, weights=weights, normalized=normalized)
    assert res.diagnostics["turning_numbers"] == [1]
    # cotangent-scale kinds (uniform; hybrid, mostly cotangent) keep k = 1 where it is regular
    assert res.diagnostics["k_search"] == ("none" if weights in ("uniform", "hybrid") and not normalized else "line")
    if weights in ("uniform", "cotangent", "hybrid"):
        # (normalized mean-value and authalic maps may fold: "not particularly desirable", Sec. 5)
        assert fold_count(s, res.uv) == 0
    if normalized:
        assert res.diagnostics["k_opt"] > 1.2  # row sums of these weights are > 1


def test_hybrid_removes_foldovers(fold_count):
    # Random-point Delaunay mesh of a tall narrow bump: many negative cotangent weights on
    # the steep flank, where cotangent SCP folds over (Fig. 12).
    s = make_surface("bump", 5000, sampling="random", seed=0, h=1.5, s=0.15)
    cot = SCP(s)
    hyb = SCP(s, weights="hybrid")
    assert fold_count(s, cot.uv) > 20
    assert hyb.diagnostics["n_uniform_rows"] > 100
    assert fold_count(s, hyb.uv) == 0
    assert hyb.diagnostics["turning_numbers"] == [1]


def test_failures_are_explicit(surfaces):
    s = surfaces["saddle"]
    with pytest.raises(SolverError, match="indefinite"):
        SCP(s, weights="cotangent", normalized=True, k_search="none")
    with pytest.raises(UnknownNameError, match="b_matrix"):
        SCP(s, b_matrix="lumped")
    with pytest.raises(UnknownNameError, match="weights|kind"):
        SCP(s, weights="harmonic")
    with pytest.raises(MissingFacesError):
        SCP(s.points_only())


def test_diagnostics_are_json_serialisable(surfaces):
    import json

    res = SCP(surfaces["saddle"], k_search="line")
    json.dumps(res.diagnostics)
    land = res.diagnostics["landscape"]
    assert set(land) == {"k", "E", "q", "t"} and len(land["k"]) == res.diagnostics["n_k_evaluations"]
    assert {"topology", "weights", "solve", "total"} <= set(res.timings)


def test_a_filled_slot_keeps_the_exact_map(rms):
    """The ``slit`` plane (a developable sheet with a long slot): with the slot filled the
    map must still be the unrolling. Before, a fan round the slot's centroid (long thin
    triangles that overlap where the rim is not convex from its centroid) put ``scp`` 6.3e-3
    of the diameter off it; the refined patch keeps it to 2.5e-6."""
    from parambench.methods.mesh.holes import fill_holes

    s = make_surface("slit", 3000, seed=0)
    filled, n = fill_holes(s)
    assert n == 1 and np.array_equal(filled.points[: s.n_points], s.points)
    result = get_method("scp")(s, holes="filled")
    assert result.diagnostics["holes_filled"] == 1
    assert rms(result.uv, s.exact_uv) < 1e-4


def test_a_hole_through_a_split_pinch_is_filled_without_zero_area_patches():
    """Two cells of a grid missing that touch at a corner: --repair splits the pinch, and the
    hole's rim passes the two copies. pymeshlab's patch joined them (7 triangles of zero
    area: DegenerateFacesError from holes="filled"); the fans join no two rim vertices."""
    from parambench.bench.metrics import evaluate
    from parambench.datasets_gen.repair import repair_surface
    from parambench.datasets_gen.surface import MethodInput, Surface, degenerate_faces
    from parambench.methods.mesh.holes import fill_holes
    from parambench.methods.mesh.map_check import check_mesh_map

    n = 9
    x, y = np.meshgrid(np.arange(n, dtype=float), np.arange(n, dtype=float))
    points = np.c_[x.ravel(), y.ravel(), 0.05 * (x.ravel() - 4.0) ** 2]
    i = np.arange(n * n).reshape(n, n)[:-1, :-1].ravel()
    faces = np.r_[np.c_[i, i + 1, i + n + 1], np.c_[i, i + n + 1, i + n]]
    cells = [3 * (n - 1) + 3, 4 * (n - 1) + 4]  # cells (3, 3) and (4, 4): they share a corner
    drop = np.r_[cells, np.add(cells, (n - 1) ** 2)]
    repaired, facts = repair_surface(Surface(points=points, faces=np.delete(faces, drop, axis=0), name="pinch"))
    assert facts["vertices_split"] == 1
    surface = MethodInput(repaired.points, repaired.faces, name="pinch")
    filled, n_holes = fill_holes(surface)
    assert n_holes == 1 and not degenerate_faces(filled.points, filled.faces).any()
    res = get_method("scp")(surface, holes="filled")
    assert check_mesh_map(surface.points, surface.faces, res.uv)["passed"]
    # a developable sheet (a parabolic cylinder): the filled map stays near conformal
    assert evaluate(surface.points, surface.faces, res.uv)["qc_mean"] < 1.01
