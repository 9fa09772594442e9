"""The contract of a procedural surface: a parameter domain and its map to 3D.

A :class:`Shape` knows its geometry only. Sampling, meshing and noise are generic and
live in :mod:`parambench.datasets_gen.sampling` and :mod:`parambench.datasets_gen.build`; they ask the shape
for five things:

- ``domain``: the parameter domain (:class:`~parambench.datasets_gen.domains.Domain`);
- ``lift(x)``: 3D points and exact unit normals at parameter points;
- ``chart(x)``: a planar chart in which the mesher runs Delaunay. It must preserve
  orientation (counter-clockwise in the chart = counter-clockwise seen from the normals'
  side) and should be (close to) conformal, so that a Delaunay triangulation there has
  well-shaped triangles on the surface;
- ``lattice(h, ...)``: the "grid" sampling (a triangular lattice in the domain unless a
  shape knows better);
- ``exact_uv(x)`` with ``exact_map_kind`` when an exact flattening is known.
"""

from __future__ import annotations

from functools import cached_property
from typing import ClassVar

import numpy as np

from ..domains import Disk, Domain, Rect
from ..errors import InvalidInputError, UnknownNameError
from ..sampling.lattice import jitter_in_disk, triangular_lattice

__all__ = ["Shape", "HeightField", "gaussian_bump"]

#: Resolution of the midpoint rule used for surface areas and density bounds.
QUADRATURE_CELLS = 400


