"""What the mesh methods try where the requested map has no regular solution: other weights rows, other pins.

Both fallbacks run only after the method as asked (default pins, plain weights, with
:func:`parambench.methods.mesh.holes.solve_with_holes` and the k search's own fallbacks)
raised :class:`SolverError` / :class:`ConvergenceError` or returned a map whose boundary
is not regular, so every map that exists without them is returned unchanged. The one
returned says in its diagnostics which fallback made it.

Authalic rows (``weights="authalic"`` without ``uniform_at``): the rows of every vertex
with a negative authalic weight hold the uniform authalic weights instead
(``uniform_at="negative"``, :mod:`parambench.methods.mesh.weights`). Why: the authalic
weight of spoke ij is negative where an angle at x_j is obtuse, and where such weights
cancel most of a row, nothing holds the vertex to its neighbours. Measured on
``real/cortex-lh`` (12226 vertices, 48 % of the faces obtuse; 3150 rows with a negative
weight, 20 with a row sum <= 0, 10 of those on the boundary): the raw SCP map keeps an
extra turn because the boundary folds back on itself (a hairpin of 174 to 180 degrees)
at boundary vertex 5033, whose row sums to -0.003 of its absolute sum; the normalized
maps spin at every k (turning number 80, energy ever more negative) because vertex 458's
row sums to 0.012 of its absolute sum, so normalizing it gives weights of -43 and +38
and the map is dominated by that vertex (388 times the median boundary radius).
Switching fewer rows was erratic (measured with a symmetrised form of these rows): only
the rows with a sum <= 0, or <= 5 to 75 % of the absolute sum, left some of the three
variants without a regular map or gave one far above the energy's zero (QC up to 150);
the vertices of the folded faces of the raw map beyond the energy's zero and one to five
rings around them gave raw SCP maps with QC 2.2 to 3.5 and none with two rings, and the
normalized maps offer no such seed (they spin at every k, with about 4800 folded faces).
Every row with a negative weight gives regular maps for all three (QC 1.85 raw SCP, 2.77
normalized SCP, 2.02 raw DNCP, against 1.13 for cotangent SCP on that mesh), and, asked
for with ``uniform_at="negative"``, on the six other real meshes too (24 maps, at most
3 foldovers each; DNCP on ``real/bump-domain`` with the pin fallback below). The authalic weights computed on the intrinsic Delaunay triangulation
(``igl.intrinsic_delaunay_triangulation``) do not help: they have as many negative
weights (3550; Delaunay bounds the angles opposite an edge, authalic weights use the
angles at its far end), and normalized they still spin.

Other pins (``dncp-opt`` with ``pins="farthest"``, the default): with non-symmetric
weights no map has zero energy, so DNCP's map depends on its pins. Normalized authalic
DNCP on ``real/bump-domain`` spins at every k (turning numbers 3 to 110) with the
farthest pair, two of the four 90-degree corners of its square boundary, also with the
uniform authalic rows; it is regular with each of the six pairs of
:func:`~parambench.methods.mesh.pins.opposite_pairs` (QC 1.43 to 1.65, at most one
foldover) and with none of four other pairs tried that include a corner (measured
with the releases before scipy 1.17 / numpy 2.4). Which fallback rescues it depends
on the last bits of the solves: under scipy 1.17 / numpy 2.4 the farthest pair
(230, 232; the square's two diagonals tie, :func:`~parambench.methods.mesh.pins.farthest_pair`
takes the first in candidate order) is regular with the uniform authalic rows (QC
1.70, 0 foldovers), while the other diagonal (231, 233) still spins. Those pairs are
tried in their fixed order. Pins given as ``"i,j"`` are never changed.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

from parambench.datasets_gen.errors import ConvergenceError, SolverError
from parambench.datasets_gen.surface import MethodInput

from ..hints import hinted
from ..spectral.turning import is_regular_turning
from .conformal_setup import resolve_pins
from .pins import opposite_pairs
from .topology import require_connected_disk_like

__all__ = ["PIN_ALTERNATIVES", "AUTHALIC_FALLBACK", "Attempt", "mesh_attempts", "first_regular",
           "authalic_fallback_applies"]

#: Other pin pairs dncp-opt tries (``opposite_pairs``) before giving up.
PIN_ALTERNATIVES = 6
#: The ``uniform_at`` of the authalic fallback.
AUTHALIC_FALLBACK = "negative"


@dataclass(frozen=True)
class Attempt:
    """One way to solve, and what its map records when it is the one returned.

    Attributes
    ----------
    label : str
        What it changes, for the error message when every attempt fails (attempts with
        the same label are named once).
    run : callable
        ``run() -> (result, work, n_filled)`` as
        :func:`parambench.methods.mesh.holes.solve_with_holes` returns it, ``result[1]``
        the :class:`~parambench.methods.spectral.problem.ConformalSolution`.
    diagnostics : dict
        Added to the method's diagnostics when this attempt's map is returned.
    """

    label: str
    run: Callable[[], tuple]
    diagnostics: dict = field(default_factory=dict)


def authalic_fallback_applies(weights: str, uniform_at: Any) -> bool:
    """The authalic fallback is for plain authalic weights only (a given ``uniform_at`` is kept)."""
    return weights == "authalic" and uniform_at is None


def mesh_attempts(solve: Callable[[Any, tuple[int, int] | None], tuple], surface: MethodInput, *, weights: str,
                  uniform_at: Any, pins: Any = None) -> list[Attempt]:
    """A mesh method's attempts, in the order :func:`first_regular` runs them.

    1. As asked. 2. Authalic weights without ``uniform_at``: ``uniform_at="negative"``.
    3. ``pins="farthest"`` (DNCP's default): each of :data:`PIN_ALTERNATIVES` pairs of
    :func:`~parambench.methods.mesh.pins.opposite_pairs` on the outer loop, from the first
    farthest pin, with the weights as asked; 4. then (authalic) with ``uniform_at="negative"``.
    The weights come before the pins because where they are the cause (``real/cortex-lh``)
    other pins give no regular map or only one far above the energy's zero (module docstring).

    Parameters
    ----------
    solve : callable
        ``solve(uniform_at, pair) -> (result, work, n_filled)``: the method with that
        ``uniform_at`` and those pins (None: the method's own ``pins`` rule).
    surface : MethodInput
        The method's input (the pin pairs are chosen on its outer loop, which filling the
        holes does not change).
    weights, uniform_at
        The method's parameters.
    pins : optional
        DNCP's ``pins`` parameter; None for methods without pins.

    Returns
    -------
    list of Attempt
        The pin pairs are computed only when a pin attempt runs; its diagnostics then hold
        ``pins_fallback`` (the pair's rank, from 1) and ``pins_farthest``.
    """
    attempts = [Attempt("as asked", lambda: solve(uniform_at, None))]
    authalic = authalic_fallback_applies(weights, uniform_at)
    if authalic:
        attempts.append(Attempt(f"uniform_at={AUTHALIC_FALLBACK!r}", lambda: solve(AUTHALIC_FALLBACK, None),
                                {"authalic_fallback": AUTHALIC_FALLBACK}))
    if not (isinstance(pins, str) and pins == "farthest"):
        return attempts
    chosen: dict = {}   # filled by the first pin attempt that runs

    def pin_attempt(rows: Any, rank: int, label: str, diagnostics: dict) -> Attempt:
        def run():
            if not chosen:
                loops = require_connected_disk_like(surface.points, surface.faces)
                farthest = resolve_pins("farthest", surface.points, loops)  # the default pins
                chosen["farthest"] = [int(v) for v in farthest]
                chosen["pairs"] = opposite_pairs(surface.points, loops[0], farthest[0], PIN_ALTERNATIVES)
            if rank > len(chosen["pairs"]):
                raise ConvergenceError(f"the outer loop has only {len(chosen['pairs'])} other pin pairs")
            diagnostics["pins_farthest"] = chosen["farthest"]
            return solve(rows, chosen["pairs"][rank - 1])
        return Attempt(label, run, diagnostics)

    label = f"{PIN_ALTERNATIVES} other pin pairs"
    attempts += [pin_attempt(uniform_at, rank, label, {"pins_fallback": rank})
                 for rank in range(1, PIN_ALTERNATIVES + 1)]
    if authalic:
        attempts += [pin_attempt(AUTHALIC_FALLBACK, rank, f"{label} with uniform_at={AUTHALIC_FALLBACK!r}",
                                 {"pins_fallback": rank, "authalic_fallback": AUTHALIC_FALLBACK})
                     for rank in range(1, PIN_ALTERNATIVES + 1)]
    return attempts


def _regular(out: tuple) -> bool:
    sol = out[0][1]
    return bool(sol.diagnostics.get("regular_boundary", True)) and is_regular_turning(sol.turning)


def _why(out: tuple | None, err: Exception | None) -> str:
    if err is not None:
        return str(err).split("; ")[0].rstrip(".")
    return f"the map's boundary is not regular (turning numbers {out[0][1].turning.tolist()})"


def first_regular(attempts: Sequence[Attempt]) -> tuple[tuple, dict]:
    """Run the attempts in order until one gives a regular map.

    Parameters
    ----------
    attempts : sequence of Attempt
        The first is the method as asked; the others are only run when it fails.

    Returns
    -------
    out : tuple
        ``(result, work, n_filled)`` of the first attempt with a regular map; where none
        has one but the first attempt returned a map, that map (as before the fallbacks).
    diagnostics : dict
        Empty for the first attempt; otherwise that attempt's ``diagnostics`` and
        ``fallback_reason`` (why the first attempt failed).

    Raises
    ------
    SolverError, ConvergenceError
        The first attempt's error, naming the fallbacks that failed too, when no attempt
        returned a map.
    """
    first_out, first_err = None, None
    try:
        first_out = attempts[0].run()
    except (SolverError, ConvergenceError) as err:
        first_err = err
    if first_err is None and _regular(first_out):
        return first_out, {}
    for attempt in attempts[1:]:
        try:
            out = attempt.run()
        except (SolverError, ConvergenceError):
            continue
        if _regular(out):
            return out, {**attempt.diagnostics, "fallback_reason": _why(first_out, first_err)}
    if first_err is None:
        return first_out, {}
    if len(attempts) == 1:
        raise first_err
    stem, hints = getattr(first_err, "parambench_hints", (str(first_err).rstrip("."), ()))
    tried = ", ".join(dict.fromkeys(a.label for a in attempts[1:]))  # each label once, in order
    raise hinted(type(first_err), f"{stem} (also without a regular map: {tried})", *hints) from None
