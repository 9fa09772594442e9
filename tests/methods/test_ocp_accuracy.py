"""ocp on points alone against cotangent SCP on the ground-truth mesh (5k points).

Figures measured when these bounds were set (energy="neumann", k_search="line"; QC mean
of ocp evaluated on the ground-truth mesh, relative to scp-igl):

    shape   grid     jittered   (foldovers 0 everywhere)
    bump    +0.03 %  +0.03 %
    saddle  +0.02 %  +0.06 %
    cap     +0.00 %  +0.01 %    stereographic error 6.7e-5 / 3.8e-4 of the diameter
    holes   +0.00 %  +0.00 %    exact error 2e-7 / 6e-8 (planar: the identity is exact)

energy="paper" (I - W^tan, Sec. 4.2) gave +0.8 to +6.7 % on the same cases.
"""

from __future__ import annotations

import pytest

from parambench.bench.metrics import evaluate
from parambench.datasets_gen.registry import make_surface
from parambench.methods import get_method

N_POINTS = 5000
#: Honest bound: the worst measured case is +0.06 %.
QC_TOLERANCE = 0.002


def _run(shape: str, sampling: str, **params):
    surf = make_surface(shape, N_POINTS, sampling=sampling, seed=0)
    kw = dict(exact_uv=surf.exact_uv, boundary_loops=surf.boundary_loops, diameter=surf.diameter)
    ref = evaluate(surf.points, surf.faces, get_method("scp-igl")(surf).uv, **kw)
    res = get_method("ocp")(surf.points_only(), **params)
    return evaluate(surf.points, surf.faces, res.uv, **kw), ref, res


def _check(ev, ref):
    assert ev["foldovers"] == 0
    assert ev["qc_mean"] <= ref["qc_mean"] * (1 + QC_TOLERANCE)


def test_cap_jittered_matches_scp_and_stereographic_map():
    ev, ref, res = _run("cap", "jittered")
    _check(ev, ref)
    # issue target 1e-3; measured 3.8e-4 with one global ball radius, 7.0e-4 with radii and
    # area terms from the local spacing (the default since graded samplings need it)
    assert ev["exact_error"] <= 1e-3
    assert abs(res.diagnostics["k_opt"] - 1.0) < 0.05  # the energy is at the conformal scale
    assert res.diagnostics["energy"] == "neumann"


# cap/jittered is the fast test above.
OTHER_CASES = [(shape, sampling) for shape in ("bump", "saddle", "cap", "holes") for sampling in ("grid", "jittered")
               if (shape, sampling) != ("cap", "jittered")]


@pytest.mark.slow
@pytest.mark.parametrize("shape,sampling", OTHER_CASES)
def test_ocp_within_bound_of_cotangent_scp(shape, sampling):
    ev, ref, _ = _run(shape, sampling)
    _check(ev, ref)
    if shape == "cap":
        assert ev["exact_error"] <= 5e-4
    if shape == "holes":  # planar with holes: the identity is an exact zero-energy map
        assert ev["exact_error"] <= 1e-5


def test_paper_energy_is_kept():
    """energy="paper" is Sec. 4.2 as before: k_opt far above 1 and a few per cent more QC."""
    ev, ref, res = _run("cap", "jittered", energy="paper")
    assert ev["foldovers"] == 0
    assert res.diagnostics["k_opt"] > 5
    assert ev["qc_mean"] > ref["qc_mean"] * 1.003  # measured +0.76 %


#: Graded (density varying ~11x) and random samplings at 2000 points, ocp against scp-igl
#: on the true mesh. Before the boundary rows' measured cell areas and narrow weights
#: (neumann_laplacian, boundary_area="spacing", boundary_width=0.5): holes/graded QC
#: +138 % with 18 foldovers, plane/graded +4.8 %, holes/random +4.5 %; after: +0.00 %.
SPARSE_BOUNDARY_CASES = [("holes", "graded"), ("plane", "graded"), ("holes", "random")]


