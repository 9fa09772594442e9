"""Per-triangle Jacobian of a piecewise-linear map to the plane, and its singular values."""

from __future__ import annotations

import numpy as np

from ._inputs import check_mesh
from .orientation import triangle_signed_areas

__all__ = ["jacobian_singular_values", "quasi_conformal", "beltrami_abs", "sigma_ratio_excess", "per_face_qc",
           "face_jacobian_sv"]


def face_jacobian_sv(
    points: np.ndarray, faces: np.ndarray, uv: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Unchecked core of :func:`jacobian_singular_values` (inputs already validated)."""
    p0, p1, p2 = points[faces[:, 0]], points[faces[:, 1]], points[faces[:, 2]]
    e1, e2 = p1 - p0, p2 - p0
    # Each triangle in its own orthonormal frame: x along e1, y in the plane so that the
    # triangle is counter-clockwise, i.e. local coords (0,0), (a,0), (b,c) with c > 0.
    a = np.sqrt(np.einsum("ij,ij->i", e1, e1))
    two_area = np.linalg.norm(np.cross(e1, e2), axis=1)
    b = np.einsum("ij,ij->i", e1, e2) / a
    c = two_area / a

    u0 = uv[faces[:, 0]]
    d1 = uv[faces[:, 1]] - u0
    d2 = uv[faces[:, 2]] - u0
    # J maps local coords to uv: J @ [[a, b], [0, c]] = [d1 d2]. Its columns:
    col1 = d1 / a[:, None]
    col2 = (d2 - (b / a)[:, None] * d1) / c[:, None]
    p, r = col1[:, 0], col1[:, 1]
    q, s = col2[:, 0], col2[:, 1]
    # Closed-form 2x2 SVD via the similarity / anti-similarity split J = [E -H; H E] + [F G; G -F]:
    # |f_z| = hypot(E, H), |f_zbar| = hypot(F, G), s1 = |f_z| + |f_zbar|, s2 = | |f_z| - |f_zbar| |.
    # This form keeps s1/s2 == 1 to rounding for a similarity (no cancellation in a discriminant).
    fz = np.hypot(0.5 * (p + s), 0.5 * (r - q))
    fzbar = np.hypot(0.5 * (p - s), 0.5 * (r + q))
    s1 = fz + fzbar
    s2 = np.abs(fz - fzbar)
    return s1, s2, triangle_signed_areas(uv, faces), 0.5 * two_area


def jacobian_singular_values(points, faces, uv) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Singular values of the piecewise-linear map's Jacobian on every triangle.

    Each 3D triangle is laid out in its own orthonormal 2D frame, counter-clockwise (as
    seen from the side its vertex order makes the normal point to), and the affine map from
    that frame to the triangle's uv image is taken. Vectorised, with a closed-form 2x2 SVD.

    Parameters
    ----------
    points : (N, 3) array_like of float64
    faces : (M, 3) array_like of int64
    uv : (N, 2) array_like of float64

    Returns
    -------
    s1, s2 : (M,) numpy.ndarray of float64
        Singular values, ``s1 >= s2 >= 0``. ``s1 * s2`` is the area ratio uv / 3D.
    signed_area_uv : (M,) numpy.ndarray of float64
        Signed uv area, positive when the uv image keeps the face's vertex order
        counter-clockwise; its sign is the sign of det J.
    area_3d : (M,) numpy.ndarray of float64
        Triangle areas in 3D (> 0).

    Raises
    ------
    InvalidInputError
        Bad shapes, NaN/inf in points or uv, face indices out of range.
    DegenerateFacesError
        A face repeats a vertex or has zero 3D area (its Jacobian is undefined).
    """
    return face_jacobian_sv(*check_mesh(points, faces, uv))


def quasi_conformal(s1: np.ndarray, s2: np.ndarray) -> np.ndarray:
    """Quasi-conformal distortion ``s1 / s2`` per triangle (1 for a conformal triangle).

    Orientation is not part of this number: a mirrored (anti-conformal) triangle also
    gives 1; flips are reported by :func:`count_foldovers`.

    Parameters
    ----------
    s1, s2 : (M,) array_like of float64
        Singular values, ``s1 >= s2 >= 0``.

    Returns
    -------
    (M,) numpy.ndarray of float64
        ``inf`` where ``s2 == 0`` (a triangle collapsed to a segment or a point).
    """
    s1 = np.asarray(s1, dtype=np.float64)
    s2 = np.asarray(s2, dtype=np.float64)
    out = np.full(np.broadcast(s1, s2).shape, np.inf)
    np.divide(s1, s2, out=out, where=s2 > 0)
    return out


def beltrami_abs(s1: np.ndarray, s2: np.ndarray) -> np.ndarray:
    """Modulus of the Beltrami coefficient per triangle, ``|mu| = (s1 - s2) / (s1 + s2)``.

    0 for a conformal triangle, towards 1 as the triangle collapses to a segment; the same
    information as QC (``|mu| = (QC - 1) / (QC + 1)``) on the bounded scale the conformal
    geometry literature reports. Like QC it ignores orientation.

    Parameters
    ----------
    s1, s2 : (M,) array_like of float64
        Singular values, ``s1 >= s2 >= 0``.

    Returns
    -------
    (M,) numpy.ndarray of float64
        In [0, 1]; NaN where ``s1 == s2 == 0`` (a triangle collapsed to a point).
    """
    s1 = np.asarray(s1, dtype=np.float64)
    s2 = np.asarray(s2, dtype=np.float64)
    den = s1 + s2
    out = np.full(np.broadcast(s1, s2).shape, np.nan)
    np.divide(s1 - s2, den, out=out, where=den > 0)
    return out


def sigma_ratio_excess(s1: np.ndarray, s2: np.ndarray) -> np.ndarray:
    """``s1/s2 + s2/s1 - 2`` per triangle: the MIPS conformal energy above its minimum.

    0 for a conformal triangle; ``(a - 1)^2 / a`` for a stretch by ``a``.

    Parameters
    ----------
    s1, s2 : (M,) array_like of float64
        Singular values, ``s1 >= s2 >= 0``.

    Returns
    -------
    (M,) numpy.ndarray of float64
        ``inf`` where ``s2 == 0``.
    """
    qc = quasi_conformal(s1, s2)
    with np.errstate(divide="ignore"):
        return qc + 1.0 / qc - 2.0


def per_face_qc(points, faces, uv) -> np.ndarray:
    """Quasi-conformal distortion of every triangle, for colour-coded pictures.

    Same code path as :func:`evaluate`. Parameters and errors as in
    :func:`jacobian_singular_values`.

    Returns
    -------
    (M,) numpy.ndarray of float64
        ``s1 / s2`` per face, ``inf`` on collapsed faces.
    """
    s1, s2, _, _ = jacobian_singular_values(points, faces, uv)
    return quasi_conformal(s1, s2)
