"""Spacing that yields a requested number of points."""

from __future__ import annotations

import numpy as np

__all__ = ["spacing_for_count", "LATTICE_DENSITY", "BOUNDARY_EXCESS"]

#: Points per unit area of a triangular lattice of unit spacing, 2 / sqrt(3).
LATTICE_DENSITY = 2.0 / np.sqrt(3.0)
#: Net points per unit boundary length and unit spacing: the boundary points minus the
#: lattice points removed near the boundary (measured over the procedural shapes).
BOUNDARY_EXCESS = 0.37


def spacing_for_count(n: float, area: float, length: float) -> float:
    """The spacing h with ``LATTICE_DENSITY * area / h^2 + BOUNDARY_EXCESS * length / h = n``.

    Parameters
    ----------
    n : float
        Target point count, > 0.
    area, length : float
        Domain area and total boundary length, in the same units as the returned h.

    Returns
    -------
    float
    """
    a, b = LATTICE_DENSITY * area, BOUNDARY_EXCESS * length
    inv_h = (-b + np.sqrt(b * b + 4.0 * a * n)) / (2.0 * a)
    return float(1.0 / inv_h)