@pytest.mark.parametrize("shape,sampling", SPARSE_BOUNDARY_CASES)
def test_ocp_on_graded_and_random_samplings(shape, sampling):
    """Within 3 % of scp-igl with 0 foldovers (issue 11), and the old boundary rows are not."""
    import numpy as np

    from parambench.methods.pointset.frontend import build_frontend
    from parambench.methods.pointset.neumann_laplacian import neumann_laplacian
    from parambench.methods.pointset.plugin_support import scale_to_spacing
    from parambench.methods.plugins.ocp import conformal_problem

    surf = make_surface(shape, 2000, sampling=sampling, seed=0)
    ref = evaluate(surf.points, surf.faces, get_method("scp-igl")(surf).uv)
    res = get_method("ocp")(surf.method_input(False))
    ev = evaluate(surf.points, surf.faces, res.uv)
    assert ev["foldovers"] == 0
    assert ev["qc_mean"] <= ref["qc_mean"] * 1.03
    # Planar: the identity is an exact zero-energy map, so nothing curls at k = 1 any more.
    assert abs(res.diagnostics["k_opt"] - 1.0) < 1e-3
    assert res.diagnostics["selfcheck"]["passed"]

    front = build_frontend(surf.points)
    old = neumann_laplacian(front.ball_indices, front.tangent_coords, front.boundary_loops, front.local_spacing,
                            boundary_area="spacing", boundary_width=0.5)
    sol = conformal_problem(front, old).solve("scp", "line")
    ev_old = evaluate(surf.points, surf.faces, scale_to_spacing(sol.uv, front))
    assert sol.k > 1.05 and ev_old["qc_mean"] > ref["qc_mean"] * 1.03
    assert np.isfinite(ev_old["qc_mean"])


def test_reg_eps_does_not_act_on_the_default_energy_and_says_so():
    """``reg_eps`` regularises W^tan, which the Neumann energy's moment rows do not use: passed with the
    default energy it changed no map, silently. Now it warns; with the paper's energy it acts and does not."""
    import warnings

    import numpy as np

    from parambench.methods.base import InertParameterWarning

    surface = make_surface("bump", 800, sampling="jittered", seed=0).points_only()
    ocp = get_method("ocp")
    plain = ocp(surface)
    with pytest.warns(InertParameterWarning, match="reg_eps=0.3 does not act on the default energy"):
        given = ocp(surface, reg_eps=0.3)
    assert given.diagnostics.get("energy_used", "neumann") == "neumann"
    np.testing.assert_array_equal(given.uv, plain.uv)
    with warnings.catch_warnings():
        warnings.simplefilter("error", InertParameterWarning)
        paper = ocp(surface, energy="paper")
        paper_eps = ocp(surface, energy="paper", reg_eps=0.3)
    assert np.abs(paper_eps.uv - paper.uv).max() > 1e-6 * np.ptp(paper.uv)
    with pytest.warns(InertParameterWarning, match="area_factor=2.0 has no effect"):
        ocp(surface, energy="paper", area_factor=2.0)


def test_two_level_parameters_on_the_direct_path_say_so():
    """Before: ``map_error=0.02`` on 2,000 points (solver='auto' runs the direct path below 200k)
    said nothing and changed nothing."""
    import numpy as np

    from parambench.methods.base import InertParameterWarning

    surface = make_surface("bump", 800, sampling="jittered", seed=0).points_only()
    ocp = get_method("ocp")
    plain = ocp(surface)
    with pytest.warns(InertParameterWarning, match=r"map_error=0.02 acts only on the two-level path, and on \d+ "
                                                   r"points solver='auto' takes the direct one"):
        given = ocp(surface, map_error=0.02)
    np.testing.assert_array_equal(given.uv, plain.uv)
    with pytest.warns(InertParameterWarning, match="polish_residual=0.0 acts only on the two-level path, and "
                                                   "solver='direct' takes the direct one"):
        ocp(surface, solver="direct", polish_residual=0.0)
    # On the two-level path they act.
    inert = ocp.inert_params({**ocp.defaults, "solver": "multilevel"}, 800)
    assert not {"fine_solver", "map_error", "polish_residual", "polish_spread"} & set(inert)
