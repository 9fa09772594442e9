"""Pieces of a mesh, and whether the largest meshes an open surface without handles."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import ConvexHull

from parambench.datasets_gen.mesh_pieces import face_pieces, largest_piece_topology


def _sphere(n=400):
    """A closed triangulated sphere: the convex hull of a Fibonacci spiral's points."""
    i = np.arange(n) + 0.5
    z, phi = 1.0 - 2.0 * i / n, np.pi * (1.0 + 5.0**0.5) * i
    r = np.sqrt(1.0 - z**2)
    points = np.c_[r * np.cos(phi), r * np.sin(phi), z]
    faces = ConvexHull(points).simplices.astype(np.int64)
    p = points[faces]
    outward = np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), p.mean(axis=1)) > 0
    return points, np.where(outward[:, None], faces, faces[:, ::-1])  # wound alike: outward


def _torus(n=24, m=12):
    """A closed torus, n x m quads split in two, wrapped both ways."""
    u, v = np.meshgrid(np.arange(n) * 2 * np.pi / n, np.arange(m) * 2 * np.pi / m, indexing="ij")
    points = np.c_[((2 + np.cos(v)) * np.cos(u)).ravel(), ((2 + np.cos(v)) * np.sin(u)).ravel(), np.sin(v).ravel()]
    idx = np.arange(n * m).reshape(n, m)
    a, b = idx, np.roll(idx, -1, axis=0)
    c, d = np.roll(b, -1, axis=1), np.roll(a, -1, axis=1)
    faces = np.r_[np.c_[a.ravel(), b.ravel(), c.ravel()], np.c_[a.ravel(), c.ravel(), d.ravel()]]
    return points, faces


def _grid(n=8):
    x, y = np.meshgrid(np.arange(n, dtype=float), np.arange(n, dtype=float))
    i = np.arange(n * n).reshape(n, n)[:-1, :-1].ravel()
    return np.c_[x.ravel(), y.ravel(), np.zeros(n * n)], np.r_[np.c_[i, i + 1, i + n + 1], np.c_[i, i + n + 1, i + n]]


@pytest.mark.parametrize("shape,holes,expected", [
    ("sphere", 0, {"boundary_loops": 0, "genus": 0}),
    ("sphere", 2, {"boundary_loops": 2, "genus": 0}),
    ("torus", 0, {"boundary_loops": 0, "genus": 1}),
    ("torus", 1, {"boundary_loops": 1, "genus": 1}),
    ("grid", 0, {"boundary_loops": 1, "genus": 0}),
])
def test_the_largest_piece_s_loops_and_genus(shape, holes, expected):
    points, faces = {"sphere": _sphere, "torus": _torus, "grid": _grid}[shape]()
    # holes: drop every face at a vertex, at vertices far apart (one hole each)
    for vertex in (0, len(points) // 2)[:holes]:
        faces = faces[~(faces == vertex).any(axis=1)]
    # a speck far away must not count: the largest piece is judged
    speck_points, speck_faces = _grid(3)
    points = np.r_[points, speck_points + 100.0]
    faces = np.r_[faces, speck_faces + len(points) - len(speck_points)]
    assert largest_piece_topology(faces, len(points)) == expected


def test_face_pieces_are_numbered_largest_first():
    sphere, fs = _sphere(60)
    grid, fg = _grid(12)
    points, faces = np.r_[sphere, grid + 10.0], np.r_[fs, fg + len(sphere)]
    label, sizes = face_pieces(faces, len(points))
    assert sizes.tolist() == [len(fg), len(fs)]
    assert (label[:len(fs)] == 1).all() and (label[len(fs):] == 0).all()


def test_no_handle_is_claimed_for_a_fin_or_a_mis_wound_piece():
    points, faces = _grid()
    a, b = faces[12, 0], faces[12, 1]
    fin = np.r_[faces, [[a, b, len(points)]]]  # a third face on an interior edge
    assert largest_piece_topology(fin, len(points) + 1)["genus"] in (None, 0)
    mixed = faces.copy()
    mixed[:5] = mixed[:5, ::-1]
    assert largest_piece_topology(mixed, len(points)) == {"boundary_loops": 1, "genus": None}


def test_a_pinched_vertex_is_no_handle():
    """Two decimations of pymeshfix's Stanford bunny each kept 2 vertices where separate fans
    meet; counted once, each lowered the Euler characteristic by one and read as a handle."""
    points, faces = _grid(8)
    extra = np.array([[0.0, 0.3, 1.0], [0.3, 0.0, 1.0]])
    pinched = np.r_[faces, [[0, 64, 65]]]  # a lone triangle on the grid's corner vertex
    points = np.r_[points, extra]
    assert largest_piece_topology(pinched, len(points)) == {"boundary_loops": 2, "genus": 0}
