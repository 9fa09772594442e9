"""A shallow smooth cap whose sampling is regular except for a strip of merged scans.

After the paper's Gnome model (Fig. 13): "mainly regularly sampled, with a small strip of
irregular sampling where it appears that two scans were merged". The geometry is an
elliptic paraboloid z = height (1 - x^2 - 0.6 y^2) over the unit disk (slope <= 0.6).
The generator (:mod:`parambench.datasets_gen.build`) samples the disk as requested (scan A), then a
second scan B (the same sampling, rotated by ``strip_angle`` degrees and shifted) is kept
inside the strip |x - strip_center| < strip_width / 2 and merged: B points closer than
``min_spacing`` * h to a kept point are dropped (no near-duplicates).
"""

from __future__ import annotations

import numpy as np

from ..domains import Domain
from .base import HeightField, unit_disk

__all__ = ["GnomeStrip"]

#: Expected fraction of second-scan points that survive the merge (measured on lattices).
MERGE_SURVIVAL = 0.55


class GnomeStrip(HeightField):
    name = "gnome-strip"
    description = ("shallow cap z = 0.3 (1 - x^2 - 0.6 y^2) on the unit disk, regular sampling except a "
                   "strip of two merged scans (after the paper's Gnome); no exact map")
    defaults = {"height": 0.3, "strip_center": 0.2, "strip_width": 0.25, "strip_angle": 17.0,
                "min_spacing": 0.35}

    def _setup(self, height: float, strip_center: float, strip_width: float, strip_angle: float,
               min_spacing: float) -> Domain:
        self._require(np.isfinite(height), f"height={height} must be finite.")
        self._require(0 < strip_width < 2 and abs(strip_center) + strip_width / 2 < 1,
                      "the strip must lie inside the unit disk (|strip_center| + strip_width/2 < 1).")
        self._require(0.05 <= min_spacing <= 1.0, f"min_spacing={min_spacing} must lie in [0.05, 1] "
                                                  "(a fraction of the sampling spacing).")
        return Domain(unit_disk())

    def height(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        a = self.options["height"]
        z = a * (1.0 - x[:, 0] ** 2 - 0.6 * x[:, 1] ** 2)
        return z, np.column_stack([-2.0 * a * x[:, 0], -1.2 * a * x[:, 1]])

    def in_strip(self, x: np.ndarray) -> np.ndarray:
        """(n,) bool: parameter points inside the merged-scan strip."""
        return np.abs(x[:, 0] - self.options["strip_center"]) < 0.5 * self.options["strip_width"]

    @property
    def strip_fraction(self) -> float:
        """Fraction of the domain area inside the strip."""
        x, _ = self.domain.grid(400)
        return float(self.in_strip(x).mean())

    def count_factor(self) -> float:
        return 1.0 + MERGE_SURVIVAL * self.strip_fraction
