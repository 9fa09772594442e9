"""Scale and pose normalisation: every method sees a centred, unit-size, axis-aligned copy.

Solvers, neighbourhood radii, degeneracy tolerances and libigl's internals all hold
absolute thresholds somewhere, so a map of the same surface at coordinates x1e12 or
x1e-12, or far from the origin, used to differ (foldovers, another k). Normalising once,
before any method runs, makes every registered method invariant to similarity
transforms of its input:

- centre: the centroid, and unit: the RMS distance to it; both follow a rotation exactly,
  unlike a bounding box, whose centre and size depend on the axes;
- rotation: the principal axes (decreasing variance), each signed so that the third
  moment along it is positive, the third axis completing a right-handed frame. Most
  methods do not need it, but robust-laplacian's local triangulations depend on the
  absolute frame (its Laplacian of a rotated cloud differs by up to 0.6 in an entry);
  in the principal frame a rotated input arrives as the same points, up to rounding.
  Where the frame is not unique (equal variances or zero third moment, e.g. an exactly
  symmetric grid) it is chosen by rounding, which is no worse than no frame at all.

The map of the points to the plane is invariant to the 3D rotation; only its scale is
given back (uv in the input's units).
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from parambench.datasets_gen.errors import InvalidInputError
from parambench.datasets_gen.surface import MethodInput, Surface

__all__ = ["Pose", "surface_pose", "normalised_surface", "run_in_unit_pose"]


@dataclass(frozen=True)
class Pose:
    """Where a surface sits: ``points = centre + scale * unit_points @ rotation``.

    Attributes
    ----------
    centre : (3,) numpy.ndarray of float64
        Centroid of the points, in input units.
    scale : float
        RMS distance of the points from ``centre``, in input units (> 0).
    rotation : (3, 3) numpy.ndarray of float64
        Rows are the principal axes (a proper rotation, determinant +1).
    """

    centre: np.ndarray
    scale: float
    rotation: np.ndarray

    def to_unit(self, points: np.ndarray) -> np.ndarray:
        """Input coordinates (N, 3) to the unit-size principal frame (N, 3)."""
        return ((points - self.centre) @ self.rotation.T) / self.scale


def surface_pose(points: np.ndarray) -> Pose:
    """Centroid, RMS radius and principal axes of a point array.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
        Finite coordinates (as :class:`Surface` guarantees).

    Returns
    -------
    Pose

    Raises
    ------
    InvalidInputError
        All points coincide, or the coordinates are so large that their spread overflows.
    """
    centre = points.mean(axis=0)
    offsets = points - centre
    # Divide by the largest offset before squaring so that neither 1e200 overflows nor
    # 1e-200 underflows.
    largest = float(np.max(np.abs(offsets)))
    if not np.isfinite(largest) or largest <= 0.0:
        raise InvalidInputError(
            "the points have no spread (all equal) or coordinates too large to subtract; "
            "give at least 4 distinct points with coordinates below 1e300."
        )
    shrunk = offsets / largest
    scale = largest * float(np.sqrt(np.mean(np.sum(shrunk**2, axis=1))))
    return Pose(centre=centre, scale=scale, rotation=_principal_axes(shrunk))


def _principal_axes(offsets: np.ndarray) -> np.ndarray:
    """Rows: eigenvectors of the covariance, largest variance first, signed by third moments."""
    _, vecs = np.linalg.eigh(offsets.T @ offsets)
    axes = vecs[:, ::-1].T.copy()
    third = np.sum((offsets @ axes[:2].T) ** 3, axis=0)
    axes[:2][third < 0] *= -1.0
    axes[2] = np.cross(axes[0], axes[1])
    return axes


def normalised_surface(surface: MethodInput | Surface) -> tuple[MethodInput, Pose]:
    """A copy of a method's input in its unit-size principal frame; the caller's is untouched.

    Normals are rotated with the points (translation and uniform scaling do not move
    them). Faces, loops and name are shared with the original (read-only data).

    Parameters
    ----------
    surface : MethodInput or Surface
        A ``Surface`` is first converted with :meth:`Surface.as_method_input`: the copy
        never carries ground truth (the exact map is evaluation's, in input units).

    Returns
    -------
    unit : MethodInput
        Points ``pose.to_unit(surface.points)``.
    pose : Pose
        To map results back with :func:`run_in_unit_pose`.

    Raises
    ------
    InvalidInputError
        See :func:`surface_pose`.
    """
    if isinstance(surface, Surface):
        surface = surface.as_method_input()
    pose = surface_pose(surface.points)
    unit = copy.copy(surface)  # a shallow copy skips __post_init__: the arrays were validated already
    object.__setattr__(unit, "points", pose.to_unit(surface.points))
    if surface.normals is not None:
        object.__setattr__(unit, "normals", surface.normals @ pose.rotation.T)
    return unit, pose


def run_in_unit_pose(run: Callable[..., Any], surface: MethodInput, params: dict) -> Any:
    """Run ``run(unit_surface, **params)`` on the normalised surface; uv back in input units.

    Parameters
    ----------
    run : callable
        A method's ``run``; returns a :class:`parambench.methods.base.Parameterization`.
    surface : MethodInput
        The method's input (not modified).
    params : dict
        Resolved method parameters.

    Returns
    -------
    Parameterization
        ``uv`` multiplied by the input's scale, so that a faithful map keeps the
        surface's lengths; ``diagnostics["input_scale"]`` records the factor (other
        diagnostics, e.g. eigenvalues, are those of the unit-size copy).

    Raises
    ------
    InvalidInputError
        See :func:`surface_pose`; anything ``run`` raises passes through.
    """
    unit, pose = normalised_surface(surface)
    result = run(unit, **params)
    result.uv = result.uv * pose.scale
    result.diagnostics["input_scale"] = pose.scale
    return result
