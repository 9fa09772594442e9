"""Least-squares similarity alignment of two planar point sets and the exact-map error."""

from __future__ import annotations

import numpy as np

from parambench.datasets_gen.errors import InvalidInputError

from ._inputs import check_uv

__all__ = ["similarity_align", "exact_map_error"]


def similarity_align(uv, target, allow_reflection: bool = True, *, return_transform: bool = False):
    """Move ``uv`` onto ``target`` by the best similarity transform (Umeyama, closed form).

    Minimises ``sum_i |s R uv_i + t - target_i|^2`` over the scale ``s >= 0``, the
    orthogonal 2x2 ``R`` (a rotation, or also a reflection if ``allow_reflection``) and
    the translation ``t``.

    Parameters
    ----------
    uv : (N, 2) array_like of float64
        The map to move.
    target : (N, 2) array_like of float64
        Reference positions, row for row.
    allow_reflection : bool
        Allow ``det R = -1`` (conformal maps are defined up to a mirror image).
    return_transform : bool
        Also return ``(scale, R, t)``.

    Returns
    -------
    aligned : (N, 2) numpy.ndarray of float64
        ``scale * uv @ R.T + t``.
    scale : float, R : (2, 2) numpy.ndarray, t : (2,) numpy.ndarray
        Only if ``return_transform``. If all rows of ``uv`` coincide the scale is 0 and
        every point goes to the centroid of ``target``.

    Raises
    ------
    InvalidInputError
        Shapes differ, fewer than 1 row, NaN or inf.
    """
    x = check_uv(uv)
    y = check_uv(target, x.shape[0], name="target")
    if x.shape[0] == 0:
        raise InvalidInputError("uv is empty; nothing to align.")
    mx, my = x.mean(axis=0), y.mean(axis=0)
    xc, yc = x - mx, y - my
    cov = yc.T @ xc / x.shape[0]
    u, sig, vt = np.linalg.svd(cov)
    d = np.ones(2)
    if not allow_reflection and np.linalg.det(u @ vt) < 0:
        d[1] = -1.0
    rot = (u * d) @ vt
    var_x = float(np.mean(np.einsum("ij,ij->i", xc, xc)))
    scale = float(sig @ d / var_x) if var_x > 0 else 0.0
    t = my - scale * rot @ mx
    aligned = scale * x @ rot.T + t
    if return_transform:
        return aligned, scale, rot, t
    return aligned


def exact_map_error(uv, exact_uv, diameter: float | None = None) -> float:
    """Relative RMS distance between a map and the known exact map, up to similarity.

    ``uv`` is first aligned to ``exact_uv`` by :func:`similarity_align` (reflection
    allowed), so the residual is in the units of ``exact_uv`` and does not depend on the
    arbitrary scale, rotation or position of ``uv``. The RMS (square root of the mean
    squared point-to-point distance) is then divided by ``diameter``, by default the
    bounding-box diagonal of ``exact_uv``: the result is a scale-free fraction (0.01 = an
    average misplacement of 1 % of the layout's size).

    Parameters
    ----------
    uv : (N, 2) array_like of float64
    exact_uv : (N, 2) array_like of float64
    diameter : float, optional
        Length in ``exact_uv`` units to divide by. Only pass the 3D surface diameter when
        ``exact_uv`` is in surface units (an isometric exact map).

    Returns
    -------
    float

    Raises
    ------
    InvalidInputError
        Shapes differ, NaN/inf, or a non-positive diameter (e.g. all exact points equal).
    """
    target = check_uv(exact_uv, name="exact_uv")
    aligned = similarity_align(uv, target, allow_reflection=True)
    if diameter is None:
        diameter = float(np.linalg.norm(target.max(axis=0) - target.min(axis=0)))
    if not np.isfinite(diameter) or diameter <= 0:
        raise InvalidInputError(f"diameter must be a positive finite length, got {diameter}; "
                                "exact_uv must not collapse to a single point.")
    rms = float(np.sqrt(np.mean(np.sum((aligned - target) ** 2, axis=1))))
    return rms / float(diameter)
