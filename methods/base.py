"""The ``Parameterization`` hand-off and the method plugin contract.

A plugin is a small class (the benchopt pattern): a ``name``, ``defaults``, a
``param_grid`` for sweeps, ``needs_faces``, optionally ``choices`` (the allowed values of
some parameters), and :meth:`Method.solve`. Plugins know nothing of sweeps, files or
reports.

Who does what:

* :meth:`Method.__call__` accepts a :class:`~parambench.datasets_gen.surface.Surface` or a
  :class:`~parambench.datasets_gen.surface.MethodInput` and hands the method a
  ``MethodInput`` (a ``Surface`` is converted: points, faces, normals, loops and name, never
  its exact map, boundary mask, generator parameters or seed); fills in defaults, refuses
  unknown parameter names and values outside ``choices`` (then
  :meth:`Method.check_params`, the plugin's own checks), puts the input in unit pose, merges coincident points of point sets, times the whole run
  and runs the point-set self-check.
* :meth:`Method.run` (the base class's) creates the :class:`StageTimer`, calls
  :meth:`Method.solve` and builds the :class:`Parameterization` (method name, params,
  stage timings, diagnostics, faces).
* A plugin implements only ``solve(surface, params, timer) -> MethodOutput``: its
  method on a ``MethodInput``, timing its stages with ``with timer("stage"):``.

A plugin that overrides :meth:`Method.run` and returns a :class:`Parameterization`
itself (the contract before ``solve``) still works: ``__call__`` only calls ``run``.
"""

from __future__ import annotations

import gc
import time
import warnings
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass, field
from typing import Any, Callable, ClassVar, Iterator

import numpy as np

from parambench.datasets_gen.errors import (InvalidInputError, MissingFacesError, ParambenchError, SolverError,
                                            UnknownNameError, released)
from parambench.datasets_gen.surface import MethodInput, Surface

from .hints import fit_hints, hinted, method_hints
from .memory_budget import PeakMemory, check_memory
from .pose import run_in_unit_pose

__all__ = ["Parameterization", "MethodOutput", "Method", "InertParameterWarning", "as_method_input", "StageTimer",
           "active_stage", "add_stage_hook", "remove_stage_hook", "retry_memo", "selfcheck_doubt"]


@dataclass(eq=False)
class Parameterization:
    """A map of the surface's points to the plane.

    Parameters
    ----------
    uv : (N, 2) numpy.ndarray of float64
        One row per input point, in input order.
    method : str
        Registered method name.
    params : dict
        The parameters the method ran with (defaults filled in).
    timings : dict of str to float
        Seconds per stage (e.g. ``{"weights": 0.1, "solve": 0.4}``); ``"total"`` is added
        by :meth:`Method.__call__`.
    diagnostics : dict
        Solver facts: iterations, eigenvalues, ``k_opt``, boundary loops found, ...
        Values are JSON-serialisable scalars, lists or dicts.
    faces : (M, 3) numpy.ndarray of int64 or None
        A triangulation the method built or used (e.g. Delaunay in uv for a point set);
        None when the method worked on the surface's own faces or on points only.
    """

    uv: np.ndarray
    method: str
    params: dict = field(default_factory=dict)
    timings: dict = field(default_factory=dict)
    diagnostics: dict = field(default_factory=dict)
    faces: np.ndarray | None = None

    def __post_init__(self) -> None:
        uv = np.asarray(self.uv, dtype=np.float64)
        if uv.ndim != 2 or uv.shape[1] != 2:
            raise InvalidInputError(f"uv must have shape (N, 2), got {uv.shape}.")
        self.uv = np.ascontiguousarray(uv)


@dataclass(eq=False)
class MethodOutput:
    """What a plugin's :meth:`Method.solve` returns; :meth:`Method.run` makes it a :class:`Parameterization`.

    Parameters
    ----------
    uv : (N, 2) array_like of float
        One row per point of the surface ``solve`` was given, in its order.
    diagnostics : dict
        Solver facts, JSON-serialisable (see :class:`Parameterization`).
    faces : (M, 3) numpy.ndarray of int64 or None
        A triangulation the method built, if any.
    """

    uv: np.ndarray
    diagnostics: dict = field(default_factory=dict)
    faces: np.ndarray | None = None


