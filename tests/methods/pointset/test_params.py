"""FrontEndParams is the one source of the front end's defaults, for build_frontend and every point-set method."""

from __future__ import annotations

import dataclasses
import inspect

import numpy as np
import pytest

from parambench.datasets_gen.surface import Surface
from parambench.methods.pointset import plugin_support
from parambench.methods.pointset.frontend import build_frontend
from parambench.methods.pointset.params import METHOD_FIELDS, FrontEndParams, frontend_params, method_defaults
from parambench.methods.pointset.plugin_support import FRONTEND_DEFAULTS
from parambench.methods.registry import all_methods, get_method

#: The point-set methods that run the front end (the scikit-learn peers do not).
FRONTEND_METHODS = {"fbcp-pc", "lem", "lle", "ocp", "scp-rl", "scp-tan", "sdp", "sdp-rl"}

#: A value other than the default for each method field (all valid).
OTHER_VALUES = {"k_nn": 9, "ball_k": 7, "ball_eps_factor": 2.75, "dem": "plain", "reg_eps": 2e-2,
                "boundary_angle_deg": 110.0, "boundary_decimate": 2, "spacing": "global", "neighbours": "surface",
                "boundary_method": "rings"}


def test_frontend_defaults_are_the_dataclass_defaults_in_field_order():
    fields = {f.name: f.default for f in dataclasses.fields(FrontEndParams)}
    assert list(FRONTEND_DEFAULTS.items()) == [(k, fields[k]) for k in METHOD_FIELDS]
    assert method_defaults() == FRONTEND_DEFAULTS and method_defaults() is not method_defaults()
    # what the methods have always accepted (a change here changes every stored result's params)
    assert list(FRONTEND_DEFAULTS) == ["k_nn", "ball_k", "ball_eps_factor", "dem", "reg_eps", "boundary_angle_deg",
                                       "boundary_decimate", "spacing", "neighbours", "boundary_method"]
    assert set(OTHER_VALUES) == set(METHOD_FIELDS)
    assert all(OTHER_VALUES[k] != FRONTEND_DEFAULTS[k] for k in METHOD_FIELDS)


def test_build_frontend_runs_with_the_dataclass_defaults(make_height_patch):
    fe = build_frontend(make_height_patch("bump", 20, "jittered").points)
    assert fe.params == dataclasses.asdict(FrontEndParams())
    # no default hides in build_frontend's signature any more
    sig = inspect.signature(build_frontend)
    assert [p.name for p in sig.parameters.values()] == ["points", "normals", "params", "given_loops", "options"]
    assert sig.parameters["given_loops"].kind is inspect.Parameter.KEYWORD_ONLY  # loops are no option


def test_build_frontend_keywords_and_dataclass_agree(make_height_patch):
    pts = make_height_patch("bump", 20, "jittered").points
    by_keyword = build_frontend(pts, k_nn=10, reg_eps=5e-2)
    by_params = build_frontend(pts, None, FrontEndParams(k_nn=10, reg_eps=5e-2))
    mixed = build_frontend(pts, None, FrontEndParams(k_nn=10), reg_eps=5e-2)
    for fe in (by_params, mixed):
        assert fe.params == by_keyword.params and fe.params["k_nn"] == 10 and fe.params["reg_eps"] == 5e-2
        assert (fe.W != by_keyword.W).nnz == 0
    with pytest.raises(TypeError, match="bogus"):
        build_frontend(pts, bogus=1)


def test_frontend_params_takes_the_method_fields_only():
    params = {**OTHER_VALUES, "k_search": "line", "energy": "paper"}
    got = frontend_params(params, weights="lle3d")
    assert got == FrontEndParams(**OTHER_VALUES, weights="lle3d")
    assert frontend_params({}) == FrontEndParams()


def test_every_frontend_method_has_every_method_field():
    names = {name for name, cls in all_methods().items() if not cls.needs_faces and "k_nn" in cls.defaults}
    assert names == FRONTEND_METHODS
    for name in FRONTEND_METHODS:
        defaults = all_methods()[name].defaults
        assert {k: defaults[k] for k in METHOD_FIELDS} == FRONTEND_DEFAULTS, name


class _Reached(Exception):
    """Raised by the stand-in front end once it has seen its parameters."""


@pytest.mark.parametrize("name", sorted(FRONTEND_METHODS))
@pytest.mark.filterwarnings("ignore::parambench.methods.base.InertParameterWarning")  # ocp's reg_eps: said, and passed on
def test_every_method_field_reaches_the_front_end(name, monkeypatch):
    seen = []

    def fake_build_frontend(points, normals=None, params=None, **options):
        seen.append(params)
        raise _Reached

    monkeypatch.setattr(plugin_support, "build_frontend", fake_build_frontend)
    points = np.random.default_rng(0).random((60, 3))
    with pytest.raises(_Reached):
        get_method(name)(Surface(points), **OTHER_VALUES)
    expected_weights = get_method(name).defaults.get("weights", "tangent")
    assert seen == [FrontEndParams(**OTHER_VALUES, weights=expected_weights)]
