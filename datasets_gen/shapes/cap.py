"""Spherical cap on the unit sphere, parameterised by geodesic polar coordinates."""

from __future__ import annotations

import numpy as np

from ..domains import Disk, Domain
from .base import Shape

__all__ = ["Cap"]


class Cap(Shape):
    """Cap of half-angle ``half_angle`` degrees around the north pole of the unit sphere.

    The parameter domain is the azimuthal equidistant chart (x = theta * (cos phi, sin phi),
    theta the polar angle): distances from the pole are exact and the area factor
    sin(theta)/theta stays above 0.82 at 60 degrees, so a lattice there is a near-regular
    sampling of the sphere. Mesh chart and exact map: stereographic projection from the
    south pole, u + iv = tan(theta/2) e^{i phi} (conformal).
    """

    name = "cap"
    description = "spherical cap, half-angle 60 deg, unit sphere; exact map: stereographic (conformal)"
    defaults = {"half_angle": 60.0}
    exact_map_kind = "conformal"

    def _setup(self, half_angle: float) -> Domain:
        self._require(5.0 <= half_angle <= 150.0, f"half_angle={half_angle} must lie in [5, 150] degrees.")
        return Domain(Disk((0.0, 0.0), np.radians(half_angle)))

    def lift(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        x = np.asarray(x, dtype=float)
        theta = np.hypot(x[:, 0], x[:, 1])
        xy = x * np.sinc(theta / np.pi)[:, None]  # sin(theta)/theta, finite at the pole
        pts = np.column_stack([xy, np.cos(theta)])
        return pts, pts.copy()

    def area_factor(self, x: np.ndarray) -> np.ndarray:
        return np.sinc(np.hypot(x[:, 0], x[:, 1]) / np.pi)

    def chart(self, x: np.ndarray) -> np.ndarray:
        pts, _ = self.lift(x)
        return pts[:, :2] / (1.0 + pts[:, 2])[:, None]

    def exact_uv(self, x: np.ndarray) -> np.ndarray:
        return self.chart(x)
