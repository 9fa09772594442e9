"""Shared helpers for the datasets_gen tests: small geometric checks written out by hand."""

from __future__ import annotations

import numpy as np
import pytest


def signed_area(poly: np.ndarray) -> float:
    """Shoelace formula, positive for a counter-clockwise polygon."""
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def jacobian_singular_values(points: np.ndarray, faces: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Per-face singular values (sigma_max, sigma_min) of the linear map triangle -> uv triangle."""
    p, q = points[faces], uv[faces]
    e = np.stack([p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]], axis=2)  # (m, 3, 2)
    f = np.stack([q[:, 1] - q[:, 0], q[:, 2] - q[:, 0]], axis=2)  # (m, 2, 2)
    _, r = np.linalg.qr(e)  # e = Q r with Q orthonormal columns: r is the triangle in its own plane
    jac = f @ np.linalg.inv(r)
    return np.linalg.svd(jac, compute_uv=False)


def face_areas(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    p = points[faces]
    return 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)


def unique_edges(faces: np.ndarray) -> np.ndarray:
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    return np.unique(np.sort(e, axis=1), axis=0)


@pytest.fixture
def helpers():
    class H:
        pass

    h = H()
    h.signed_area = signed_area
    h.jacobian_singular_values = jacobian_singular_values
    h.face_areas = face_areas
    h.unique_edges = unique_edges
    return h
