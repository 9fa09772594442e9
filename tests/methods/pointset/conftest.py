"""Small analytic surfaces for the front-end tests, with exact ground truth.

Each generator returns a ``Patch``: points, exact unit normals (pointing to +z-ish, the
front end's orientation rule), the true boundary loops (outer counter-clockwise seen
from the normals, holes clockwise), and where it exists the exact log map at any centre.
Samplings: ``grid`` (square lattice of spacing h), ``jittered`` (lattice points moved
uniformly by up to 0.3 h per axis; boundary points stay on the boundary curve),
``random`` (uniform random interior points, boundary points evenly spaced).
Boundary curves carry their own evenly spaced points; lattice points closer than 0.6 h
to a boundary curve are removed so no interior point sits on the boundary.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import pytest


@dataclass
class Patch:
    points: np.ndarray
    normals: np.ndarray
    loops: list = field(default_factory=list)
    uv: np.ndarray | None = None  # exact isometric unrolling (plane, cylinder)
    log_map: Callable | None = None  # log_map(centre_index, member_indices) -> (M, 3) in 3D tangent plane
    faces: np.ndarray | None = None

    @property
    def boundary_mask(self) -> np.ndarray:
        mask = np.zeros(len(self.points), dtype=bool)
        for loop in self.loops:
            mask[loop] = True
        return mask


def _lattice_in_square(n_side: int, half: float) -> tuple[np.ndarray, float]:
    h = 2 * half / (n_side - 1)
    g = np.linspace(-half, half, n_side)
    xy = np.stack(np.meshgrid(g, g, indexing="xy"), axis=-1).reshape(-1, 2)
    return xy, h


def _square_loop_indices(n_side: int) -> np.ndarray:
    """Indices of the lattice border of an n x n 'xy' meshgrid, counter-clockwise from (-1, -1)."""
    idx = np.arange(n_side * n_side).reshape(n_side, n_side)  # idx[row=y, col=x]
    bottom = idx[0, :]
    right = idx[1:, -1]
    top = idx[-1, -2::-1]
    left = idx[-2:0:-1, 0]
    return np.concatenate([bottom, right, top, left])


def _jitter(xy: np.ndarray, keep: np.ndarray, h: float, rng, sampling: str, half: float | None = None):
    """Move the points not in ``keep`` (boundary) according to ``sampling``."""
    out = xy.copy()
    free = ~keep
    if sampling == "jittered":
        out[free] += rng.uniform(-0.3 * h, 0.3 * h, size=(free.sum(), 2))
    elif sampling == "random":
        lo, hi = xy[free].min(axis=0), xy[free].max(axis=0)
        out[free] = rng.uniform(lo, hi, size=(free.sum(), 2))
    elif sampling != "grid":
        raise ValueError(sampling)
    return out


def height_patch(kind: str, n_side: int = 70, sampling: str = "grid", seed: int = 0, holes=()) -> Patch:
    """Graph surface z = f(x, y) over [-1, 1]^2: 'plane', 'bump', 'saddle'; optional circular holes."""
    rng = np.random.default_rng(seed)
    xy, h = _lattice_in_square(n_side, 1.0)
    outer = _square_loop_indices(n_side)
    is_b = np.zeros(len(xy), dtype=bool)
    is_b[outer] = True
    keep_pts = [xy]
    # Holes: remove lattice points near/inside each circle, add evenly spaced ring points.
    remove = np.zeros(len(xy), dtype=bool)
    rings = []
    for cx, cy, r in holes:
        d = np.hypot(xy[:, 0] - cx, xy[:, 1] - cy)
        remove |= d < r + 0.6 * h
        m = int(round(2 * np.pi * r / h))
        t = -np.linspace(0, 2 * np.pi, m, endpoint=False)  # clockwise seen from +z
        rings.append(np.c_[cx + r * np.cos(t), cy + r * np.sin(t)])
    moved = _jitter(xy, is_b, h, rng, sampling)
    # Random interior points may land in holes or too close to the outer border: drop them.
    for cx, cy, r in holes:
        remove |= np.hypot(moved[:, 0] - cx, moved[:, 1] - cy) < r + 0.3 * h
    remove &= ~is_b
    old_to_new = np.cumsum(~remove) - 1
    pts2 = moved[~remove]
    loops = [old_to_new[outer]]
    for ring in rings:
        start = len(pts2)
        pts2 = np.vstack([pts2, ring])
        loops.append(np.arange(start, start + len(ring)))
    x, y = pts2[:, 0], pts2[:, 1]
    if kind == "plane":
        z, zx, zy = 0 * x, 0 * x, 0 * x
    elif kind == "bump":
        a, s = 0.6, 0.5
        e = a * np.exp(-(x**2 + y**2) / s**2)
        z, zx, zy = e, -2 * x / s**2 * e, -2 * y / s**2 * e
    elif kind == "saddle":
        a = 0.5
        z, zx, zy = a * (x**2 - y**2), 2 * a * x, -2 * a * y
    else:
        raise ValueError(kind)
    pts = np.c_[x, y, z]
    nrm = np.c_[-zx, -zy, np.ones_like(x)]
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    uv = pts2.copy() if kind == "plane" else None
    log_map = None
    if kind == "plane":
        def log_map(c, members, _p=pts):
            return _p[members] - _p[c]
    return Patch(points=pts, normals=nrm, loops=loops, uv=uv, log_map=log_map)


def cylinder_patch(radius: float = 1.0, n_side: int = 60, sampling: str = "grid", seed: int = 0,
                   noise: float = 0.0) -> Patch:
    """A quarter cylinder (axis y), unrolled isometrically: u = R theta, v = y. Normals outward (+z-ish)."""
    rng = np.random.default_rng(seed)
    half = radius * np.pi / 4
    uv, h = _lattice_in_square(n_side, half)
    outer = _square_loop_indices(n_side)
    is_b = np.zeros(len(uv), dtype=bool)
    is_b[outer] = True
    uv = _jitter(uv, is_b, h, rng, sampling)
    theta = uv[:, 0] / radius
    nrm = np.c_[np.sin(theta), np.zeros_like(theta), np.cos(theta)]
    clean = np.c_[radius * np.sin(theta), uv[:, 1], radius * np.cos(theta)]
    pts = clean + noise * h * rng.standard_normal(len(uv))[:, None] * nrm

    def log_map(c, members):
        d = uv[members] - uv[c]  # geodesics are straight in the unrolling
        tc = np.array([np.cos(theta[c]), 0.0, -np.sin(theta[c])])  # d/du direction at c
        return d[:, :1] * tc + d[:, 1:2] * np.array([0.0, 1.0, 0.0])

    return Patch(points=pts, normals=nrm, loops=[outer], uv=uv, log_map=log_map)


def sphere_cap(radius: float = 1.0, cap_angle: float = 1.0, n_side: int = 70, sampling: str = "grid",
               seed: int = 0, noise: float = 0.0) -> Patch:
    """Spherical cap of polar angle ``cap_angle`` around +z, sampled through the azimuthal
    equidistant chart (u, v) = R phi (cos a, sin a), which keeps boundary points on the rim."""
    rng = np.random.default_rng(seed)
    rho = radius * cap_angle
    xy, h = _lattice_in_square(n_side, rho)
    xy = _jitter(xy, np.zeros(len(xy), dtype=bool), h, rng, sampling)
    xy = xy[np.hypot(xy[:, 0], xy[:, 1]) < rho - 0.6 * h]
    m = int(round(2 * np.pi * rho / h))
    t = np.linspace(0, 2 * np.pi, m, endpoint=False)
    ring = np.c_[rho * np.cos(t), rho * np.sin(t)]
    chart = np.vstack([xy, ring])
    phi = np.hypot(chart[:, 0], chart[:, 1]) / radius
    az = np.arctan2(chart[:, 1], chart[:, 0])
    nrm = np.c_[np.sin(phi) * np.cos(az), np.sin(phi) * np.sin(az), np.cos(phi)]
    pts = radius * nrm + noise * h * rng.standard_normal(len(chart))[:, None] * nrm
    clean = radius * nrm

    def log_map(c, members):
        sc = clean[c] / radius
        q = clean[members] / radius
        cosang = np.clip(q @ sc, -1.0, 1.0)
        ang = np.arccos(cosang)
        tangent = q - cosang[:, None] * sc
        norm = np.linalg.norm(tangent, axis=1, keepdims=True)
        norm[norm == 0] = 1.0
        return radius * ang[:, None] * tangent / norm

    loops = [np.arange(len(xy), len(chart))]
    return Patch(points=pts, normals=nrm, loops=loops, log_map=log_map)


def full_sphere(n: int = 2000, seed: int = 0) -> np.ndarray:
    """Fibonacci points on the unit sphere (a closed surface)."""
    i = np.arange(n) + 0.5
    phi = np.arccos(1 - 2 * i / n)
    theta = np.pi * (1 + 5**0.5) * i
    return np.c_[np.cos(theta) * np.sin(phi), np.sin(theta) * np.sin(phi), np.cos(phi)]


@pytest.fixture
def make_height_patch():
    return height_patch


@pytest.fixture
def make_cylinder():
    return cylinder_patch


@pytest.fixture
def make_cap():
    return sphere_cap


@pytest.fixture
def make_sphere():
    return full_sphere
