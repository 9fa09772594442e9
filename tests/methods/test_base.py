"""The plugin contract of parambench.methods.base: the base class times, checks and builds the result."""

from __future__ import annotations

import re

import numpy as np
import pytest

from parambench.datasets_gen.errors import InvalidInputError, UnknownNameError
from parambench.datasets_gen.surface import Surface
from parambench.methods.base import InertParameterWarning, Method, MethodOutput, Parameterization, StageTimer
from parambench.methods.registry import all_methods, get_method


class _Flat(Method):
    """A mesh method mapping to x, y; records what ``solve`` and ``check_params`` see."""

    name = "test-flat"
    needs_faces = True
    defaults = {"mode": "xy", "scale": 1.0}
    choices = {"mode": ("xy", "yx")}

    def __init__(self) -> None:
        self.solved: list[dict] = []
        self.checked: list[dict] = []

    def check_params(self, params: dict) -> None:
        self.checked.append(dict(params))
        if params["scale"] <= 0:
            raise InvalidInputError("scale must be positive.")

    def solve(self, surface: Surface, params: dict, timer: StageTimer) -> MethodOutput:
        self.solved.append(dict(params))
        with timer("project"):
            cols = [0, 1] if params["mode"] == "xy" else [1, 0]
            uv = surface.points[:, cols] * params["scale"]
        return MethodOutput(uv, {"n_cols": 2}, faces=surface.faces)


def _mesh() -> Surface:
    pts = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.1], [1.0, 1.0, 0.2], [0.0, 1.0, 0.3]])
    return Surface(pts, np.array([[0, 1, 2], [0, 2, 3]]), name="square")


def test_base_class_builds_the_parameterization_from_solve():
    method = _Flat()
    result = method(_mesh(), scale=2.0)
    assert isinstance(result, Parameterization)
    assert result.method == "test-flat"
    assert result.params == {"mode": "xy", "scale": 2.0}
    assert list(result.timings) == ["project", "total"] and result.timings["total"] >= result.timings["project"]
    # the plugin's diagnostics, plus the input scale the pose wrapper adds
    assert result.diagnostics["n_cols"] == 2 and "input_scale" in result.diagnostics
    np.testing.assert_array_equal(result.faces, _mesh().faces)
    assert method.solved == [{"mode": "xy", "scale": 2.0}] and method.checked == method.solved


def test_run_is_solve_timed_and_wrapped_without_pose():
    method = _Flat()
    surface = _mesh()
    result = method.run(surface, mode="yx", scale=1.0)
    np.testing.assert_array_equal(result.uv, surface.points[:, [1, 0]])
    assert result.method == "test-flat" and result.params == {"mode": "yx", "scale": 1.0}
    assert list(result.timings) == ["project"] and result.diagnostics == {"n_cols": 2}


def test_value_outside_choices_is_refused_before_solve():
    method = _Flat()
    with pytest.raises(UnknownNameError, match=r"unknown mode 'zx'; choose one of xy, yx\."):
        method(_mesh(), mode="zx")
    assert method.solved == [] and method.checked == []


class _FlatInertScale(_Flat):
    name = "test-flat-inert"

    def inert_params(self, params: dict) -> dict:
        return {"scale": "does nothing in yx mode"} if params["mode"] == "yx" else {}


def test_a_parameter_passed_where_it_does_not_act_is_warned_about_only_when_passed():
    import warnings

    method = _FlatInertScale()
    with pytest.warns(InertParameterWarning, match=r"test-flat-inert: scale=2\.0 does nothing in yx mode"):
        method(_mesh(), mode="yx", scale=2.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        method(_mesh(), mode="yx")  # the default is not the user's choice
        method(_mesh(), mode="xy", scale=2.0)


def test_plugin_checks_run_before_solve():
    method = _Flat()
    with pytest.raises(InvalidInputError, match="scale must be positive"):
        method(_mesh(), scale=-1.0)
    assert method.checked == [{"mode": "xy", "scale": -1.0}] and method.solved == []


def test_a_plugin_without_solve_or_run_says_so():
    class Empty(Method):
        name = "test-empty"
        needs_faces = True

    with pytest.raises(NotImplementedError, match="Empty implements neither solve nor run"):
        Empty()(_mesh())


def test_solve_output_diagnostics_are_not_shared_between_results():
    # MethodOutput's default diagnostics must be a fresh dict: the wrappers add keys to it
    a, b = MethodOutput(np.zeros((3, 2))), MethodOutput(np.zeros((3, 2)))
    a.diagnostics["x"] = 1
    assert b.diagnostics == {}


@pytest.mark.parametrize("name", sorted(all_methods()))
def test_every_builtin_plugin_implements_solve_only(name):
    cls = type(get_method(name))
    if not cls.__module__.startswith("parambench.methods.plugins."):
        pytest.skip(f"{name} is a third-party plugin")
    assert cls.run is Method.run, f"{name} overrides run; the base class times and builds the result"
    assert cls.solve is not Method.solve, f"{name} does not implement solve"
    assert set(cls.choices) <= set(cls.defaults)
    for key, allowed in cls.choices.items():
        assert cls.defaults[key] in allowed, f"{name}: default {key}={cls.defaults[key]!r} not in its choices"


@pytest.mark.parametrize("params, words", [
    ({"k_nn": None}, "k_nn expects a whole number, got None"),
    ({"k_nn": "8"}, "k_nn expects a whole number, got '8' (str)"),
    ({"k_nn": 8.5}, "k_nn expects a whole number"),
    ({"reg_eps": "abc"}, "reg_eps expects a finite number, got 'abc'"),
    ({"reg_eps": float("inf")}, "reg_eps expects a finite number"),
    ({"area_factor": "x"}, "area_factor expects a finite number"),
])
def test_parameters_of_the_wrong_kind_are_refused_by_name(params, words):
    """From Python these reached the numerics (a bare TypeError or ValueError deep in the front
    end), or were converted quietly ("0.01") while others were refused ("got 8")."""
    from parambench.datasets_gen.registry import make_surface

    surface = make_surface("bump", 300, sampling="jittered", seed=0).method_input(False)
    with pytest.raises(InvalidInputError, match=re.escape(words)):
        get_method("ocp")(surface, **params)
    assert get_method("ocp")(surface, k_nn=8.0, ball_eps_factor=np.float32(2.5)).uv.shape == (surface.n_points, 2)
