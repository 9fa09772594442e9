"""Flat shapes: the unit square and the square with circular holes. Exact map: identity."""

from __future__ import annotations

import numpy as np

from ..domains import Disk, Domain
from .base import Shape, square, unit_square

__all__ = ["Plane", "Holes", "HOLES"]

#: The holes of "holes" and "holes-bumped": fixed, disjoint, away from the centre bump.
HOLES = (Disk((-0.5, 0.45), 0.22), Disk((0.5, 0.4), 0.2), Disk((0.05, -0.5), 0.25))


class Flat(Shape):
    """A planar domain lying in z = 0; the exact map is the identity."""

    exact_map_kind = "conformal"

    def lift(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        x = np.asarray(x, dtype=float)
        n = len(x)
        return np.column_stack([x, np.zeros(n)]), np.tile([0.0, 0.0, 1.0], (n, 1))

    def area_factor(self, x: np.ndarray) -> np.ndarray:
        return np.ones(len(x))

    def exact_uv(self, x: np.ndarray) -> np.ndarray:
        return np.array(x, dtype=float, copy=True)


class Plane(Flat):
    name = "plane"
    description = "flat unit square in z=0; exact map: identity"

    def _setup(self) -> Domain:
        return Domain(unit_square())


class Holes(Flat):
    name = "holes"
    description = "flat square [-1,1]^2 with 3 circular holes; exact map: identity"

    def _setup(self) -> Domain:
        return Domain(square(), HOLES)
