"""A patch of a circular cylinder: developable, with an exact isometric unrolling."""

from __future__ import annotations

import numpy as np

from ..domains import Domain, Rect
from .base import Shape

__all__ = ["Cylinder"]


class Cylinder(Shape):
    """Cylinder patch of ``radius``, angular ``span`` (degrees) and ``height``.

    Parameters are the unrolled coordinates (u, v) = (radius * theta, z), theta centred on
    the +x axis, so the exact map is the identity on the domain (isometric).
    """

    name = "cylinder"
    description = "cylinder patch, radius 1, 180 deg span, height 2; exact map: unrolling (isometric)"
    defaults = {"radius": 1.0, "span": 180.0, "height": 2.0}
    exact_map_kind = "isometric"

    def _setup(self, radius: float, span: float, height: float) -> Domain:
        self._require(radius > 0 and height > 0, "radius and height must be positive.")
        self._require(0 < span < 360, f"span={span} must lie in (0, 360) degrees (an open patch).")
        half = 0.5 * radius * np.radians(span)
        return Domain(Rect((-half, -0.5 * height), (half, 0.5 * height)))

    def lift(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        x = np.asarray(x, dtype=float)
        r = self.options["radius"]
        theta = x[:, 0] / r
        c, s = np.cos(theta), np.sin(theta)
        return np.column_stack([r * c, r * s, x[:, 1]]), np.column_stack([c, s, np.zeros(len(x))])

    def area_factor(self, x: np.ndarray) -> np.ndarray:
        return np.ones(len(x))

    def exact_uv(self, x: np.ndarray) -> np.ndarray:
        return np.array(x, dtype=float, copy=True)
