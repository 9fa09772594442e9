"""Narrow-gap surfaces: two parts of the surface far apart on it but close in space.

Euclidean k-nearest-neighbour graphs bridge such gaps, which is what these datasets test.
The gap is set in units of the sampling spacing, so it stays 2-3 spacings wide at every
size: the generator rebuilds the shape for the nominal surface spacing of the requested
count (:meth:`~parambench.datasets_gen.shapes.base.Shape.at_spacing`); built on its own, a shape uses
``DEFAULT_SPACING`` (about 2000 points). Both are developable with their unrolling as the
exact (isometric) map, so the ground-truth mesh is meshed in the unrolled domain and no
ground-truth edge crosses the gap.

- ``slit``: the unit disk bent around a cylinder of radius 2 (gently curved), with a long
  straight slot (a hole) whose lips are ``gap`` spacings apart (graded samplings are
  refined around it, :meth:`Slit.refinement`).
- ``fold``: a rectangular sheet wrapped around a thin cylinder by 180 degrees plus a small
  over-bend, a hairpin whose flat sheets lie ``gap + taper/2`` spacings apart at the bend
  and ``gap - taper/2`` at their free ends.
"""

from __future__ import annotations

import numpy as np

from ..domains import Domain, Rect, Stadium
from ..sampling.graded import smootherstep
from .base import Shape, unit_disk

__all__ = ["Slit", "Fold", "DEFAULT_SPACING"]

#: Spacing used when a gap shape is built without one (about 2000 points on either shape).
DEFAULT_SPACING = 0.04
#: Graded samplings keep the fold's bend at their finest spacing, blending out over this
#: distance (surface units) along the sheets: coarse spacing there (about 2 nominal
#: spacings, more than half the bend) would put ground-truth edges across the U.
BEND_MARGIN = 0.2


class _DevelopableGap(Shape):
    """A developable surface given in unrolled coordinates: exact map = identity, area factor 1."""

    exact_map_kind = "isometric"
    spacing_dependent = True

    @property
    def spacing(self) -> float:
        """The spacing the gap is measured in (surface units)."""
        return self.nominal_spacing if self.nominal_spacing is not None else DEFAULT_SPACING

    def _check_gap(self, gap: float, low: float) -> None:
        self._require(np.isfinite(gap) and low <= gap <= 20.0,
                      f"gap={gap} must lie in [{low:g}, 20] spacings (2-3 makes a narrow gap).")

    def area_factor(self, x: np.ndarray) -> np.ndarray:
        return np.ones(len(x))

    def exact_uv(self, x: np.ndarray) -> np.ndarray:
        return np.array(x, dtype=float, copy=True)


#: Graded samplings raise their sizing field towards the dense end around the slot, by
#: ``SLOT_REFINEMENT`` within ``SLOT_MARGIN`` spacings (see :meth:`Slit.refinement`).
SLOT_MARGIN = 6.0
SLOT_REFINEMENT = 0.6