def as_method_input(surface: Surface | MethodInput) -> MethodInput:
    """What a method is given: a ``MethodInput`` as is, a ``Surface`` converted.

    Parameters
    ----------
    surface : Surface or MethodInput

    Returns
    -------
    MethodInput
        ``surface`` itself, or :meth:`Surface.as_method_input` (points, faces, normals,
        loops and name shared with the ``Surface``; no exact map, mask, parameters or seed).

    Raises
    ------
    InvalidInputError
        Anything else.
    """
    if isinstance(surface, MethodInput):
        return surface
    if isinstance(surface, Surface):
        return surface.as_method_input()
    raise InvalidInputError(
        f"a method takes a Surface or a MethodInput, got {type(surface).__name__}; "
        "wrap arrays as parambench.datasets_gen.surface.MethodInput(points, faces)."
    )


#: Names of the StageTimer stages running now, innermost last (read by memory samplers).
_ACTIVE_STAGES: list[str] = []
#: Callables ``hook(event, stage)`` run at every stage's "enter" and "exit".
_STAGE_HOOKS: list[Callable[[str, str], None]] = []


def add_stage_hook(hook: Callable[[str, str], None]) -> None:
    """Call ``hook("enter", stage)`` and ``hook("exit", stage)`` around every StageTimer stage.

    Runs in the thread of the stage, so it sees the process state even while a compiled
    library holds the GIL for the whole stage (a sampling thread would not).
    """
    _STAGE_HOOKS.append(hook)


def remove_stage_hook(hook: Callable[[str, str], None]) -> None:
    """Undo :func:`add_stage_hook` (no error if absent)."""
    if hook in _STAGE_HOOKS:
        _STAGE_HOOKS.remove(hook)


def active_stage() -> str | None:
    """The innermost :class:`StageTimer` stage running now, or None.

    A memory sampler in another thread (``parambench.bench.memory.PeakMemory``) calls this to
    attribute the resident memory it sees to a stage.
    """
    return _ACTIVE_STAGES[-1] if _ACTIVE_STAGES else None


class StageTimer:
    """Collects wall-clock seconds per named stage.

    Examples
    --------
    >>> timer = StageTimer()
    >>> with timer("solve"):
    ...     pass
    >>> sorted(timer.timings)
    ['solve']
    """

    def __init__(self) -> None:
        self.timings: dict[str, float] = {}

    @contextmanager
    def __call__(self, stage: str) -> Iterator[None]:
        start = time.perf_counter()
        _ACTIVE_STAGES.append(stage)
        for hook in tuple(_STAGE_HOOKS):
            hook("enter", stage)
        try:
            yield
        finally:
            for hook in tuple(_STAGE_HOOKS):
                hook("exit", stage)
            _ACTIVE_STAGES.pop()
            self.timings[stage] = self.timings.get(stage, 0.0) + time.perf_counter() - start


class InertParameterWarning(UserWarning):
    """A parameter was passed that has no effect under the method's other parameters."""


