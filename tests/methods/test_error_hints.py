"""Error messages name only parameters of the method in use (issue #12 messages, #11 item 7).

Before: ``k_nn`` larger than the point count said "at least 51 points are needed" without
naming ``k_nn``; shared numerics told ``ocp`` users to set ``normalized`` (ocp has no such
parameter) and told a ``k_search='direct'`` run to try ``k_search='direct'``.
"""

import re

import numpy as np
import pytest

from parambench.datasets_gen.errors import ConvergenceError, NoBoundaryError, ParambenchError, SolverError, TooFewPointsError
from parambench.datasets_gen.registry import make_surface
from parambench.datasets_gen.surface import Surface
from parambench.methods import Parameterization, get_method
from parambench.methods.hints import FALLBACK, Hint, fit_hints, hinted, method_hints
from parambench.methods.registry import all_methods
from parambench.methods.spectral.ksearch import KPoint, line_search

#: Every parameter name of every registered method that could not pass for an English word.
PARAM_NAMES = {p for cls in all_methods().values() for p in cls.defaults if "_" in p}


def named_parameters(message: str) -> set[str]:
    """Parameters a message names: ``name=`` and quoted ``'name'`` forms, and known snake_case names."""
    assigned = set(re.findall(r"\b([A-Za-z_]\w*)=", message))
    quoted = {q for q in re.findall(r"'([A-Za-z_]\w*)'", message) if q in PARAM_NAMES}
    bare = {w for w in re.findall(r"\b[a-z]\w*_\w+\b", message) if w in PARAM_NAMES}
    return assigned | quoted | bare


def _sphere(n: int) -> np.ndarray:
    p = np.random.default_rng(0).normal(size=(n, 3))
    return p / np.linalg.norm(p, axis=1, keepdims=True)


TRIGGERS = {
    "too few points": (lambda: Surface(np.random.default_rng(1).random((6, 3))), {}, TooFewPointsError),
    "k_nn above count": (lambda: Surface(np.random.default_rng(2).random((30, 3))), {"k_nn": 50}, TooFewPointsError),
    "closed sphere": (lambda: Surface(_sphere(1500)), {}, NoBoundaryError),
}


@pytest.mark.parametrize("trigger", sorted(TRIGGERS))
@pytest.mark.parametrize("name", ["ocp", "sdp", "lem"])
def test_hints_name_only_parameters_of_the_method(name, trigger):
    make, params, error = TRIGGERS[trigger]
    method = get_method(name)
    with pytest.raises(error) as err:
        method(make(), **params)
    named = named_parameters(str(err.value))
    assert named, f"the message names no parameter to change: {err.value}"
    assert named <= set(method.defaults), f"{sorted(named - set(method.defaults))} not parameters of {name}"


def test_k_nn_above_the_point_count_says_k_nn_the_count_and_the_limit():
    with pytest.raises(TooFewPointsError) as err:
        get_method("ocp")(Surface(np.random.default_rng(2).random((30, 3))), k_nn=50)
    message = str(err.value)
    assert "k_nn=50" in message and "only 30 points" in message and "k_nn to at most 29" in message


@pytest.mark.parametrize("name", ["ltsa-sklearn", "isomap-sklearn"])
def test_sklearn_peers_name_n_neighbors(name):
    with pytest.raises(TooFewPointsError) as err:
        get_method(name)(Surface(np.random.default_rng(1).random((6, 3))))
    assert "n_neighbors" in str(err.value) and "at most 5" in str(err.value)
    assert named_parameters(str(err.value)) <= set(get_method(name).defaults)


def _spinning(k: float) -> KPoint:
    # every k gives a map that winds twice: the k search finds no crossing
    return KPoint(k=k, energy=-1.0, turning=np.array([2]))


def _with_failing_k_search(name: str):
    """The registered method ``name`` whose run ends in the shared k search failing."""
    base = type(get_method(name))

    class Failing(base):
        def run(self, surface, **params) -> Parameterization:
            line_search(_spinning, max_steps=3)
            raise AssertionError("unreachable")

    return Failing()


def test_k_search_hints_follow_the_method():
    surface = make_surface("plane", 200, sampling="random", seed=0)
    # scp has `normalized`; ocp does not
    with pytest.raises(ConvergenceError) as scp_err:
        _with_failing_k_search("scp")(surface, normalized=True)
    assert "normalized=False" in str(scp_err.value) and "k_search='direct'" in str(scp_err.value)
    with pytest.raises(ConvergenceError) as unnormalized_err:
        _with_failing_k_search("scp")(surface, normalized=False)
    assert "normalized" not in str(unnormalized_err.value)
    with pytest.raises(ConvergenceError) as ocp_err:
        _with_failing_k_search("ocp")(surface.points_only())
    assert "normalized" not in str(ocp_err.value) and "k_search='direct'" in str(ocp_err.value)
    # no circle: a run that used k_search='direct' is not told to use it
    with pytest.raises(ConvergenceError) as direct_err:
        _with_failing_k_search("ocp")(surface.points_only(), k_search="direct")
    assert "k_search" not in str(direct_err.value) and FALLBACK in str(direct_err.value)
    for err, name in [(scp_err, "scp"), (ocp_err, "ocp"), (direct_err, "ocp")]:
        assert named_parameters(str(err.value)) <= set(get_method(name).defaults)


