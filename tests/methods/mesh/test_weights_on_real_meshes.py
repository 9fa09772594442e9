"""Every weight option on the real meshes: the fixes behind issue #13 item 5, one test each, and the matrix."""

from __future__ import annotations

import igl
import numpy as np
import pytest

from parambench.bench.metrics import evaluate, mesh_boundary_loops, turning_number
from parambench.datasets_gen.errors import ConvergenceError
from parambench.datasets_gen.registry import make_surface
from parambench.methods.base import StageTimer
from parambench.methods.mesh.conformal_setup import build_mesh_problem, k_start_estimate, resolve_pins
from parambench.methods.mesh.holes import fill_holes
from parambench.methods.mesh.map_check import check_mesh_map
from parambench.methods.pointset.selfcheck_advice import mesh_advice
from parambench.methods.mesh.weights import WEIGHT_KINDS, laplacian, mesh_weights, negative_weight_rows
from parambench.methods.registry import get_method

SCP = get_method("scp")
DNCP = get_method("dncp-opt")
REAL = ["real/camelhead", "real/lilium", "real/bump-domain", "real/bunny10k", "real/meg-helmet", "real/spot-top",
        "real/cortex-lh"]


@pytest.fixture(scope="module")
def real_meshes():
    return {name: make_surface(name, seed=0) for name in REAL}


def test_normalized_authalic_rows_with_nonpositive_sum_use_the_absolute_sum(real_meshes):
    # Before: InvalidInputError "5 row(s) of the authalic weights sum to <= 0" on camelhead.
    s = real_meshes["real/camelhead"]
    raw = mesh_weights(s.points, s.faces, "authalic")
    sums = np.asarray(raw.sum(axis=1)).ravel()
    bad = sums <= 0
    assert bad.sum() == 5
    w = mesh_weights(s.points, s.faces, "authalic", normalized=True)
    row = np.asarray(w.sum(axis=1)).ravel()
    assert np.allclose(row[~bad], 1.0, atol=1e-12)
    abs_sums = np.asarray(abs(raw).sum(axis=1)).ravel()
    assert np.allclose(row[bad], sums[bad] / abs_sums[bad], atol=1e-12)
    assert np.abs(np.asarray(laplacian(w).sum(axis=1))).max() < 1e-12
    res = SCP(s, weights="authalic", normalized=True)
    assert res.diagnostics["regular_boundary"] and np.isfinite(res.uv).all()


def test_k_start_is_one_for_cotangent_and_near_k_opt_for_authalic(real_meshes):
    s = real_meshes["real/bump-domain"]
    # the cotangent Dirichlet energy of the embedding is exactly the surface area
    cot = laplacian(mesh_weights(s.points, s.faces, "cotangent"))
    area = igl.doublearea(s.points, s.faces).sum() / 2
    assert abs(0.5 * np.einsum("ij,ij->", s.points, cot @ s.points) / area - 1) < 1e-10
    assert k_start_estimate(s.points, s.faces, cot) == 1.0
    # authalic weights scale like 1 / edge^2: k_opt is ~1e-3, three orders below 1
    res = DNCP(s, weights="authalic")  # before: no t = 1 crossing stepping up from k = 1 to 7523
    assert res.diagnostics["turning_numbers"] == [1]
    k0 = k_start_estimate(s.points, s.faces, laplacian(mesh_weights(s.points, s.faces, "authalic")))
    assert 0.2 < k0 / res.diagnostics["k_opt"] < 5