class Method:
    """Base class of method plugins.

    Subclasses set the class attributes and implement :meth:`solve` (see the module
    docstring for what the base class does around it).

    Attributes
    ----------
    name : str
        Registered name, used on the command line and in result tables.
    description : str
        One line shown by ``parambench list``.
    needs_faces : bool
        True for mesh methods; they raise :class:`MissingFacesError` on a point set.
    defaults : dict
        Every accepted parameter with its default value.
    param_grid : dict of str to list
        Values a sweep tries per parameter (a subset of ``defaults`` keys); missing keys
        use the default.
    choices : dict of str to tuple
        For parameters that take one of a few names: the allowed values. Checked by
        :meth:`__call__` before the method runs.
    conformal_map : bool
        A point-set method that promises a conformal map: its self-check also fails a map
        that stretches whole regions one way ("distorted").
    nullable : frozenset of str
        Parameters with a number as default that also take None (e.g. ``ocp``'s
        ``polish_spread``: null = never); any other number parameter refuses None.
    peak_memory : PeakMemory or None
        The method's peak resident memory, measured on its worst sampling, and its
        growth with size (:class:`~parambench.methods.memory_budget.PeakMemory`);
        :meth:`__call__` refuses an input whose estimate exceeds the memory available
        (:func:`~parambench.methods.memory_budget.check_memory`) instead of being killed
        by the system part way. None: not checked.
    """

    name: ClassVar[str] = ""
    description: ClassVar[str] = ""
    needs_faces: ClassVar[bool] = False
    defaults: ClassVar[dict[str, Any]] = {}
    param_grid: ClassVar[dict[str, list]] = {}
    choices: ClassVar[dict[str, tuple]] = {}
    nullable: ClassVar[frozenset[str]] = frozenset()
    conformal_map: ClassVar[bool] = False
    peak_memory: ClassVar[PeakMemory | None] = None

    def resolve_params(self, params: dict[str, Any]) -> dict[str, Any]:
        """Fill in defaults and reject unknown parameter names.

        Raises
        ------
        UnknownNameError
            A key that is not in ``defaults``; the message lists the accepted ones.
        """
        unknown = sorted(set(params) - set(self.defaults))
        if unknown:
            accepted = ", ".join(sorted(self.defaults)) or "(none)"
            raise UnknownNameError(
                f"method {self.name!r} has no parameter(s) {', '.join(unknown)}; accepted: {accepted}."
            )
        merged = dict(self.defaults)
        merged.update(params)
        return merged

    def check_values(self, params: dict[str, Any]) -> None:
        """Refuse parameter values outside ``choices``, then run :meth:`check_params`.

        Parameters
        ----------
        params : dict
            Resolved parameters (every key of ``defaults``).

        Raises
        ------
        UnknownNameError
            A value not in ``choices[name]``; the message lists the allowed ones.
        ParambenchError
            Whatever :meth:`check_params` raises.
        """
        for key, allowed in self.choices.items():
            if params[key] not in allowed:
                raise UnknownNameError(f"unknown {key} {params[key]!r}; choose one of {', '.join(allowed)}.")
        for key, default in self.defaults.items():
            if not (key in self.nullable and params[key] is None):
                _check_number_type(key, default, params[key])
        self.check_params(params)

    def inert_params(self, params: dict[str, Any], n_points: int | None = None) -> dict[str, str]:
        """Parameters that do not shape the map under the other values of ``params`` (none by default).

        Parameters
        ----------
        params : dict
            Resolved parameters.
        n_points : int, optional
            Points of the surface about to be mapped (where a size decides what acts).

        Returns
        -------
        dict of str to str
            Name -> what it does not act on and what would make it act (a phrase after
            ``"<name>=<value> "``). :meth:`__call__` warns
            (:class:`InertParameterWarning`) for those the caller passed.
        """
        return {}

    def check_params(self, params: dict[str, Any]) -> None:
        """Checks of a plugin's parameters beyond ``choices`` (none by default).

        Runs before the surface is touched, so a bad value fails fast. Checks that need
        the surface belong in :meth:`solve`.

        Parameters
        ----------
        params : dict
            Resolved parameters.
        """

    def __call__(self, surface: Surface | MethodInput, **params: Any) -> Parameterization:
        """Validate, run and time the method.

        Parameters
        ----------
        surface : Surface or MethodInput
            A ``Surface`` is converted with :meth:`Surface.as_method_input` (its points,
            faces, normals, boundary loops and name; never its exact map, boundary mask,
            generator parameters or seed), so :meth:`run` and :meth:`solve` always receive
            a :class:`MethodInput`.
        **params
            Method parameters; see ``defaults``.

        Returns
        -------
        Parameterization
            With ``timings["total"]`` set and ``params`` fully resolved; one uv row per
            input point. A point-set method runs on one point per group of coincident
            points, and the copies get that point's uv
            (:func:`parambench.methods.pointset.coincident.run_on_representatives`). Point-set
            results (``needs_faces`` False) also carry ``diagnostics["selfcheck"]``, see
            :func:`parambench.methods.pointset.plugin_support.selfcheck_result`; its time is not in
            ``timings["total"]``.

        Warns
        -----
        CoincidentPointsWarning
            A point-set method's input had coincident points (they were merged).
        InertParameterWarning
            A parameter the caller passed does not act under the other values
            (:meth:`inert_params`).

        Raises
        ------
        InvalidInputError
            ``surface`` is neither a ``Surface`` nor a ``MethodInput``.
        MissingFacesError
            Mesh method given a point set.
        UnknownNameError
            Unknown parameter name, or a value outside ``choices``.
        ResourceLimitError
            The input is larger than the memory available holds for this method
            (``peak_memory``).
        """
        surface = as_method_input(surface)
        resolved = self.resolve_params(params)
        if self.needs_faces and not surface.has_faces:
            raise MissingFacesError(
                f"method {self.name!r} needs a triangle mesh but {surface.name!r} is a point set without faces; "
                "use a point-set method (e.g. 'ocp') or give a mesh file."
            )
        start = time.perf_counter()
        # Scale and pose: the method sees a centred, unit-size copy; uv comes back in input units.
        # Error hints name only this method's parameters (methods/hints.py).
        with method_hints(self.defaults, resolved):
            self.check_values(resolved)
            self._warn_inert(params, resolved, surface.n_points)
            if self.peak_memory is not None:
                check_memory(self.name, surface.n_points, self.peak_memory)
            result = self._run_point_or_mesh(surface, **resolved)
        # The self-check's time is its own (diagnostics["selfcheck"]["seconds"]), not the method's.
        check_seconds = result.diagnostics.get("selfcheck", {}).get("seconds", 0.0)
        result.timings["total"] = time.perf_counter() - start - check_seconds
        result.params = resolved
        result.method = self.name
        if result.uv.shape[0] != surface.n_points:
            raise InvalidInputError(
                f"method {self.name!r} returned {result.uv.shape[0]} uv rows for {surface.n_points} points (a bug)."
            )
        return result

    def _warn_inert(self, given: dict[str, Any], resolved: dict[str, Any], n_points: int | None = None) -> None:
        try:
            inert = self.inert_params(resolved, n_points)
        except TypeError:  # a plugin written for inert_params(params) alone
            inert = self.inert_params(resolved)
        for key, why in inert.items():
            if key in given:
                warnings.warn(InertParameterWarning(f"{self.name}: {key}={given[key]!r} {why}"),
                              stacklevel=3)

    def _run_point_or_mesh(self, surface: MethodInput, **params: Any) -> Parameterization:
        """Mesh methods: :meth:`run` in unit pose, its map checked on the mesh's faces
        (:func:`~parambench.methods.mesh.map_check.check_mesh_map`). Point-set methods:
        :meth:`_run_and_check` in unit pose on one point per group of coincident points (the
        pose is that of the distinct points, so copies change nothing), its uv copied to
        the others. Either check goes to ``diagnostics["selfcheck"]``."""
        if self.needs_faces:
            from .mesh.map_check import check_mesh_map

            result = run_in_unit_pose(self.run, surface, params)
            result.diagnostics["selfcheck"] = check_mesh_map(surface.points, surface.faces, result.uv)
            return result
        # Imported here because parambench.methods.pointset imports this module.
        from .pointset.coincident import run_on_representatives

        def checked_in_unit_pose(distinct: MethodInput, **kwargs: Any) -> Parameterization:
            return run_in_unit_pose(self._run_and_check, distinct, kwargs)

        return run_on_representatives(checked_in_unit_pose, surface, params)

    def _run_and_check(self, surface: MethodInput, **params: Any) -> Parameterization:
        """:meth:`run`, then the point-set self-check on the same points (``diagnostics["selfcheck"]``).

        Inside :func:`~parambench.methods.pointset.coincident.run_on_representatives`, so the check
        sees the distinct points the method saw, and reuses that run's front end. A run
        that raises SolverError on loops that fail the coverage check raises it restated
        (:func:`~parambench.methods.pointset.plugin_support.boundary_doubt`).
        """
        token = _RETRY_MEMO.set({})
        try:
            return self._checked_with_retries(surface, params)
        finally:
            _RETRY_MEMO.reset(token)

    def _checked_with_retries(self, surface: MethodInput, params: dict[str, Any]) -> Parameterization:
        from .pointset.plugin_support import boundary_doubt, selfcheck_result

        after_error = None
        try:
            result = self.run(surface, **params)
        except SolverError as exc:  # ConvergenceError included
            # A solve that fails on loops that miss the boundary: say so, not only the solver's advice.
            doubt = boundary_doubt(surface, exc)
            if doubt is not None:
                raise doubt from exc
            retry = self.error_retry_params(params, exc)
            if retry is None:
                raise
            result, after_error = self._run_after_error(surface, params, retry, exc)
            params = retry
        check = selfcheck_result(surface, result, conformal=self.conformal_map)
        if after_error is not None:
            check["after_error"] = after_error
        # Points far from all others fail every run alike: no parameter moves them onto the
        # surface; nor does one take a handle off it (a torus cut open: 4 retries, 16 s).
        hopeless = "isolated" in (check.get("failed") or ()) or "handle" in (check.get("causes") or {})
        retries = [] if check["passed"] or hopeless else _as_list(self.retry_params(params, check))
        notes: list[dict] = []
        runs = [(params, result.diagnostics)]  # the runs made: parameters, diagnostics
        kept, kept_check, kept_changed = result, check, {}
        seconds = check.get("seconds", 0.0)
        for retry in retries:
            if self.repeats_a_run(retry, runs):
                continue
            changed = {key: value for key, value in retry.items() if params.get(key) != value}
            # Whatever the last run left in reference cycles (errors caught and passed on
            # inside the solvers keep their frames' arrays) goes before the next one starts.
            gc.collect()
            try:
                second = self.run(surface, **retry)
            except ParambenchError as exc:  # a retry is another chance, never a new way to fail
                released(exc)  # the failed run's arrays go before the next retry
                fit_hints(exc, self.defaults, retry)  # what it suggests must exist for this method
                notes.append({"params": changed, "passed": False, "first_reason": check["reason"],
                              "error": f"{type(exc).__name__}: {exc}"})
                continue
            runs.append((retry, second.diagnostics))
            second_check = selfcheck_result(surface, second, conformal=self.conformal_map)
            # The earlier checks' time is the self-check's too, not the method's.
            seconds += second_check.get("seconds", 0.0)
            notes.append({"params": changed, "passed": bool(second_check["passed"]), "first_reason": check["reason"]})
            if second_check["passed"]:
                second_check["seconds"] = seconds
                second_check["retry"] = _retry_note(notes)
                _carry_after_error(check, second_check)
                return second
            if selfcheck_doubt(second_check) < selfcheck_doubt(kept_check):
                kept, kept_check, kept_changed = second, second_check, changed
            del second
        if notes:
            kept_check["retry"] = _retry_note(notes)
            kept_check["seconds"] = seconds
            if kept is not result:
                # Every run failed its check: the map kept is the least doubtful, and says whose it is.
                kept_check["kept"] = {"params": kept_changed, "first_reason": check["reason"]}
                _carry_after_error(check, kept_check)
        return kept

    def _run_after_error(self, surface: MethodInput, params: dict[str, Any], retry: dict[str, Any],
                         exc: SolverError) -> tuple[Parameterization, dict]:
        """The run with ``retry`` after the first run raised ``exc``: (result, the note kept as
        ``diagnostics["selfcheck"]["after_error"]``). When the retry fails too its error is
        raised, saying what was tried, its hints fitted to the retry's parameters (so they
        do not offer what was just tried)."""
        changed = {key: value for key, value in retry.items() if params.get(key) != value}
        first = f"{type(exc).__name__}: {exc}"
        released(exc)
        gc.collect()
        try:
            result = self.run(surface, **retry)
        except ParambenchError as second:
            released(second)
            fit_hints(second, self.defaults, retry)
            tried = ", ".join(f"{key}={value!r}" for key, value in changed.items())
            stem, hints = getattr(second, "parambench_hints", (None, ()))
            note = f"with {tried}, tried after {type(exc).__name__} with {self._changed_from(params, changed)}"
            if stem is None:
                raise type(second)(f"{str(second).rstrip('.')} ({note}).") from None
            # What was just tried is no remedy ("raise k_nn" offers any larger value).
            hints = [hint for hint in hints if hint.param not in changed]
            raise hinted(type(second), f"{stem} ({note})", *hints) from None
        return result, {"params": changed, "error": first}

    @staticmethod
    def _changed_from(params: dict[str, Any], changed: dict[str, Any]) -> str:
        return ", ".join(f"{key}={params.get(key)!r}" for key in changed)

    def error_retry_params(self, params: dict[str, Any], exc: SolverError) -> dict[str, Any] | None:
        """Parameters for one more run when the first raised a solver error (``exc``), or
        None (the error stands; the default). A point-set method's map from that run is
        self-checked as any other; ``diagnostics["selfcheck"]["after_error"]`` holds the
        changed parameters and the first error."""
        return None

    def retry_params(self, params: dict[str, Any], check: dict) -> dict[str, Any] | list | None:
        """Parameters for another run when the first map failed its self-check, or None (no retry).

        Point-set methods only. A list gives several, tried in order until a map passes
        (those :meth:`repeats_a_run` says would repeat a run already made are left out).
        A later map replaces the first only if it passes; either way
        ``diagnostics["selfcheck"]["retry"]`` says what was tried last (``params``: the
        changed ones), whether it passed and why the first failed, and ``earlier`` lists
        the attempts before it, when there were several.

        By default, after loops that missed boundary candidates, the front end's angle
        criterion lowered (:func:`~parambench.methods.pointset.plugin_support.coverage_retries`:
        nothing for a method without ``boundary_angle_deg``).
        """
        from .pointset.plugin_support import coverage_retries

        return coverage_retries(params, check) or None

    def repeats_a_run(self, retry: dict[str, Any], runs: list[tuple[dict, dict]]) -> bool:
        """Whether the retry ``retry`` (parameters) would only run again what one of ``runs``
        ran (the parameters and diagnostics of the runs made so far, the first run's first);
        such a retry is left out. False by default.
        """
        return False

    def run(self, surface: MethodInput, **params: Any) -> Parameterization:
        """Time :meth:`solve` on ``surface`` and wrap its output in a :class:`Parameterization`.

        No pose normalisation, merging of coincident points or parameter checks: that is
        :meth:`__call__`, the entry point callers use.

        Parameters
        ----------
        surface : MethodInput
            The input as the method sees it (unit pose, distinct points).
        **params
            Resolved parameters (every key of ``defaults``).

        Returns
        -------
        Parameterization
            ``uv``, ``diagnostics`` and ``faces`` from :meth:`solve`, the stage timings
            of its :class:`StageTimer`, this method's name and ``params``.
        """
        timer = StageTimer()
        out = self.solve(surface, params, timer)
        return Parameterization(uv=out.uv, method=self.name, params=dict(params), timings=timer.timings,
                                diagnostics=out.diagnostics, faces=out.faces)

    def solve(self, surface: MethodInput, params: dict[str, Any], timer: StageTimer) -> MethodOutput:
        """The method itself. Subclasses implement this.

        Parameters
        ----------
        surface : MethodInput
            The input in unit pose; for point-set methods, distinct points without faces.
            No ground truth: there is no exact map, boundary mask, parameters or seed;
            ``boundary_loops`` only when the caller supplied them.
        params : dict
            Resolved and checked parameters (every key of ``defaults``).
        timer : StageTimer
            Time each stage with ``with timer("name"):``; the stages become
            ``Parameterization.timings``.

        Returns
        -------
        MethodOutput
        """
        raise NotImplementedError(f"{type(self).__qualname__} implements neither solve nor run")


