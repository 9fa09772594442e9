"""libigl baselines on surfaces with known flattenings (issue: foundation, done-when figures)."""

import numpy as np
import pytest

from parambench.bench.metrics import evaluate
from parambench.datasets_gen.registry import make_surface
from parambench.methods import get_method


def _metrics(surface, method):
    result = get_method(method)(surface)
    return evaluate(surface.points, surface.faces, result.uv, exact_uv=surface.exact_uv,
                    boundary_loops=surface.boundary_loops, diameter=surface.diameter)


@pytest.mark.parametrize("sampling", ["grid", "jittered"])
def test_scp_igl_unrolls_cylinder(sampling):
    surface = make_surface("cylinder", 10_000, sampling=sampling, seed=0)
    m = _metrics(surface, "scp-igl")
    assert m["qc_mean"] < 1.01 and m["foldovers"] == 0 and m["exact_error"] < 1e-3


@pytest.mark.parametrize("sampling", ["grid", "jittered"])
def test_scp_igl_matches_stereographic_on_cap(sampling):
    surface = make_surface("cap", 10_000, sampling=sampling, seed=0)
    assert surface.exact_map_kind == "conformal"
    m = _metrics(surface, "scp-igl")
    assert m["exact_error"] < 1e-3 and m["foldovers"] == 0


@pytest.mark.parametrize("method", ["lscm-igl", "scp-igl"])
def test_baselines_on_plane_with_holes_are_similarities(method):
    surface = make_surface("holes", 3000, sampling="random", seed=1)
    m = _metrics(surface, method)
    assert m["qc_max"] < 1 + 1e-6 and m["exact_error"] < 1e-6
    assert np.allclose(sorted(m["turning_numbers"]), [-1, -1, -1, 1], atol=1e-9)


def test_lscm_pins_are_farthest_boundary_pair():
    surface = make_surface("saddle", 1500, sampling="jittered", seed=0)
    result = get_method("lscm-igl")(surface)
    i, j = result.diagnostics["pins"]
    boundary = np.concatenate(surface.boundary_loops)
    d = np.linalg.norm(surface.points[boundary][:, None] - surface.points[boundary][None], axis=-1)
    assert np.linalg.norm(surface.points[i] - surface.points[j]) == pytest.approx(d.max())
    np.testing.assert_allclose(result.uv[i], [0, 0], atol=1e-9)


@pytest.mark.parametrize("method, target", [("lscm-igl", "lscm"), ("scp-igl", "spectra.lscm")])
def test_a_libigl_solver_failure_is_a_solver_error_naming_what_to_do(monkeypatch, method, target):
    """libigl signals a failed solve with a bare RuntimeError ("igl::lscm failed"), which the
    command line printed as a traceback."""
    import igl
    import igl.spectra

    from parambench.datasets_gen.errors import SolverError

    def broken(*args, **kwargs):
        raise RuntimeError("igl::lscm failed")

    module, name = (igl.spectra, "lscm") if target == "spectra.lscm" else (igl, "lscm")
    monkeypatch.setattr(module, name, broken)
    with pytest.raises(SolverError, match="igl::lscm failed.*try --method scp"):
        get_method(method)(make_surface("bump", 300, sampling="jittered", seed=0))


def test_lscm_igl_does_not_depend_on_the_vertex_order():
    """A jittered square grid's two diagonals tie for the farthest boundary pair: the first in vertex
    order was pinned, so a shuffled copy of the mesh got another map (2e-3 of its size apart)."""
    from parambench.datasets_gen.surface import MethodInput

    surface = make_surface("bump", 1500, sampling="jittered", seed=0)
    points, faces = surface.points, surface.faces
    perm = np.random.default_rng(3).permutation(len(points))
    inverse = np.argsort(perm)
    plain = get_method("lscm-igl")(MethodInput(points, faces)).uv
    shuffled = get_method("lscm-igl")(MethodInput(points[perm], inverse[faces])).uv[inverse]
    np.testing.assert_allclose(shuffled, plain, atol=1e-9 * np.ptp(plain))