def test_dncp_falls_back_to_the_direct_k_where_the_good_region_is_too_narrow(real_meshes):
    s = real_meshes["real/bunny10k"]
    prob, loops, _ = build_mesh_problem(s, StageTimer(), weights="cotangent", normalized=False, uniform_at=None,
                                        b_matrix="boundary")
    pins = resolve_pins("farthest", s.points, loops)
    with pytest.raises(ConvergenceError, match="no t = 1 crossing"):
        prob.solve("dncp", "line", pins=pins)
    res = DNCP(s, holes="free")
    assert res.diagnostics["k_search_fallback"] == "direct"
    assert res.diagnostics["turning_numbers"] == [1, -1, -1, -1, -1]
    assert abs(res.diagnostics["k_opt"] - prob.k_direct(pins)[0]) < 1e-12
    m = evaluate(s.points, s.faces, res.uv)
    assert m["foldovers"] == 0
    scp_qc = evaluate(s.points, s.faces, SCP(s).uv)["qc_mean"]
    assert abs(m["qc_mean"] / scp_qc - 1) < 0.01
    # but its holes' images cross the rim's (4 crossings: a failed check), so with holes
    # left to the method they are filled, and the map passes
    free_check = check_mesh_map(s.points, s.faces, res.uv)
    assert free_check["n_boundary_crossings"] > 0
    # holes' images, not a surface winding round: the advice is the filled holes, not a cut
    assert free_check["n_crossings_of_holes"] == free_check["n_boundary_crossings"]
    assert mesh_advice(free_check, res.params, "dncp-opt") == "its holes' images overlap: try --param holes=filled"
    auto = DNCP(s)
    assert auto.diagnostics["holes_filled"] == 4 and check_mesh_map(s.points, s.faces, auto.uv)["passed"]
    assert abs(evaluate(s.points, s.faces, auto.uv)["qc_mean"] / scp_qc - 1) < 0.01


@pytest.mark.slow
def test_scp_falls_back_to_the_exact_search_where_the_subspace_k_opt_spins(real_meshes):
    # before: SolverError "the exact SCP map near the subspace k_opt = 3.20485 is not regular".
    # The subspace search hands over either because its k_opt spins or, since the
    # refinement judges progress over several steps, because it stops unconverged
    # (residual 1.3e-4, k_opt 3.2610: the exact map there is regular, but off the exact k_opt).
    s = real_meshes["real/cortex-lh"]
    res = SCP(s, weights="cotangent", normalized=True)
    reason = res.diagnostics["subspace_fallback"]
    assert "not regular" in reason or "did not converge" in reason
    assert res.diagnostics["backend"] == "boundary" and res.diagnostics["turning_numbers"] == [1]
    # the exact k_opt is where the energy crosses zero: +-0.1 % gives a negative energy or a spin
    prob, _, _ = build_mesh_problem(s, StageTimer(), weights="cotangent", normalized=True, uniform_at=None,
                                    b_matrix="boundary")
    k = res.diagnostics["k_opt"]
    below, above = prob._scp_reduced(0.999 * k), prob._scp_reduced(1.001 * k)
    assert not below.good and above.good


def test_fill_holes_makes_a_consistently_oriented_disk(real_meshes):
    s = real_meshes["real/bunny10k"]
    filled, n = fill_holes(s)
    assert n == 4 and filled.n_points > s.n_points
    assert np.array_equal(filled.points[: s.n_points], s.points)
    assert len(igl.boundary_loop_all(filled.faces)) == 1
    v, e, f = filled.n_points, len(igl.edges(filled.faces)), len(filled.faces)
    assert v - e + f == 1
    # consistently oriented: every directed edge occurs once
    he = np.concatenate([filled.faces[:, [0, 1]], filled.faces[:, [1, 2]], filled.faces[:, [2, 0]]])
    assert len(np.unique(he, axis=0)) == len(he)


def test_fill_holes_falls_back_to_fans_where_the_patches_fail(real_meshes, monkeypatch):
    """Where pymeshlab's closing fails (or moves a vertex), each hole gets a fan round a new
    centre vertex: one vertex and one triangle per rim edge per hole, still a disk."""
    import parambench.methods.mesh.holes as holes

    monkeypatch.setattr(holes, "_closed_by_pymeshlab", lambda *args: None)
    s = real_meshes["real/bunny10k"]
    filled, n = holes.fill_holes(s)
    rims = sum(len(loop) for loop in igl.boundary_loop_all(s.faces)) - max(
        len(loop) for loop in igl.boundary_loop_all(s.faces))
    assert n == 4 and filled.n_points == s.n_points + 4 and len(filled.faces) == len(s.faces) + rims
    assert np.array_equal(filled.points[: s.n_points], s.points)
    assert len(igl.boundary_loop_all(filled.faces)) == 1