def _check_number_type(key: str, default: Any, value: Any) -> None:
    """Refuse a value of the wrong kind for a parameter whose default is a number or a bool.

    From Python, ``k_nn=None`` or ``reg_eps="abc"`` reached the numerics and raised a bare
    TypeError or ValueError there, while ``reg_eps="0.01"`` was quietly converted and
    ``k_nn="8"`` refused with "got 8". Parameters whose default is None or a string are left
    to ``choices`` and :meth:`Method.check_params`.

    Raises
    ------
    InvalidInputError
        A bool parameter given anything but a bool; a whole-number parameter given anything
        but a whole number; a real parameter given anything but a finite real number.
    """
    if isinstance(default, bool):
        ok, kind = isinstance(value, (bool, np.bool_)), "true or false"
    elif isinstance(default, (int, np.integer)):
        ok = (isinstance(value, (int, np.integer, float, np.floating)) and not isinstance(value, (bool, np.bool_))
              and np.isfinite(value) and float(value).is_integer())
        kind = "a whole number"
    elif isinstance(default, (float, np.floating)):
        ok = (isinstance(value, (int, np.integer, float, np.floating)) and not isinstance(value, (bool, np.bool_))
              and bool(np.isfinite(value)))
        kind = "a finite number"
    else:
        return
    if not ok:
        raise InvalidInputError(f"parameter {key} expects {kind}, got {value!r} ({type(value).__name__}).")


