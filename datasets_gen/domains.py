"""Planar parameter domains: a disk or a rectangle, minus circular or slot-shaped holes.

A procedural surface is a map from one of these domains to 3D. The domain answers three
questions for the samplers and the mesher: which points lie inside, where the boundary
curves run (as closed chains of segments, corners kept), and how large it is.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

__all__ = ["Disk", "Rect", "Stadium", "Domain", "Segment"]

#: A boundary segment: maps parameters t in [0, 1] of shape (n,) to points (n, 2).
Segment = Callable[[np.ndarray], np.ndarray]


@dataclass(frozen=True)
class Disk:
    """The open disk of ``radius`` around ``center``."""

    center: tuple[float, float]
    radius: float

    def inside(self, x: np.ndarray) -> np.ndarray:
        """(n,) bool: True where the (n, 2) points lie strictly inside."""
        d = x - np.asarray(self.center)
        return np.einsum("ij,ij->i", d, d) < self.radius ** 2

    @property
    def area(self) -> float:
        return float(np.pi * self.radius ** 2)

    @property
    def bbox(self) -> tuple[np.ndarray, np.ndarray]:
        c = np.asarray(self.center, dtype=float)
        return c - self.radius, c + self.radius

    def segments(self) -> list[Segment]:
        """One closed segment, counter-clockwise, starting at angle 0 (t=0 and t=1 coincide)."""
        c, r = np.asarray(self.center, dtype=float), float(self.radius)

        def circle(t: np.ndarray) -> np.ndarray:
            a = 2.0 * np.pi * np.asarray(t, dtype=float)
            return c + r * np.column_stack([np.cos(a), np.sin(a)])

        return [circle]


@dataclass(frozen=True)
class Rect:
    """The open axis-aligned rectangle ``lo < x < hi``."""

    lo: tuple[float, float]
    hi: tuple[float, float]

    def inside(self, x: np.ndarray) -> np.ndarray:
        """(n,) bool: True where the (n, 2) points lie strictly inside."""
        lo, hi = np.asarray(self.lo), np.asarray(self.hi)
        return np.all((x > lo) & (x < hi), axis=1)

    @property
    def area(self) -> float:
        return float(np.prod(np.asarray(self.hi) - np.asarray(self.lo)))

    @property
    def bbox(self) -> tuple[np.ndarray, np.ndarray]:
        return np.asarray(self.lo, dtype=float), np.asarray(self.hi, dtype=float)

    def segments(self) -> list[Segment]:
        """Four straight sides, counter-clockwise from the lower-left corner.

        Sides are separate segments so that the corners are always boundary points.
        """
        (x0, y0), (x1, y1) = self.lo, self.hi
        corners = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], dtype=float)

        def side(a: np.ndarray, b: np.ndarray) -> Segment:
            return lambda t: a + np.asarray(t, dtype=float)[:, None] * (b - a)

        return [side(corners[k], corners[(k + 1) % 4]) for k in range(4)]


@dataclass(frozen=True)
class Stadium:
    """The open slot (stadium) of points closer than ``half_width`` to a horizontal segment.

    The segment runs from ``center - (half_length, 0)`` to ``center + (half_length, 0)``;
    the slot has two straight sides and two semicircular ends.
    """

    center: tuple[float, float]
    half_length: float
    half_width: float

    def inside(self, x: np.ndarray) -> np.ndarray:
        """(n,) bool: True where the (n, 2) points lie strictly inside."""
        d = np.asarray(x, dtype=float) - np.asarray(self.center)
        along = np.clip(d[:, 0], -self.half_length, self.half_length)
        return (d[:, 0] - along) ** 2 + d[:, 1] ** 2 < self.half_width ** 2

    @property
    def radius(self) -> float:
        """Radius of the smallest disk around ``center`` holding the slot (for the overlap checks)."""
        return float(self.half_length + self.half_width)

    @property
    def area(self) -> float:
        return float(4.0 * self.half_length * self.half_width + np.pi * self.half_width ** 2)

    @property
    def bbox(self) -> tuple[np.ndarray, np.ndarray]:
        c = np.asarray(self.center, dtype=float)
        half = np.array([self.half_length + self.half_width, self.half_width])
        return c - half, c + half

    def segments(self) -> list[Segment]:
        """Lower side, right end, upper side, left end: counter-clockwise, the joints always boundary points."""
        c = np.asarray(self.center, dtype=float)
        a, w = float(self.half_length), float(self.half_width)

        def side(start: np.ndarray, end: np.ndarray) -> Segment:
            return lambda t: start + np.asarray(t, dtype=float)[:, None] * (end - start)

        def end_cap(mid: np.ndarray, start_angle: float) -> Segment:
            def arc(t: np.ndarray) -> np.ndarray:
                angle = start_angle + np.pi * np.asarray(t, dtype=float)
                return mid + w * np.column_stack([np.cos(angle), np.sin(angle)])
            return arc

        right, left = c + [a, 0.0], c - [a, 0.0]
        return [side(left - [0.0, w], right - [0.0, w]), end_cap(right, -0.5 * np.pi),
                side(right + [0.0, w], left + [0.0, w]), end_cap(left, 0.5 * np.pi)]


@dataclass(frozen=True)
class Domain:
    """An outer disk or rectangle minus disjoint holes (disks or slots).

    Parameters
    ----------
    outer : Disk or Rect
    holes : tuple of Disk or Stadium
        Must lie inside ``outer`` and not overlap each other (checked, conservatively for
        slots: by their enclosing disks).

    Raises
    ------
    ValueError
        Holes overlapping each other or leaving the outer shape (a programming error in
        a generator, not a user input problem).
    """

    outer: Disk | Rect
    holes: tuple[Disk | Stadium, ...] = ()

    def __post_init__(self) -> None:
        lo, hi = self.outer.bbox
        for k, h in enumerate(self.holes):
            hlo, hhi = h.bbox
            if not (np.all(hlo > lo) and np.all(hhi < hi)):
                raise ValueError(f"hole {k} leaves the outer domain")
            if isinstance(self.outer, Disk):
                gap = self.outer.radius - np.hypot(*(np.subtract(h.center, self.outer.center)))
                if gap <= h.radius:
                    raise ValueError(f"hole {k} leaves the outer disk")
            for m in range(k):
                other = self.holes[m]
                if np.hypot(*np.subtract(h.center, other.center)) <= h.radius + other.radius:
                    raise ValueError(f"holes {m} and {k} overlap")

    def contains(self, x: np.ndarray) -> np.ndarray:
        """(n,) bool: True where the (n, 2) points lie strictly inside the domain."""
        x = np.asarray(x, dtype=float)
        ok = self.outer.inside(x)
        for h in self.holes:
            ok &= ~h.inside(x)
        return ok

    @property
    def area(self) -> float:
        """Area of the domain in parameter units."""
        return self.outer.area - sum(h.area for h in self.holes)

    @property
    def bbox(self) -> tuple[np.ndarray, np.ndarray]:
        """(lo, hi): the outer shape's bounding box, two (2,) arrays."""
        return self.outer.bbox

    def curves(self) -> list[list[Segment]]:
        """Boundary curves, outer first then holes in order, each a closed chain of segments."""
        return [self.outer.segments()] + [h.segments() for h in self.holes]

    def grid(self, n: int) -> tuple[np.ndarray, float]:
        """Cell centres of an ``n`` x ``n`` grid over the bounding box that fall inside.

        Returns
        -------
        x : (m, 2) numpy.ndarray of float64
            Cell centres inside the domain.
        cell_area : float
            Area of one cell (for midpoint-rule integrals over the domain).
        """
        lo, hi = self.bbox
        step = (hi - lo) / n
        u = lo[0] + (np.arange(n) + 0.5) * step[0]
        v = lo[1] + (np.arange(n) + 0.5) * step[1]
        x = np.stack(np.meshgrid(u, v, indexing="xy"), axis=-1).reshape(-1, 2)
        return x[self.contains(x)], float(step[0] * step[1])