def test_uniform_weights_keep_bunny_holes_open_once_filled(real_meshes):
    s = real_meshes["real/bunny10k"]
    free = SCP(s, weights="uniform", holes="free")
    assert free.diagnostics["regular_boundary"] is False  # holes inside out at every k
    res = SCP(s, weights="uniform")
    assert res.diagnostics["holes_filled"] == 4
    m = evaluate(s.points, s.faces, res.uv)
    assert m["foldovers"] == 0
    loops = mesh_boundary_loops(s.faces)
    assert sorted(round(turning_number(res.uv[loop])) for loop in loops) == [-1, -1, -1, -1, 1]
    # plain cotangent keeps its holes free and its map unchanged
    assert SCP(s).diagnostics["holes_filled"] == 0


#: Combinations with no regular map at any k as asked, and the fallback that gives one
#: (methods/mesh/fallbacks.py). bump-domain: with the farthest pins (two corners of the
#: square) the map spins at every k (turning numbers 3 to 110), with or without the
#: uniform authalic rows; the first other pair is regular. cortex-lh: the authalic maps
#: keep an extra turn at every k (boundary vertices whose negative weights cancel their
#: row); with uniform authalic rows at the 3150 vertices with a negative weight they are
#: regular.
FALLBACKS = {
    ("real/cortex-lh", "scp", "authalic", False): {"authalic_fallback": "negative", "n_uniform_rows": 3150},
    ("real/cortex-lh", "scp", "authalic", True): {"authalic_fallback": "negative", "n_uniform_rows": 3150},
    ("real/cortex-lh", "dncp-opt", "authalic", False): {"authalic_fallback": "negative", "n_uniform_rows": 3150,
                                                        "pins": [376, 12191]},
}
#: No regular map as asked, and some fallback gives one, but which one depends on the last
#: bits of the sparse solves: bump-domain's normalized authalic DNCP with its farthest pins
#: (two corners of the square; the two diagonals tie) is regular with the authalic
#: fallback's uniform rows under scipy 1.17 / numpy 2.4 (QC 1.70, 0 foldovers), and needed
#: the first other pin pair (494, 354) under the releases before.
SOME_FALLBACK = {("real/bump-domain", "dncp-opt", "authalic", True)}
#: More than 10 s each (measured 12 to 32 s): the failing searches before the fallback on
#: cortex-lh's 451 boundary vertices, and the exact boundary search after the subspace one.
SLOW = {("real/cortex-lh", "scp", "authalic", False), ("real/cortex-lh", "scp", "authalic", True),
        ("real/cortex-lh", "scp", "cotangent", True), ("real/cortex-lh", "scp", "hybrid", True)}
#: Regular outer boundary, but a filled hole collapses (turning number 0). bunny10k's
#: normalized authalic SCP did so with the holes filled by fans (64 foldovers, 0.6 % of the
#: faces; 17 of those weights' rows sum to <= 0 there, the paper's "not particularly
#: desirable" kind); with the refined patches (forty-third session) every hole stays open
#: (57 foldovers, QC 4.50), so no case is left here.
COLLAPSED_HOLE: set = set()
#: Either of the two, by the machine's floating point: on the fifty-first session's machine
#: (numpy 2.4.6, scipy 1.17.1, the same releases as the fiftieth's) bunny10k's normalized
#: authalic SCP has no regular map with its holes free (the line search ends at turning
#: numbers [2, 1, 0, 1, 1], the direct k search finds none), so ``holes="auto"`` keeps the
#: filled map, whose 8-vertex hole collapses (63 flipped triangles, 0.63 %); on the fiftieth
#: session's machine the free map was regular and kept (57 foldovers); on the fifty-second's
#: (the same releases) the filled map is kept with every hole open (57 foldovers).
COLLAPSED_HOLE_OR_OPEN = {("real/bunny10k", "scp", "authalic", True)}


