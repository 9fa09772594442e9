"""What to try after a map failed its self-check: one line for the user.

The line names what failed (the check's reason) and one change worth trying: a cause told
from the geometry where it names no parameter (:func:`.failure_causes.cause_advice`: a part
thinner than the sampling, stray points), else a parameter of the method that ran, changed
beyond what its retries already tried (:func:`suggest_fix`), so the advice never sends the
user in a circle. A mesh map's check has advice of its own (:func:`mesh_advice`).
"""

from __future__ import annotations

from typing import Any

from .failure_causes import cause_advice

__all__ = ["suggest_fix", "failure_line", "mesh_advice", "MAX_STEPS"]


#: Per failed check, most telling first (a spinning boundary also folds and stretches
#: triangles): (parameter, how to change it) in order of preference.
_FIXES = {
    "turning": [("k_search", "line"), ("k", "x10"), ("ball_eps_factor", "raise"), ("k_nn", "raise")],
    "coverage": [("boundary_angle_deg", "lower"), ("ball_eps_factor", "raise")],
    "flipped": [("k_nn", "raise"), ("ball_eps_factor", "raise"), ("n_neighbors", "raise")],
    "boundary-crossing": [("k_nn", "raise"), ("ball_eps_factor", "raise"), ("n_neighbors", "raise")],
    "degenerate": [("ball_eps_factor", "raise"), ("k_nn", "raise"), ("n_neighbors", "raise")],
    "triangulation": [("k_nn", "raise"), ("n_neighbors", "raise")],
    "distorted": [("refine", "mesh"), ("k_nn", "raise")],
    "outside": [("boundary_angle_deg", "lower"), ("k_nn", "raise")],
}


def _step(how: str, value: Any) -> Any:
    """``value`` changed one step the way ``how`` says (a number; ``how`` not "line" / "mesh")."""
    if how == "x10":  # scp-tan's fixed k: k_opt of W^tan is ~10-25 (Sec. 4.2)
        return 10 * value
    if how == "lower":
        return value - 20
    if isinstance(value, int):
        return value + 4
    return float(f"{value * 1.4:.3g}")


#: Steps from the method's default a proposal may reach: advice relative to the value the
#: run used grew without end when followed (fbcp-pc on random points of a square proposed
#: ball_eps_factor 3.5, 4.9, 6.86, 9.6, 13.5 in turn, none of which helped).
MAX_STEPS = 2


def _proposal(key: str, how: str, current: Any, default: Any = None) -> str | None:
    if how in ("line", "mesh"):
        return None if current == how else f"{key}={how}"
    if not isinstance(current, (int, float)) or isinstance(current, bool):
        return None
    proposed = _step(how, current)
    if isinstance(default, (int, float)) and not isinstance(default, bool):
        reach = default
        for _ in range(MAX_STEPS):
            reach = _step(how, reach)
        if (proposed - reach) * (_step(how, default) - default) > 0:  # past the reach, the way it moves
            return None
    return f"{key}={proposed:g}"


def suggest_fix(failed: list[str], params: dict, method: str) -> str:
    """A parameter change worth trying for the first failed check, as ``--param KEY=VALUE``.

    Parameters
    ----------
    failed : list of str
        ``diagnostics["selfcheck"]["failed"]``.
    params : dict
        The parameters the method ran with (only keys present here are proposed).
    method : str
        Method name, for the fallback advice.

    Returns
    -------
    str
        E.g. ``"try --param boundary_angle_deg=100"``, or advice to try ``ocp``. A change is
        proposed only within :data:`MAX_STEPS` steps of the method's default, so following
        the advice ends.
    """
    defaults = _defaults(method)
    for name in sorted(failed, key=lambda f: list(_FIXES).index(f) if f in _FIXES else len(_FIXES)):
        for key, how in _FIXES.get(name, []):
            if key in params:
                change = _proposal(key, how, params[key], defaults.get(key))
                if change:
                    return f"try --param {change}"
    if method != "ocp":
        return "try another method, e.g. --method ocp"
    return "try --param k_nn=12" if params.get("k_nn", 12) < 12 else "try --method sdp"


def _defaults(method: str) -> dict:
    """The registered method's defaults, or {} (an unknown name: proposals then have no reach)."""
    from ..registry import all_methods

    cls = all_methods().get(method)
    return dict(cls.defaults) if cls is not None else {}


def mesh_advice(check: dict, params: dict, method: str) -> str:
    """What to try after a mesh map failed its check (:func:`~parambench.methods.mesh.map_check.check_mesh_map`).

    Where every flipped face sits at a fold of the mesh itself, no weights help; a non-finite
    uv is a failed solve; holes whose images cross each other or the rim drifted (filled,
    they cannot); a boundary that crosses itself with no flipped triangle is a surface that
    winds round (no weights help either); collapsed triangles alone are a
    protrusion the conformal map shrank. Otherwise the hybrid weights (Sec. 5), made to remove folds, then ``scp`` with
    them, then remeshing.
    """
    n_flipped = int(check.get("n_flipped") or 0)
    if n_flipped and check.get("n_folded_3d") == n_flipped:
        return "the mesh folds back on itself at those faces: repair its geometry there"
    if check.get("n_nonfinite"):
        return "the solve gave no uv at some vertices: try another method (parambench list)"
    if check.get("n_crossings_of_holes"):
        # holes' images drifting over each other or the rim: a filled hole cannot drift
        if params.get("holes") == "free":  # "auto" tried the filled holes already
            return "its holes' images overlap: try --param holes=filled"
        if "holes" not in params:
            return "its holes' images overlap: try --method scp (it fills holes whose free images overlap)"
    if not n_flipped and check.get("n_boundary_crossings") and not check.get("n_degenerate"):
        return ("the surface winds round further than one flat map can hold without overlap (as a helical strip "
                "does): cut it into pieces that each lie flat")
    if not n_flipped:  # collapsed triangles alone: a conformal map shrinks a protrusion exponentially
        return "cut the shrunk protrusion off, or cut a seam along it, before flattening"
    if "weights" in params and params["weights"] != "hybrid":
        return "try --param weights=hybrid"
    if method != "scp":
        return "try --method scp --param weights=hybrid"
    return "remesh the surface into better-shaped triangles (e.g. pymeshlab meshing_isotropic_explicit_remeshing)"


def failure_line(check: dict, params: dict, method: str) -> str:
    """One line, no final period: what failed and what to try."""
    if check.get("kind") == "mesh":
        return f"{method}: the map fails its self-check: {check['reason']}; {mesh_advice(check, params, method)}"
    # After a failed retry (Method.retry_params) propose beyond what it already tried.
    retry = check.get("retry", {})
    tried = dict(params)
    for note in [check.get("after_error") or {}, *retry.get("earlier", []), retry]:
        tried.update(note.get("params", {}))
    advice, alone = cause_advice(check.get("causes", {}), check["failed"])
    hint = advice if alone else "; ".join(a for a in (advice, suggest_fix(check["failed"], tried, method)) if a)
    if method == "ocp" and retry and not alone:
        # Its own retries failed, and the parameters it offers then tend to hand the user from
        # one to the next (a plane under normal noise of 0.3 spacings, 4000 random points: k_nn=16,
        # then boundary_angle_deg and ball_eps_factor, each failing and naming the other), where
        # sdp's map passed its check, 2.4 % of the diameter off the exact one.
        hint += "; or try --method sdp (the spectral Dirichlet map: no k search, less conformal)"
    return f"{method}: the map fails its self-check: {check['reason']}; {hint}"
