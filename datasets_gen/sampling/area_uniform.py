"""Points uniformly distributed by surface area (rejection sampling in the parameter domain)."""

from __future__ import annotations

import numpy as np

__all__ = ["sample_by_area"]


def sample_by_area(shape, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` parameter points whose lifts are uniform on the surface.

    Proposals are uniform in the domain's bounding box; one inside the domain is kept with
    probability J(x) / J_max, J the area factor, so the kept density is proportional to
    surface area.

    Parameters
    ----------
    shape : Shape
    n : int
    rng : numpy.random.Generator

    Returns
    -------
    (n, 2) numpy.ndarray of float64
        Strictly inside the domain.
    """
    lo, hi = shape.domain.bbox
    j_max = shape.area_factor_bound
    box = float(np.prod(hi - lo))
    # expected keep rate: (surface area / J_max) / box area
    rate = max(shape.surface_area / (j_max * box), 1e-3)
    out, got = [], 0
    while got < n:
        m = int((n - got) / rate * 1.1) + 64
        x = lo + rng.random((m, 2)) * (hi - lo)
        x = x[shape.domain.contains(x)]
        x = x[rng.random(len(x)) * j_max < shape.area_factor(x)]
        out.append(x)
        got += len(x)
    return np.concatenate(out)[:n]