def test_fit_hints_keeps_existing_parameters_and_other_values():
    exc = hinted(SolverError, "it failed", Hint("use b_matrix='mass'", "b_matrix", "mass"),
                 Hint("try a larger reg_eps", "reg_eps"), Hint("check the mesh"))
    assert str(exc) == "it failed; use b_matrix='mass', or try a larger reg_eps, or check the mesh."
    fit_hints(exc, {"b_matrix": "boundary", "weights": "cotangent"}, {"b_matrix": "mass"})
    assert str(exc) == "it failed; check the mesh."


def test_boundary_hints_are_dropped_once_the_parameter_is_that_far_already():
    """"raise k_nn (e.g. 12)" is no advice to a run with 12 neighbours or more, nor "lower
    boundary_angle_deg (e.g. 100)" to one at 100 degrees or less."""
    from parambench.methods.pointset.plugin_support import BOUNDARY_HINTS

    defaults = {"k_nn": 8, "boundary_angle_deg": 120.0, "ball_eps_factor": 2.5}

    def remedies(**params):
        exc = hinted(SolverError, "no loop", *BOUNDARY_HINTS)
        fit_hints(exc, defaults, {**defaults, **params})
        return str(exc)

    assert "raise k_nn" in remedies(k_nn=8) and "lower boundary_angle_deg" in remedies()
    assert "raise k_nn" not in remedies(k_nn=12) and "raise k_nn" not in remedies(k_nn=16)
    assert "lower boundary_angle_deg" not in remedies(boundary_angle_deg=100.0)
    assert "lower boundary_angle_deg" not in remedies(boundary_angle_deg=90.0)
    assert remedies(k_nn=16, boundary_angle_deg=90.0, ball_eps_factor=4.0) == f"no loop; {FALLBACK}."


def test_errors_without_hints_pass_unchanged():
    with pytest.raises(ParambenchError, match=r"^plain; try normalized=True\.$"):
        with method_hints({"k_nn": 8}, {"k_nn": 8}):
            raise SolverError("plain; try normalized=True.")


def test_errors_a_method_recovered_from_are_noted_with_its_own_hints(monkeypatch):
    """A failed search that a fallback recovered from is kept in the diagnostics
    (``energy_error``); its remedies, too, name only parameters of the method."""
    import parambench.methods.plugins.ocp as ocp_module

    real_front, calls = ocp_module._solve_front, []

    def neumann_fails(front, box, solver, params, timer, exact_fallbacks=True):
        calls.append(1)
        if len(calls) == 1:
            raise hinted(ConvergenceError, "no t = 1 crossing found (stand-in)",
                         Hint("try normalized=False", "normalized", False),
                         Hint("use k_search='direct'", "k_search", "direct"))
        return real_front(front, box, solver, params, timer, exact_fallbacks)

    monkeypatch.setattr(ocp_module, "_solve_front", neumann_fails)
    result = get_method("ocp")(make_surface("plane", 600, seed=0).method_input(False))
    note = result.diagnostics["energy_error"]
    assert note.startswith("ConvergenceError: no t = 1 crossing found (stand-in)")
    assert "normalized" not in note and "k_search='direct'" in note


def test_error_note_fits_the_hints_to_the_method():
    from parambench.methods.hints import error_note

    exc = hinted(SolverError, "no map", Hint("use normalized=False", "normalized", False),
                 Hint("use k_nn=12", "k_nn", 12))
    assert error_note(exc, {"k_nn": 8}, {"k_nn": 8}) == "SolverError: no map; use k_nn=12."
    assert error_note(exc, {"k_nn": 8}, {"k_nn": 12}) == f"SolverError: no map; {FALLBACK}."


def test_error_note_without_a_method_leaves_the_remedies_out():
    from parambench.methods.hints import error_note

    exc = hinted(ConvergenceError, "no regular coarse map", Hint("use normalized=False", "normalized", False))
    assert error_note(exc) == "ConvergenceError: no regular coarse map."
    assert error_note(SolverError("plain")) == "SolverError: plain"


def test_a_restated_error_names_each_parameter_once():
    """"the detected boundary looks wrong" adds its own hints before the solver's: "raise k_nn (e.g.
    12), or raise k_nn (e.g. 16)" named one parameter twice."""
    from parambench.methods.hints import Hint, hinted
    from parambench.datasets_gen.errors import SolverError

    err = hinted(SolverError, "failed", Hint("raise k_nn (e.g. 12)", "k_nn", 12, 1), Hint("repair the mesh"),
                 Hint("raise k_nn (e.g. 16)", "k_nn", 16, 1), Hint("try --method ocp"))
    assert str(err) == "failed; raise k_nn (e.g. 12), or repair the mesh, or try --method ocp."


def test_pinched_detected_loops_are_a_failed_solve_not_bad_input():
    """Scan lines 5 spacings apart gave loops through one point twice, and the conformal problem
    refused them as bad input: "split pinched boundary vertices first", which a point set's user
    cannot do. It is now a SolverError (the retries take it up) naming k_nn."""
    import numpy as np

    from parambench.datasets_gen.errors import SolverError
    from parambench.methods.pointset.plugin_support import _require_simple_loops

    _require_simple_loops([np.array([0, 1, 2]), np.array([3, 4, 5])], 8)
    with pytest.raises(SolverError, match=r"pass 1 point\(s\) twice .* raise k_nn \(e.g. 16\)"):
        _require_simple_loops([np.array([0, 1, 2, 3]), np.array([3, 4, 5])], 8)