class Shape:
    """Base class of the procedural surfaces.

    Subclasses set ``name``, ``description``, ``defaults`` (their options) and
    ``exact_map_kind``, build ``self.domain`` in :meth:`_setup`, and implement
    :meth:`lift`.

    Parameters
    ----------
    **options
        Overrides of ``defaults``.

    Raises
    ------
    UnknownNameError
        An option the shape does not have.
    InvalidInputError
        An option value out of range.
    """

    name: ClassVar[str] = ""
    description: ClassVar[str] = ""
    defaults: ClassVar[dict] = {}
    exact_map_kind: ClassVar[str | None] = None
    #: "param" when the lattice is uniform in the parameter domain, "3d" when uniform on the surface.
    lattice_metric: ClassVar[str] = "param"
    #: True when the geometry is set in units of the sampling spacing (narrow gaps): the
    #: generator then rebuilds the shape with :meth:`at_spacing`.
    spacing_dependent: ClassVar[bool] = False
    #: Surface spacing the geometry was built for (None: the shape's own default).
    nominal_spacing: float | None = None

    def __init__(self, **options) -> None:
        unknown = sorted(set(options) - set(self.defaults))
        if unknown:
            valid = ", ".join(sorted(self.defaults)) or "none"
            raise UnknownNameError(f"{self.name}: unknown option(s) {', '.join(unknown)}; valid options: {valid}.")
        merged = dict(self.defaults)
        for key, value in options.items():
            try:
                merged[key] = type(self.defaults[key])(value)
            except (TypeError, ValueError):
                raise InvalidInputError(f"{self.name}: option {key}={value!r} must be a "
                                        f"{type(self.defaults[key]).__name__}.") from None
        self.options = merged
        self.domain: Domain = self._setup(**merged)

    def _setup(self, **options) -> Domain:
        raise NotImplementedError

    def at_spacing(self, h: float) -> "Shape":
        """This shape rebuilt for a sampling of surface spacing ``h`` (itself unless spacing-dependent).

        Parameters
        ----------
        h : float
            Nominal spacing on the surface, > 0 (see :func:`parambench.datasets_gen.build.nominal_spacing`).

        Returns
        -------
        Shape
            A new instance with the same options and ``nominal_spacing == h``.
        """
        if not self.spacing_dependent:
            return self
        shape = type(self).__new__(type(self))
        shape.nominal_spacing = float(h)
        Shape.__init__(shape, **self.options)
        return shape

    def _require(self, condition: bool, message: str) -> None:
        if not condition:
            raise InvalidInputError(f"{self.name}: {message}")

    # --- geometry -------------------------------------------------------------------
    def lift(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Surface points and exact unit normals.

        Parameters
        ----------
        x : (n, 2) numpy.ndarray of float64
            Parameter points.

        Returns
        -------
        points, normals : (n, 3) numpy.ndarray of float64
        """
        raise NotImplementedError

    def chart(self, x: np.ndarray) -> np.ndarray:
        """Orientation-preserving, near-conformal planar chart for meshing; (n, 2) -> (n, 2).

        The default is the parameter domain itself.
        """
        return np.array(x, dtype=float, copy=True)

    def exact_uv(self, x: np.ndarray) -> np.ndarray | None:
        """The exact flattening at parameter points, (n, 2), or None when none is known."""
        return None

    def refinement(self, x: np.ndarray) -> np.ndarray | None:
        """Where a graded sampling must use its finest spacing, whatever its random field.

        Parameters
        ----------
        x : (n, 2) numpy.ndarray of float64
            Parameter points.

        Returns
        -------
        (n,) numpy.ndarray of float64 in [0, 1], or None
            1 where the geometry needs the finest spacing (a bend tighter than the coarse
            spacing), blending smoothly to 0; None (the default) when nowhere.
        """
        return None

    def area_factor(self, x: np.ndarray) -> np.ndarray:
        """Surface area per unit parameter area, |F_u x F_v|, at (n, 2) points; shape (n,).

        The default uses central differences of :meth:`lift` (relative error ~1e-8).
        """
        x = np.asarray(x, dtype=float)
        eps = 1e-6 * max(1.0, float(np.max(np.abs(np.concatenate(self.domain.bbox)))))
        du = (self.lift(x + [eps, 0.0])[0] - self.lift(x - [eps, 0.0])[0]) / (2 * eps)
        dv = (self.lift(x + [0.0, eps])[0] - self.lift(x - [0.0, eps])[0]) / (2 * eps)
        return np.linalg.norm(np.cross(du, dv), axis=1)

    @cached_property
    def _quadrature(self) -> tuple[float, float]:
        x, cell = self.domain.grid(QUADRATURE_CELLS)
        j = self.area_factor(x)
        return float(j.sum() * cell), float(j.max())

    @property
    def surface_area(self) -> float:
        """Area of the surface in 3D (midpoint rule, relative error ~1e-3)."""
        return self._quadrature[0]

    @property
    def area_factor_bound(self) -> float:
        """An upper bound of :meth:`area_factor` over the domain (sampled maximum + 10 %)."""
        return 1.1 * self._quadrature[1]

    # --- sampling hooks ------------------------------------------------------------
    def snap_spacing(self, h: float) -> float:
        """Adjust a lattice spacing so that the lattice fits the domain (rectangles: whole columns)."""
        outer = self.domain.outer
        if isinstance(outer, Rect):
            width = outer.hi[0] - outer.lo[0]
            return width / max(1, round(width / h))
        return h

    def lattice(self, h: float, *, angle: float = 0.0, offset=(0.0, 0.0), jitter: float = 0.0,
                rng: np.random.Generator | None = None) -> np.ndarray:
        """Lattice ("grid") sampling of the domain interior, optionally jittered.

        Parameters
        ----------
        h : float
            Spacing (parameter units, or surface units when ``lattice_metric == "3d"``).
        angle : float
            Rotation of the lattice, radians.
        offset : (2,) array_like of float
            Shift of the lattice origin, parameter units.
        jitter : float
            Radius of the uniform jitter disk as a fraction of ``h`` (0: none).
        rng : numpy.random.Generator
            Required when ``jitter > 0``.

        Returns
        -------
        (n, 2) numpy.ndarray of float64
            Points strictly inside the domain.
        """
        outer = self.domain.outer
        lo, hi = self.domain.bbox
        origin = np.asarray(outer.lo if isinstance(outer, Rect) else outer.center, dtype=float)
        pts = triangular_lattice(lo, hi, h, origin=origin + np.asarray(offset, dtype=float), angle=angle)
        if jitter > 0:
            pts = pts + jitter_in_disk(len(pts), jitter * h, rng)
        return pts[self.domain.contains(pts)]

    def count_factor(self) -> float:
        """Expected points per lattice-density unit (1, or more where a shape adds points)."""
        return 1.0

    def describe(self) -> str:
        return self.description


def gaussian_bump(x: np.ndarray, height: float, sigma: float, center=(0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """z = height * exp(-|x - c|^2 / (2 sigma^2)) and its gradient.

    Returns
    -------
    z : (n,) numpy.ndarray of float64
    grad : (n, 2) numpy.ndarray of float64
    """
    d = x - np.asarray(center, dtype=float)
    z = height * np.exp(-np.einsum("ij,ij->i", d, d) / (2.0 * sigma ** 2))
    return z, -d * (z / sigma ** 2)[:, None]


class HeightField(Shape):
    """A graph z = f(x, y) over the domain, normals pointing to +z."""

    def height(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """f and its gradient at (n, 2) points: ((n,), (n, 2))."""
        raise NotImplementedError

    def lift(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        x = np.asarray(x, dtype=float)
        z, g = self.height(x)
        normals = np.column_stack([-g[:, 0], -g[:, 1], np.ones(len(x))])
        normals /= np.linalg.norm(normals, axis=1)[:, None]
        return np.column_stack([x, z]), normals

    def area_factor(self, x: np.ndarray) -> np.ndarray:
        _, g = self.height(np.asarray(x, dtype=float))
        return np.sqrt(1.0 + np.einsum("ij,ij->i", g, g))


def unit_square() -> Rect:
    return Rect((0.0, 0.0), (1.0, 1.0))


def square() -> Rect:
    return Rect((-1.0, -1.0), (1.0, 1.0))


def unit_disk() -> Disk:
    return Disk((0.0, 0.0), 1.0)
