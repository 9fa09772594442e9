"""Turning numbers of the image of the boundary loops: the penalty term of Eq. 16.

Holes: a faithful flattening maps the outer loop counter-clockwise (t = +1) and every
hole clockwise (t = -1), whichever loop ends up outside (for an annulus either may).
So the penalty sums ``| |t| - 1 |`` over all loops: 0 for a faithful map, and at least 1
per extra turn when any loop spins (|t| >= 2) or folds into a figure eight (t = 0). For a
disk this is the paper's ``|t(u)|`` minus the constant 1, which does not move the
minimiser of Eq. 16 but keeps ``q^2`` (down to 1e-18 near k_opt) resolvable next to the
penalty in double precision: with ``r |t| = 10`` added, E could not resolve q below 4e-8
and the DNCP map, which near k_opt moves by ~1e3 x (k - k_opt) on a disk whose two
smallest conformal modes are close, came out 5e-3 of the diameter off. A map counts as
*regular* when exactly one loop has t = +1 and all others t = -1.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..geometry2d import turning_number

__all__ = ["loop_turning_numbers", "turning_penalty", "is_regular_turning"]


def loop_turning_numbers(z: np.ndarray, loops: Sequence[np.ndarray]) -> np.ndarray:
    """Turning number of the image of each loop.

    Parameters
    ----------
    z : (V,) numpy.ndarray of complex128, or (V, 2) of float64
        The map.
    loops : sequence of (L_i,) numpy.ndarray of int64

    Returns
    -------
    (n_loops,) numpy.ndarray of int64
        Rounded to the nearest integer (exact closed polygons give integers up to ~1e-12).
    """
    uv = np.column_stack([z.real, z.imag]) if np.iscomplexobj(z) else np.asarray(z)
    return np.array([int(round(turning_number(uv[loop]))) for loop in loops], dtype=np.int64)


def turning_penalty(turning: np.ndarray) -> float:
    """Sum of ``| |t| - 1 |`` over the loops: 0 for a regular map."""
    return float(np.sum(np.abs(np.abs(np.asarray(turning)) - 1)))


def is_regular_turning(turning: np.ndarray) -> bool:
    """True when exactly one loop turns +1 and every other loop -1."""
    t = np.asarray(turning)
    return bool(np.sum(t == 1) == 1 and np.sum(t == -1) == t.size - 1)