class Slit(_DevelopableGap):
    """Unit disk bent around the y axis (cylinder of ``bend_radius``) with a slot along x.

    The slot is the set of points closer than ``gap * spacing / 2`` to the segment
    |x| <= ``slot_length`` / 2, y = 0; the bend keeps y straight, so the lips are exactly
    ``gap`` spacings apart in 3D along the slot's straight part.
    """

    name = "slit"
    description = ("unit disk bent around a cylinder of radius 2 with a straight slot of length 1.2 whose lips "
                   "are 2 point spacings apart at every size; exact map: unrolling (isometric)")
    defaults = {"gap": 2.0, "slot_length": 1.2, "bend_radius": 2.0}

    def _setup(self, gap: float, slot_length: float, bend_radius: float) -> Domain:
        self._check_gap(gap, 1.0)
        self._require(np.isfinite(bend_radius) and bend_radius >= 1.0,
                      f"bend_radius={bend_radius} must be at least 1 (a gentle bend of the unit disk).")
        half_width = 0.5 * gap * self.spacing
        self._require(np.isfinite(slot_length) and 0 < slot_length and 0.5 * slot_length + half_width < 0.9,
                      f"slot_length={slot_length} must be positive and leave the slot inside the disk "
                      "(slot_length / 2 + gap * spacing / 2 < 0.9).")
        return Domain(unit_disk(), (Stadium((0.0, 0.0), 0.5 * slot_length, half_width),))

    def refinement(self, x: np.ndarray) -> np.ndarray:
        """``SLOT_REFINEMENT`` at the slot, smoothly 0 ``SLOT_MARGIN`` spacings from it.

        The slot is ``gap`` nominal spacings wide, but a graded sampling's sparse plateau
        is about twice as coarse: there the lips were less than one local spacing apart
        (slot width over the mean 6-NN distance beside it, the sparsest tenth of the
        lips, seeds 0-3: 0.81-0.85 against 1.62 jittered), narrower than the gaps
        between the points along them, which no sampling of that density resolves. An
        adaptive remesher refines at such a feature; with this refinement the ratio is
        1.72-1.83 in the median (jittered 1.72) and 1.42-1.49 at the sparsest tenth
        (random 1.47-1.56).
        """
        x = np.asarray(x, dtype=float)
        half_length = 0.5 * self.options["slot_length"]
        along = np.clip(x[:, 0], -half_length, half_length)
        outside = np.hypot(x[:, 0] - along, x[:, 1]) - 0.5 * self.options["gap"] * self.spacing
        return SLOT_REFINEMENT * (1.0 - smootherstep(np.maximum(outside, 0.0) / (SLOT_MARGIN * self.spacing)))

    def lift(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        x = np.asarray(x, dtype=float)
        rho = self.options["bend_radius"]
        c, s = np.cos(x[:, 0] / rho), np.sin(x[:, 0] / rho)
        points = np.column_stack([rho * s, x[:, 1], rho * (1.0 - c)])
        return points, np.column_stack([-s, np.zeros(len(x)), c])


class Fold(_DevelopableGap):
    """A ``length`` + bend + ``length`` by ``width`` sheet folded into a hairpin around the z axis.

    Unrolled coordinates (u, v): the first sheet is u in [-length, 0] on the plane y = -R,
    the bend u in [0, theta R] wraps the cylinder of radius R about the z axis by
    theta = pi + 2 alpha, and the second sheet continues along the tangent. With gap
    widths g_near at the bend and g_far at the free ends (in 3D, across the sheets),
    sin(2 alpha) = (g_near - g_far) / length and R = g_near / (2 cos^2 alpha).
    """

    name = "fold"
    description = ("a 2.0 x 1.0 strip (plus its bend) folded around a thin cylinder by slightly more than "
                   "180 deg, the two sheets 2.5 to 2 point spacings apart at every size; exact map: "
                   "unrolling (isometric)")
    defaults = {"gap": 2.25, "taper": 0.5, "length": 1.0, "width": 1.0}

    def _setup(self, gap: float, taper: float, length: float, width: float) -> Domain:
        self._check_gap(gap, 1.0)
        self._require(np.isfinite(taper) and 0 <= taper <= 2.0 * (gap - 1.0),
                      f"taper={taper} must lie in [0, 2 (gap - 1)] so the free ends stay a spacing apart.")
        self._require(np.isfinite(length) and np.isfinite(width) and length > 0 and width > 0,
                      "length and width must be positive.")
        near, far = (gap + 0.5 * taper) * self.spacing, (gap - 0.5 * taper) * self.spacing
        self._require(near - far < length, f"the taper ({taper} spacings) must be shorter than length={length}.")
        alpha = 0.5 * np.arcsin((near - far) / length)
        self.bend_radius = float(near / (2.0 * np.cos(alpha) ** 2))
        self.bend_angle = float(np.pi + 2.0 * alpha)
        return Domain(Rect((-length, 0.0), (self.bend_angle * self.bend_radius + length, width)))

    def refinement(self, x: np.ndarray) -> np.ndarray:
        """1 on the bend, smoothly 0 at ``BEND_MARGIN`` along either sheet."""
        u = np.asarray(x, dtype=float)[:, 0]
        outside = np.maximum(np.maximum(-u, u - self.bend_angle * self.bend_radius), 0.0)
        return 1.0 - smootherstep(outside / BEND_MARGIN)

    def lift(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        x = np.asarray(x, dtype=float)
        r = self.bend_radius
        on_bend = np.clip(x[:, 0], 0.0, self.bend_angle * r)
        phi = on_bend / r
        c, s = np.cos(phi), np.sin(phi)
        straight = x[:, 0] - on_bend  # distance along a flat sheet, negative on the first one
        points = np.column_stack([r * s + straight * c, -r * c + straight * s, x[:, 1]])
        return points, np.column_stack([s, -c, np.zeros(len(x))])
