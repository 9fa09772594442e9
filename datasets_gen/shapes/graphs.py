"""Height fields z = f(x, y): saddle, Gaussian bump, bumped square with holes."""

from __future__ import annotations

import numpy as np

from ..domains import Domain
from .base import HeightField, gaussian_bump, square, unit_disk
from .flat import HOLES

__all__ = ["Saddle", "Bump", "HolesBumped"]


class Saddle(HeightField):
    name = "saddle"
    description = "saddle z = a (x^2 - y^2) over the unit disk (a=1); no exact map"
    defaults = {"a": 1.0}

    def _setup(self, a: float) -> Domain:
        self._require(np.isfinite(a) and a != 0, f"a={a} must be finite and non-zero.")
        return Domain(unit_disk())

    def height(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        a = self.options["a"]
        return a * (x[:, 0] ** 2 - x[:, 1] ** 2), 2.0 * a * x * [1.0, -1.0]


class _BumpOptions(HeightField):
    defaults = {"h": 0.5, "s": 0.3}

    def _check_bump(self, h: float, s: float) -> None:
        self._require(np.isfinite(h), f"h={h} must be finite.")
        self._require(np.isfinite(s) and s > 0, f"s={s} must be a positive width.")

    def height(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return gaussian_bump(x, self.options["h"], self.options["s"])


class Bump(_BumpOptions):
    name = "bump"
    description = "Gaussian bump z = h exp(-r^2 / 2 s^2) on the square [-1,1]^2 (h=0.5, s=0.3); no exact map"

    def _setup(self, h: float, s: float) -> Domain:
        self._check_bump(h, s)
        return Domain(square())


class HolesBumped(_BumpOptions):
    name = "holes-bumped"
    description = "the 'holes' domain lifted by a centred Gaussian bump (h=0.5, s=0.3); no exact map"

    def _setup(self, h: float, s: float) -> Domain:
        self._check_bump(h, s)
        return Domain(square(), HOLES)
