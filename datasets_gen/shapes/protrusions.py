"""A square base with three tall, narrow finger-like bumps (after Fig. 8 of the paper).

Each finger is a compactly supported radial height profile f(r) = H (1 - (r/R)^2)^3 for
r < R (C^2 at its foot), so the fingers' supports are disjoint and the base is exactly flat
outside them. Two things make this surface hard to sample well, and both are solved
per finger with 1D tables along the radius:

- Area: the steep sides carry most of the area (area factor up to ~6 with the defaults),
  so the "grid" sampling uses rings at constant arc length from each apex (spacing
  sqrt(3)/2 h, about 2 pi r / h points per ring) and a triangular lattice on the flat
  base: uniform in 3D, like every other sampling of this shape.
- Triangle shape: a Delaunay triangulation in the (x, y) plane of 3D-uniform points would
  stretch triangles ~6:1 on the sides. The mesher runs instead in the *exact conformal
  chart* of the surface: around each finger the radial map rho(r) = r exp(-int_r^R (J - 1)/t dt),
  J = sqrt(1 + f'(r)^2), makes the metric isotropic (J dr/r = d rho/rho), and it is the
  identity outside the supports. Conformal means angles are preserved, so the chart's
  Delaunay triangles are well shaped on the surface.

The chart squeezes each fingertip by exp(-7.5) with the defaults (the crowding a conformal map of this
surface must have); it is not published as ``exact_uv`` because free-boundary methods
produce a different conformal map (not one with a square boundary), so a similarity-
aligned error against it would be meaningless. It is available as :meth:`chart`.
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import cumulative_simpson

from ..domains import Domain
from ..sampling.lattice import ROW, jitter_in_disk
from .base import HeightField, square

__all__ = ["Protrusions", "FINGER_CENTERS"]

FINGER_CENTERS = np.array([[-0.5, -0.4], [0.5, -0.4], [0.0, 0.5]])

#: Samples of the radial tables; interpolation error is far below 1e-8.
TABLE_SIZE = 20001


class Protrusions(HeightField):
    name = "protrusions"
    description = ("square [-1,1]^2 with 3 finger-like bumps of height 1 and foot radius 0.3 "
                   "(after the paper's Fig. 8); no exact map")
    defaults = {"height": 1.0, "radius": 0.3}
    lattice_metric = "3d"

    def _setup(self, height: float, radius: float) -> Domain:
        self._require(np.isfinite(height) and height > 0, f"height={height} must be positive.")
        self._require(0 < radius <= 0.45, f"radius={radius} must lie in (0, 0.45] so the fingers stay "
                                          "inside the square and apart.")
        r = np.linspace(0.0, radius, TABLE_SIZE)
        j = np.sqrt(1.0 + self._profile_slope(r) ** 2)
        integrand = np.zeros_like(r)
        integrand[1:] = (j[1:] - 1.0) / r[1:]  # (J - 1)/r -> 0 at the apex: the profile is flat there
        log_scale = cumulative_simpson(integrand, x=r, initial=0.0)
        self._r = r
        self._log_scale = log_scale - log_scale[-1]  # 0 at the foot: identity outside the support
        self._arc = cumulative_simpson(j, x=r, initial=0.0)
        return Domain(square())

    def _profile_slope(self, r: np.ndarray) -> np.ndarray:
        height, radius = self.options["height"], self.options["radius"]
        t = np.clip(r / radius, 0.0, 1.0)
        return -6.0 * height / radius * t * (1.0 - t ** 2) ** 2

    def height(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        height, radius = self.options["height"], self.options["radius"]
        z = np.zeros(len(x))
        grad = np.zeros((len(x), 2))
        for c in FINGER_CENTERS:
            d = x - c
            q = np.clip(1.0 - np.einsum("ij,ij->i", d, d) / radius ** 2, 0.0, None)
            z += height * q ** 3
            grad += (-6.0 * height / radius ** 2 * q ** 2)[:, None] * d
        return z, grad

    def chart(self, x: np.ndarray) -> np.ndarray:
        """The exact conformal chart (identity outside the fingers), (n, 2) -> (n, 2)."""
        x = np.asarray(x, dtype=float)
        out = x.copy()
        for c in FINGER_CENTERS:
            d = x - c
            r = np.hypot(d[:, 0], d[:, 1])
            near = r < self.options["radius"]
            scale = np.exp(np.interp(r[near], self._r, self._log_scale))
            out[near] = c + d[near] * scale[:, None]
        return out

    def lattice(self, h: float, *, angle: float = 0.0, offset=(0.0, 0.0), jitter: float = 0.0,
                rng: np.random.Generator | None = None) -> np.ndarray:
        """Rings of constant arc length on the fingers, a triangular lattice on the base.

        ``h`` is in surface units; ``jitter`` displaces ring points along the surface
        (arc length and circumference) so the jitter is ~``jitter * h`` in 3D everywhere.
        """
        radius = self.options["radius"]
        base = super().lattice(h, angle=angle, offset=offset, jitter=jitter, rng=rng)
        for c in FINGER_CENTERS:
            base = base[np.hypot(*(base - c).T) >= radius + 0.6 * h]
        parts = [base]
        total = self._arc[-1]
        n_rings = max(1, round(total / (ROW * h)))
        for c in FINGER_CENTERS:
            s, phi = [np.zeros(1)], [np.zeros(1)]
            for k in range(1, n_rings + 1):
                s_k = k * total / n_rings
                r_k = np.interp(s_k, self._arc, self._r)
                n_k = max(3, round(2.0 * np.pi * r_k / h))
                s.append(np.full(n_k, s_k))
                phi.append(angle + (np.arange(n_k) + 0.5 * (k % 2)) * 2.0 * np.pi / n_k)
            s, phi = np.concatenate(s), np.concatenate(phi)
            if jitter > 0:
                d = jitter_in_disk(len(s), jitter * h, rng)
                ring_r = np.interp(s, self._arc, self._r)
                phi = phi + np.where(ring_r > 0, d[:, 1] / np.maximum(ring_r, 1e-300), 0.0)
                s = s + d[:, 0]
                phi = phi + np.where(s < 0, np.pi, 0.0)  # jittered past the apex: other side
            r = self._radius_at_arc(np.abs(s))
            ring = c + np.column_stack([r * np.cos(phi), r * np.sin(phi)])
            # The apex is a single point; jitter it in the plane (the top is flat there).
            if jitter > 0:
                ring[0] = c + jitter_in_disk(1, jitter * h, rng)[0]
            parts.append(ring)
        pts = np.concatenate(parts)
        return pts[self.domain.contains(pts)]

    def _radius_at_arc(self, s: np.ndarray) -> np.ndarray:
        """Foot-relative radius at arc length s from the apex; beyond the foot the base is flat."""
        total = self._arc[-1]
        return np.where(s <= total, np.interp(s, self._arc, self._r), self._r[-1] + (s - total))