#: The memo of the checked run in progress (:meth:`Method._run_and_check`), None outside one.
_RETRY_MEMO: ContextVar[dict | None] = ContextVar("parambench_retry_memo", default=None)


def retry_memo() -> dict | None:
    """A dict that lives for one checked point-set run: the first run and its retries.

    A plugin may keep there what a retry with other parameters can reuse (``ocp`` keeps
    its map before the uv-mesh refinement, so a retry that changes only ``refine`` does
    not solve again). None outside such a run (:meth:`Method.run` called directly).
    Context-local, so runs in other threads each see their own.
    """
    return _RETRY_MEMO.get()


def _as_list(retry: dict | list | None) -> list[dict]:
    """:meth:`Method.retry_params`' answer as a list of parameter dicts."""
    if retry is None:
        return []
    return [retry] if isinstance(retry, dict) else list(retry)


#: Self-check failures that leave no usable map: its triangulation, loops or shape are
#: wrong as a whole, not in a few triangles.
_STRUCTURAL_FAILURES = frozenset({"check-error", "triangulation", "turning", "boundary-crossing", "distorted"})


def selfcheck_doubt(check: dict) -> tuple[bool, bool, int]:
    """How doubtful a point-set map is by its self-check facts; smaller is better.

    Ordered by: a structural failure (:data:`_STRUCTURAL_FAILURES`), then candidates off the
    loops ("coverage": a missed hole), then the count of flipped triangles (those of the uv
    triangulation and the reversed triangles of neighbouring points, plus the degenerate
    ones where those fail the check). A map that passed scores (False, False, 0).

    Parameters
    ----------
    check : dict
        ``diagnostics["selfcheck"]`` (:func:`~parambench.methods.pointset.plugin_support.selfcheck_result`).

    Returns
    -------
    tuple of (bool, bool, int)
    """
    failed = set(check.get("failed") or ())
    bad = (int(check.get("n_flipped") or 0) + int(check.get("n_ring_flipped") or 0)
           + (int(check.get("n_degenerate") or 0) if "degenerate" in failed else 0))
    return bool(failed & _STRUCTURAL_FAILURES), "coverage" in failed, bad


def _carry_after_error(first: dict, other: dict) -> None:
    """A retry's check keeps the note that the first run needed a second run after an error."""
    if "after_error" in first:
        other["after_error"] = first["after_error"]


def _retry_note(notes: list[dict]) -> dict:
    """The ``retry`` fact: the last attempt's note, with the ones before it under ``earlier``."""
    return notes[-1] if len(notes) == 1 else {**notes[-1], "earlier": notes[:-1]}
