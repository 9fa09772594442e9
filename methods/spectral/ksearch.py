"""The k line search of Sec. 4.2 (Eq. 16), independent of how a map is computed at k.

``E(k) = q(k)^2 + r * sum_loops | |t(u_k)| - 1 |`` where ``q(k)`` is the normalised
conformal energy ``z^H (k L / 2 - M) z / z^H B z`` of the map u_k found at that k (SCP
or DNCP) and t the turning numbers of the boundary loops (see :mod:`.turning`; for a
disk the penalty is the paper's ``r |t|`` minus the constant r, which keeps q^2
resolvable). Below k_opt the map spins (t >= 2) or its energy is negative; above k_opt
it is regular and q > 0 grows. The search therefore

1. evaluates k0 = 1; if the map there is *good* (regular turning and q >= 0) it steps
   down geometrically until it is not, otherwise up until it is; the last two k bracket
   the transition (the paper searches forward from k = 1; stepping down is needed for
   weights like the cotangent ones whose k_opt is at or just below 1). When a step up
   turns a regular map with q < 0 into a spinning one, the step is bisected first: the
   good region can be narrower than a step (DNCP pinned on a hole: about 5e-4 wide);
2. bisects on "good" until the bracket is narrow (relative 1e-4), because the t = 1
   bowl is often far narrower than the geometric step;
3. minimises E over that bracket with bounded Brent (``scipy.optimize.minimize_scalar``);
4. polishes: if regular maps with q < 0 and q > 0 straddle the minimiser, the zero of q
   between them is found to machine precision (``scipy.optimize.brentq``). Near k_opt a
   pinned (DNCP) map can move by ~1e3 x (k - k_opt), so k must be exact.

Each step of t adds r to E, so the minimiser cannot slide back into a spinning bowl.

:func:`root_search_near` is the short form for a landscape whose k_opt is known to within
a small relative distance (a search repeated on a slightly grown subspace, or started
from an eigenvalue estimate): a secant step and a bracketed root find on q, or None when
the landscape there is not that simple.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from parambench.datasets_gen.errors import ConvergenceError, InvalidInputError

from ..hints import Hint, hinted
from .turning import is_regular_turning, turning_penalty

__all__ = ["KPoint", "KSearchResult", "line_search", "root_search_near", "penalized_energy", "DEFAULT_R"]

#: The paper's r in Eq. 16.
DEFAULT_R = 10.0


@dataclass
class KPoint:
    """One evaluation of the landscape.

    Attributes
    ----------
    k : float
    energy : float
        Normalised conformal energy q(k) (signed).
    turning : (n_loops,) numpy.ndarray of int64
    state : Any
        Whatever the evaluator needs to rebuild the map (e.g. boundary values).
    """

    k: float
    energy: float
    turning: np.ndarray
    state: Any = field(default=None, repr=False)

    @property
    def regular(self) -> bool:
        """Turning numbers of a faithful map (one loop +1, the others -1)."""
        return is_regular_turning(self.turning)

    @property
    def good(self) -> bool:
        """Regular and with non-negative energy: at or above k_opt."""
        return self.regular and self.energy >= 0.0


def penalized_energy(point: KPoint, r: float = DEFAULT_R) -> float:
    """Eq. 16 up to a constant: ``q^2 + r * sum | |t| - 1 |``."""
    return point.energy ** 2 + r * turning_penalty(point.turning)


@dataclass
class KSearchResult:
    """Outcome of :func:`line_search`.

    Attributes
    ----------
    k_opt : float
    best : KPoint
        The evaluation at k_opt.
    bracket : tuple of float
        The (lower, upper) k handed to the bounded minimiser.
    landscape : dict
        Lists ``k``, ``E``, ``q``, ``t`` (turning numbers per loop) in evaluation order.
    n_evaluations : int
    """

    k_opt: float
    best: KPoint
    bracket: tuple[float, float]
    landscape: dict
    n_evaluations: int


def line_search(evaluate: Callable[[float], KPoint], *, k0: float = 1.0, growth: float = 1.25, max_steps: int = 40,
                r: float = DEFAULT_R, xatol: float = 1e-9, maxiter: int = 100, refine_rtol: float = 1e-4,
                refine_steps: int = 40, bracket: tuple[float, float] | None = None) -> KSearchResult:
    """Find k_opt by Eq. 16.

    Parameters
    ----------
    evaluate : callable
        ``evaluate(k) -> KPoint``; called once per distinct k.
    k0 : float
        Start of the geometric search (> 0).
    growth : float
        Ratio between successive k of the bracketing steps (> 1).
    max_steps : int
        Bracketing steps before giving up.
    r : float
        Turning-number penalty weight.
    xatol : float
        Absolute tolerance on k of the bounded minimiser, relative to the upper bracket end.
    maxiter : int
        Iterations of the bounded minimiser.
    refine_rtol, refine_steps : float, int
        Before minimising, bisect (geometrically) on "good" until ``hi / lo - 1`` is at
        most ``refine_rtol`` or ``refine_steps`` were taken.
    bracket : (float, float), optional
        Skip the bracketing and minimise in this interval; its upper end must be good
        (regular, q >= 0) and its lower end not.

    Returns
    -------
    KSearchResult

    Raises
    ------
    InvalidInputError
        k0 <= 0, growth <= 1, or a bracket that is not ``0 < lower < upper``.
    ConvergenceError
        No t = 1 crossing was found (within ``max_steps``, or in ``bracket``), the
        minimiser did not converge, or it ended on a spinning map.
    """
    if not k0 > 0 or not growth > 1:
        raise InvalidInputError(f"the k search needs k0 > 0 and growth > 1, got k0={k0}, growth={growth}.")
    ev = _Landscape(evaluate, r)
    lo, hi = _check_bracket(ev, bracket) if bracket is not None else _find_bracket(ev, k0, growth, max_steps)
    lo, hi = _narrow_bracket(ev, lo, hi, refine_rtol, refine_steps)
    _minimise(ev, lo, hi, r, xatol, maxiter)
    best = _best_regular(ev, lo, hi, r)
    return KSearchResult(k_opt=best.k, best=best, bracket=(lo, hi), landscape=ev.record,
                         n_evaluations=len(ev.points))


def root_search_near(evaluate: Callable[[float], KPoint], k: float, *, r: float = DEFAULT_R, width: float = 4e-3,
                     first_step: float = 1e-7, max_steps: int = 12, k_rtol: float = 1e-13) -> KSearchResult | None:
    """k_opt as the zero of q near a known estimate k, by a bracketed root find alone.

    For a landscape that has moved little since k was its k_opt (the repeated searches
    on a grown boundary subspace, :mod:`.subspace`: measured 1e-8 to 2e-4 relative), the
    bracketing, bisection and minimisation of :func:`line_search` (about 20 evaluations)
    only rediscover that q crosses zero between regular maps next to k. This starts
    there: a secant step from k and a probe ``first_step`` away gives a bracket of
    opposite signs of q, both maps regular, and regula falsi finds the zero to the
    tolerance of :func:`line_search`'s polish, or until q is within ``k_rtol`` of the
    zero by the bracket's slope (measured: 3-5 evaluations).
    Whenever the landscape near k is not that simple (a spinning map met, no sign change
    within ``width``), it returns None and the caller runs :func:`line_search`.

    Parameters
    ----------
    evaluate : callable
        ``evaluate(k) -> KPoint``.
    k : float
        The estimate (> 0).
    r : float
        Turning-number penalty weight of the recorded E.
    width : float
        Give up when a bracket would reach farther than ``width * k`` from k.
    first_step : float
        Relative distance of the probe that gives the first secant slope.
    max_steps : int
        Secant or widening steps before giving up.
    k_rtol : float
        Stop the root find at a regular map with ``|q / slope| <= k_rtol * k``. The
        rounding of q (measured ~1e-16 absolute with slopes ~1e-2 at 10k-20k points, so
        ~1e-14 in k) would leave the last steps to 1e-15 k bouncing in the noise
        (4-6 evaluations per search with brentq, measured).

    Returns
    -------
    KSearchResult or None
        ``bracket`` is the (lower, upper) handed to the root find.
    """
    ev = _Landscape(evaluate, r)
    a = ev(k)
    if not a.regular:
        return None
    if a.energy != 0.0:
        direction = -1.0 if a.energy > 0 else 1.0
        b = ev(k * (1.0 + direction * first_step))
        for _ in range(max_steps):
            if not b.regular:
                return None
            if b.energy == 0.0 or (b.energy > 0) != (a.energy > 0):
                break
            # Same sign: take the secant estimate of the zero, 10 % beyond it so that it
            # brackets (q is close to linear at this scale), at least doubling the reach.
            slope = (b.energy - a.energy) / (b.k - a.k)
            reach = abs(b.k - a.k)
            estimate = b.k - b.energy / slope if slope != 0.0 else b.k + direction * 2.0 * reach
            k_next = b.k + direction * max(1.1 * abs(estimate - b.k), 2.0 * reach)
            if abs(k_next / k - 1.0) > width:
                return None
            a, b = b, ev(k_next)
        else:
            return None
        if b.energy != 0.0:
            q_tol = abs((b.energy - a.energy) / (b.k - a.k)) * k_rtol * k
            best = _root_between(ev, a, b, q_tol)
            if best is None:
                return None
        else:
            best = b
        a, b = sorted((a, b), key=lambda p: p.k)
    else:
        best = b = a
    return KSearchResult(k_opt=best.k, best=best, bracket=(a.k, b.k), landscape=ev.record,
                         n_evaluations=len(ev.points))


def _root_between(ev: Callable[[float], KPoint], a: KPoint, b: KPoint, q_tol: float = 0.0,
                  max_iter: int = 60) -> KPoint | None:
    """The zero of q between regular maps a and b of opposite energy sign, or None when a spinning map is met.

    Regula falsi with the Illinois modification (an end kept twice in a row has its q
    halved, so both ends move): q is close to linear here and the first secant step
    lands within ~1e-14 of the zero (measured). Written out rather than calling
    ``scipy.optimize.brentq``, because importing scipy.optimize costs ~0.08 s of CPU
    per process and this is its only use on ``parambench flatten``'s usual path. Stops
    at a regular map with ``|q| <= q_tol``, or when the bracket is within 1e-15 k (the
    xtol of :func:`_polish_root`'s brentq).
    """
    lo, hi = sorted((a, b), key=lambda p: p.k)
    q_lo, q_hi = lo.energy, hi.energy
    kept = 0  # +1: hi was kept by the last step, -1: lo was
    for _ in range(max_iter):
        if hi.k - lo.k <= 1e-15 * hi.k:
            break
        k_new = (lo.k * q_hi - hi.k * q_lo) / (q_hi - q_lo)
        if not lo.k < k_new < hi.k:
            k_new = 0.5 * (lo.k + hi.k)
        p = ev(k_new)
        if not p.regular:
            return None
        if p.energy == 0.0 or abs(p.energy) <= q_tol:
            return p
        if (p.energy > 0) == (hi.energy > 0):
            hi, q_hi = p, p.energy
            if kept == -1:
                q_lo *= 0.5
            kept = -1
        else:
            lo, q_lo = p, p.energy
            if kept == 1:
                q_hi *= 0.5
            kept = 1
    return min((lo, hi), key=lambda e: abs(e.energy))


class _Landscape:
    """``evaluate`` memoised per distinct k, recording k, E, q and t in evaluation order.

    Parameters
    ----------
    evaluate : callable
        ``evaluate(k) -> KPoint``.
    r : float
        Turning-number penalty weight of the recorded E.
    """

    def __init__(self, evaluate: Callable[[float], KPoint], r: float) -> None:
        self._evaluate = evaluate
        self._r = r
        #: Evaluations by k, in evaluation order (ties in E go to the earliest).
        self.points: dict[float, KPoint] = {}
        self.record: dict[str, list] = {"k": [], "E": [], "q": [], "t": []}

    def __call__(self, k: float) -> KPoint:
        k = float(k)
        if k not in self.points:
            p = self._evaluate(k)
            self.points[k] = p
            self.record["k"].append(k)
            self.record["E"].append(float(penalized_energy(p, self._r)))
            self.record["q"].append(float(p.energy))
            self.record["t"].append([int(v) for v in p.turning])
        return self.points[k]


def _check_bracket(ev: Callable[[float], KPoint], bracket: tuple[float, float]) -> tuple[float, float]:
    """A given bracket as floats, after checking its upper end is good and its lower end not."""
    lo, hi = (float(v) for v in bracket)
    if not 0 < lo < hi:
        raise InvalidInputError(f"a k bracket must satisfy 0 < lower < upper, got {bracket}.")
    p_hi = ev(hi)
    if not p_hi.good:
        raise hinted(
            ConvergenceError,
            f"no t = 1 crossing in the k bracket [{lo:g}, {hi:g}]: at k = {hi:g} the boundary turning numbers are "
            f"{p_hi.turning.tolist()} and the energy {p_hi.energy:.3g}",
            Hint("widen the bracket upwards or let the search bracket by itself", "bracket"), Hint("use k_search='direct'", "k_search", "direct"),
        )
    if ev(lo).good:
        raise hinted(
            ConvergenceError,
            f"no t = 1 crossing in the k bracket [{lo:g}, {hi:g}]: the map is already regular with positive "
            "energy at the lower end, so k_opt lies below it",
            Hint("lower the bracket", "bracket"), Hint("use k_search='direct'", "k_search", "direct"),
        )
    return lo, hi


def _find_bracket(ev: Callable[[float], KPoint], k0: float, growth: float, max_steps: int) -> tuple[float, float]:
    """Step 1: (not-good k, good k) from geometric steps from k0, down if k0 is good, else up."""
    k = float(k0)
    p = ev(k)
    step = 1.0 / growth if p.good else growth
    for _ in range(max_steps):
        k_next = k * step
        p_next = ev(k_next)
        if p_next.good != p.good:
            return tuple(sorted((k, k_next)))
        if step > 1 and p.regular and not p_next.regular:
            # A regular map with q < 0 turned into a spinning one within one step:
            # the good region may be narrower than the step (DNCP pinned on a hole).
            found = _good_between(ev, k, k_next)
            if found is not None:
                return found
        k, p = k_next, p_next
    direction = "down" if step < 1 else "up"
    raise hinted(
        ConvergenceError,
        f"no t = 1 crossing found stepping {direction} from k = {k0:g} to k = {k:g} in {max_steps} steps "
        f"(last turning numbers {p.turning.tolist()}, energy {p.energy:.3g}); the weights' scale is far "
        "from the conformal one",
        Hint("try normalized=False", "normalized", False), Hint("use k_search='direct'", "k_search", "direct"),
    )


def _narrow_bracket(ev: Callable[[float], KPoint], lo: float, hi: float, refine_rtol: float,
                    refine_steps: int) -> tuple[float, float]:
    """Step 2: geometric bisection on "good" until ``hi / lo - 1 <= refine_rtol`` (or ``refine_steps``)."""
    # The t = 1 bowl can be a tiny part of the bracket (cotangent DNCP: about 3e-5 of a
    # bracket [0.8, 1]) and Brent's golden-section steps would keep landing on spinning
    # maps; bisect on "good" first so the bracket hugs the transition.
    for _ in range(refine_steps):
        if hi / lo - 1.0 <= refine_rtol:
            break
        mid = float(np.sqrt(lo * hi))
        if ev(mid).good:
            hi = mid
        else:
            lo = mid
    return lo, hi


def _minimise(ev: Callable[[float], KPoint], lo: float, hi: float, r: float, xatol: float, maxiter: int) -> None:
    """Step 3: bounded Brent on E over [lo, hi]; its evaluations land in ``ev``, where step 4 picks the best."""
    # scipy.optimize costs ~0.09 s to import; only k searches need it, not every command.
    from scipy.optimize import minimize_scalar

    res = minimize_scalar(lambda kk: penalized_energy(ev(kk), r), bounds=(lo, hi), method="bounded",
                          options={"xatol": xatol * hi, "maxiter": maxiter})
    if not res.success:
        raise hinted(ConvergenceError,
                     f"the bounded k minimisation in [{lo:g}, {hi:g}] did not converge ({res.message})",
                     Hint("raise maxiter", "maxiter"), Hint("use k_search='direct'", "k_search", "direct"))


def _best_regular(ev: _Landscape, lo: float, hi: float, r: float) -> KPoint:
    """Step 4: the regular evaluation of least E so far, polished to the zero of q when one is straddled."""
    regular = [p for p in ev.points.values() if p.regular]
    if not regular:
        raise hinted(ConvergenceError, f"every map evaluated in [{lo:g}, {hi:g}] spins (turning numbers != 1)",
                     Hint("use k_search='direct'", "k_search", "direct"))
    best = min(regular, key=lambda p: penalized_energy(p, r))
    return _polish_root(ev, regular + [best], best) if best.energy != 0.0 else best


def _good_between(ev: Callable[[float], KPoint], lo: float, hi: float, max_halvings: int = 60
                  ) -> tuple[float, float] | None:
    """(not-good k, good k) inside [lo, hi], where lo is regular with q < 0 and hi spins.

    Bisects: a regular map with q < 0 moves the lower end up, a spinning one the upper end
    down, until a good map turns up. None when the interval shrinks to nothing first.
    """
    for _ in range(max_halvings):
        mid = 0.5 * (lo + hi)
        if not lo < mid < hi:
            return None
        p = ev(mid)
        if p.good:
            return lo, mid
        if p.regular:
            lo = mid
        else:
            hi = mid
    return None


def _polish_root(ev: Callable[[float], KPoint], regular: list[KPoint], best: KPoint) -> KPoint:
    """The zero of q between the closest regular maps of opposite energy sign around ``best``."""
    below = [p for p in regular if p.energy < 0 and p.k < best.k] if best.energy > 0 else []
    above = [p for p in regular if p.energy > 0 and p.k > best.k] if best.energy < 0 else []
    if best.energy > 0 and below:
        lo, hi = max(below, key=lambda p: p.k).k, best.k
    elif best.energy < 0 and above:
        lo, hi = best.k, min(above, key=lambda p: p.k).k
    else:
        return best

    def q(kk: float) -> float:
        p = ev(kk)
        # A spinning map inside the interval ends the polish at the side it lies on.
        return p.energy if p.regular else (1.0 if p.k > best.k else -1.0) * abs(best.energy)

    from scipy.optimize import brentq  # lazily, as in line_search

    try:
        k_root = brentq(q, lo, hi, xtol=1e-15 * hi, rtol=4 * np.finfo(float).eps, maxiter=60)
    except (ValueError, RuntimeError):
        return best
    p = ev(k_root)
    return p if p.regular and abs(p.energy) <= abs(best.energy) else best
