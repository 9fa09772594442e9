"""The plugin contract: registry lookups, parameter checking, mesh-only methods."""

from pathlib import Path

import numpy as np
import pytest

import parambench.methods.plugins

from parambench.datasets_gen.errors import MissingFacesError, UnknownNameError
from parambench.datasets_gen.surface import Surface
from parambench.methods import Method, Parameterization, get_method, method_names, register
from parambench.methods.pose import surface_pose
from parambench.methods.registry import all_methods


def test_baselines_registered():
    names = method_names()
    assert "lscm-igl" in names and "scp-igl" in names
    assert all(cls.name == name for name, cls in all_methods().items())


BUILTIN = {"bff-mouette", "dncp-opt", "fbcp-pc", "hlle-sklearn", "isomap-sklearn", "lem", "lle", "lscm-igl",
           "ltsa-sklearn", "ocp", "scp", "scp-igl", "scp-rl", "scp-tan", "sdp", "sdp-rl"}


def test_every_builtin_plugin_lives_in_a_module_named_after_it():
    plugins = Path(parambench.methods.plugins.__file__).parent
    modules = {p.stem for p in plugins.glob("*.py") if not p.stem.startswith("_")}
    builtin = {name: cls for name, cls in all_methods().items() if cls.__module__.startswith("parambench.methods.plugins.")}
    assert set(builtin) == BUILTIN
    for name, cls in builtin.items():
        assert cls.__module__ == f"parambench.methods.plugins.{name.replace('-', '_')}", name
    # and no plugin module holds something else (or nothing)
    assert modules == {name.replace("-", "_") for name in BUILTIN}


def test_unknown_method_lists_available():
    with pytest.raises(UnknownNameError, match="lscm-igl"):
        get_method("no-such-method")


def test_unknown_parameter_is_refused():
    with pytest.raises(UnknownNameError, match="no parameter"):
        get_method("scp-igl").resolve_params({"bogus": 1})


@pytest.mark.parametrize("name", ["lscm-igl", "scp-igl"])
def test_mesh_baselines_refuse_point_sets(name):
    pts = np.random.default_rng(0).random((50, 3))
    with pytest.raises(MissingFacesError, match="point set"):
        get_method(name)(Surface(pts))


@pytest.fixture
def clean_registry():
    from parambench.methods import registry

    before = dict(registry._REGISTRY)
    yield
    registry._REGISTRY.clear()
    registry._REGISTRY.update(before)


def test_registered_plugin_runs_and_is_timed(clean_registry):
    @register
    class Projection(Method):
        name = "test-xy-projection"
        defaults = {"scale": 1.0}

        def run(self, surface, scale):
            return Parameterization(uv=surface.points[:, :2] * scale, method=self.name)

    pts = np.random.default_rng(1).random((20, 3))
    result = get_method("test-xy-projection")(Surface(pts), scale=2.0)
    # plugins see the centred, unit-size principal-frame copy (parambench.methods.pose); uv comes back in input units
    pose = surface_pose(pts)
    np.testing.assert_allclose(result.uv, pose.to_unit(pts)[:, :2] * pose.scale * 2.0)
    assert result.params == {"scale": 2.0} and result.timings["total"] >= 0


def test_a_method_name_that_is_no_string_is_an_unknown_name():
    from parambench.datasets_gen.errors import UnknownNameError

    with pytest.raises(UnknownNameError, match="unknown method"):
        get_method(["ocp"])