CASES = [pytest.param(name, method, weights, normalized, id=f"{name[5:]}-{method}-{weights}-{'norm' if normalized else 'raw'}",
                      marks=[pytest.mark.slow] if (name, method, weights, normalized) in SLOW else [])
         for name in REAL for method in ("scp", "dncp-opt") for weights in WEIGHT_KINDS for normalized in (False, True)]


@pytest.mark.parametrize("name,method,weights,normalized", CASES)
def test_every_weight_option_works_on_every_real_mesh(real_meshes, name, method, weights, normalized):
    s = real_meshes[name]
    case = (name, method, weights, normalized)
    res = get_method(method)(s, weights=weights, normalized=normalized)
    assert np.isfinite(res.uv).all()
    assert res.diagnostics["regular_boundary"]
    fallback = FALLBACKS.get(case, {})
    if case in SOME_FALLBACK:
        assert res.diagnostics["fallback_reason"].startswith("no regular dncp map at any k")
        assert {"authalic_fallback", "pins_fallback"} & set(res.diagnostics)
        assert res.diagnostics.get("pins_farthest", res.diagnostics["pins"]) == [230, 232]  # the first of the tie
        assert evaluate(s.points, s.faces, res.uv)["foldover_fraction"] < 0.01
        return
    for key, value in fallback.items():
        assert res.diagnostics[key] == value, key
    if fallback:
        assert res.diagnostics["fallback_reason"].startswith(f"no regular {method.split('-')[0]} map at any k")
    else:
        # the fallbacks fire nowhere else: every other map is the one asked for
        assert not {"authalic_fallback", "pins_fallback", "fallback_reason"} & set(res.diagnostics)
    assert ("authalic_fallback" in fallback) == ("authalic_fallback" in res.diagnostics)
    assert ("pins_fallback" in fallback) == ("pins_fallback" in res.diagnostics)
    loops = mesh_boundary_loops(s.faces)
    turning = sorted(round(turning_number(res.uv[loop])) for loop in loops)
    m = evaluate(s.points, s.faces, res.uv)
    assert np.isfinite(m["qc_mean"]) and m["foldover_fraction"] < 0.01
    collapsed = [-1, -1, -1, 0, 1]
    if case in COLLAPSED_HOLE:
        assert turning == collapsed
        return
    if case in COLLAPSED_HOLE_OR_OPEN and res.diagnostics.get("holes_filled") and turning == collapsed:
        return
    assert turning == [-1] * (len(loops) - 1) + [1]


def test_given_pins_are_never_changed(real_meshes):
    # two corners of bump-domain (the square's other diagonal), given explicitly: no other
    # pins are tried, only the authalic rows, which do not help with these pins
    s = real_meshes["real/bump-domain"]
    with pytest.raises(ConvergenceError, match=r"no regular dncp map at any k") as info:
        DNCP(s, weights="authalic", normalized=True, pins="231,233")
    assert "(also without a regular map: uniform_at='negative')" in str(info.value)
    assert "pins=" not in str(info.value)


def test_authalic_uniform_rows_can_be_asked_for(real_meshes):
    # uniform_at with authalic weights is a plain parameter: used as given, no fallback
    s = real_meshes["real/lilium"]
    plain = SCP(s, weights="authalic")
    res = SCP(s, weights="authalic", uniform_at="negative")
    n_negative = int(negative_weight_rows(mesh_weights(s.points, s.faces, "authalic")).sum())
    assert res.diagnostics["n_uniform_rows"] == n_negative > 0
    assert "authalic_fallback" not in res.diagnostics and "n_uniform_rows" not in plain.diagnostics
    assert not np.array_equal(res.uv, plain.uv)
