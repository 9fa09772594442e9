"""Points scattered over a real mesh (``sampling="scattered"``): on the surface, uniform by
area, none on the rim, with a reference triangulation that is a disk over every point."""

from __future__ import annotations

import igl
import numpy as np
import pytest
from scipy.spatial import cKDTree

from parambench.bench.metrics import evaluate, turning_number
from parambench.datasets_gen.errors import InvalidInputError, NotADiskError, TooFewPointsError, UnknownNameError
from parambench.datasets_gen.registry import make_surface
from parambench.bench.metrics.rim import rim_samples
from parambench.datasets_gen import scattered as scattered_module
from parambench.datasets_gen.scattered import PEEL_RADIUS_SPACINGS, scatter_on_mesh
from parambench.datasets_gen.surface import Surface, circumradii


@pytest.fixture(scope="module")
def lilium():
    return make_surface("real/lilium", seed=0)


@pytest.fixture(scope="module")
def scattered(lilium):
    return make_surface("real/lilium", 3000, sampling="scattered", seed=0)


def test_points_lie_on_the_mesh_uniformly_by_area(lilium, scattered):
    assert scattered.n_points == 3000 and scattered.params["n_actual"] == 3000
    dist2, face, _ = igl.point_mesh_squared_distance(scattered.points, lilium.points, lilium.faces)
    assert np.sqrt(dist2.max()) < 1e-9 * scattered.diameter
    # Half the mesh's area by face order: about half the points, within 4 standard deviations.
    area = igl.doublearea(lilium.points, lilium.faces)
    first = np.cumsum(area) <= 0.5 * area.sum()
    share = np.mean(first[face])
    expected = area[first].sum() / area.sum()
    assert abs(share - expected) < 4 * np.sqrt(expected * (1 - expected) / scattered.n_points)


def test_no_point_on_the_rim(lilium, scattered):
    loop = lilium.boundary_loops[0]
    start, end = lilium.points[loop], lilium.points[np.roll(loop, -1)]
    # distance of every point to every rim segment, the smallest
    d = end - start
    t = np.clip(np.einsum("nsk,sk->ns", scattered.points[:, None] - start[None], d) / np.einsum("sk,sk->s", d, d),
                0, 1)
    nearest = np.linalg.norm(scattered.points[:, None] - (start[None] + t[..., None] * d[None]), axis=2).min(axis=1)
    assert nearest.min() > 1e-6 * scattered.params["spacing"]
    assert np.mean(nearest < scattered.params["spacing"]) < 0.1  # a rim band, not a rim of points


def test_reference_triangulation_is_a_disk_over_every_point_facing_the_normals(scattered):
    faces = scattered.faces
    assert np.array_equal(np.unique(faces), np.arange(scattered.n_points))  # no point left out
    assert igl.is_edge_manifold(faces)[0]
    assert igl.facet_components(faces)[0] == 1
    assert len(scattered.boundary_loops) == 1  # lilium has one rim
    assert scattered.boundary_mask.sum() == scattered.boundary_loops[0].size
    p = scattered.points[faces]
    face_normals = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    assert np.all(np.einsum("mk,mk->m", face_normals, scattered.normals[faces].sum(axis=1)) > 0)
    # libigl's map of the reference folds nothing and runs the rim counter-clockwise
    uv = np.asarray(igl.spectra.lscm(scattered.points, faces))
    if evaluate(scattered.points, faces, uv)["foldovers"]:
        uv[:, 1] *= -1
    assert evaluate(scattered.points, faces, uv)["foldovers"] == 0
    assert turning_number(uv[scattered.boundary_loops[0]]) == pytest.approx(1.0)


def test_the_rim_notches_are_opened_not_bridged(lilium, scattered, monkeypatch):
    """Rim triangles of the reference are not the slivers a plain Delaunay triangulation
    lays along the outermost points: their circumradius stays under the peel's radius,
    while without the peel a good share of the rim triangles is wider."""
    alpha = PEEL_RADIUS_SPACINGS * scattered.params["spacing"]
    # Only rim triangles the peel must keep (ears, or a peel that would pinch) stay wide.
    assert np.mean(_rim_radii(scattered) > alpha) < 0.02
    monkeypatch.setattr(scattered_module, "peel_rim", lambda points, faces, radius: faces)
    unpeeled = scatter_on_mesh(lilium, 3000, seed=0)
    assert np.mean(_rim_radii(unpeeled) > alpha) > 0.2


def test_the_peel_stops_at_the_rim(lilium, scattered):
    """The reference's boundary runs along the mesh's rim: no boundary point deeper than
    the peel's disk diameter. (A peel at 2 spacings ran on through the interior's wide
    Delaunay triangles, 18 % of them, and cut notches 10-27 spacings deep.)"""
    spacing = scattered.params["spacing"]
    rim = rim_samples(lilium.points, lilium.boundary_loops, 0.25 * spacing)
    depth = cKDTree(rim).query(scattered.points[scattered.boundary_mask])[0] / spacing
    assert depth.max() < 2 * PEEL_RADIUS_SPACINGS
    assert np.median(depth) < 1.5


def _rim_radii(surface) -> np.ndarray:
    """Circumradii of the triangles with an edge on the surface's outer loop."""
    loop = surface.boundary_loops[0]
    rim_edges = {tuple(sorted(e)) for e in zip(loop.tolist(), np.roll(loop, -1).tolist())}
    on_rim = np.array([any(tuple(sorted((f[i], f[(i + 1) % 3]))) in rim_edges for i in range(3))
                       for f in surface.faces.tolist()])
    return circumradii(surface.points, surface.faces)[on_rim]


def test_seeded_and_reproducible(lilium):
    one = scatter_on_mesh(lilium, 500, seed=4)
    again = scatter_on_mesh(lilium, 500, seed=4)
    other = scatter_on_mesh(lilium, 500, seed=5)
    assert np.array_equal(one.points, again.points) and np.array_equal(one.faces, again.faces)
    assert not np.allclose(one.points, other.points)


def test_noise_moves_points_along_the_normals_by_the_asked_spacings(scattered):
    noisy = make_surface("real/lilium", 3000, sampling="scattered", seed=0, noise=0.5)
    offset = noisy.points - scattered.points
    along = np.einsum("nk,nk->n", offset, scattered.normals)
    assert np.allclose(offset, along[:, None] * scattered.normals, atol=1e-12)
    assert np.std(along) / scattered.params["spacing"] == pytest.approx(0.5, rel=0.1)
    assert np.array_equal(noisy.faces, scattered.faces) and noisy.params["noise"] == 0.5


def test_what_cannot_be_scattered_says_why(lilium):
    with pytest.raises(InvalidInputError, match="folds"):  # five holes: libigl's map folds
        make_surface("real/bunny10k", 1000, sampling="scattered")
    with pytest.raises(InvalidInputError, match="no faces"):
        make_surface("real/chameleon", 1000, sampling="scattered")
    with pytest.raises(TooFewPointsError):
        make_surface("real/lilium", 50, sampling="scattered")
    with pytest.raises(UnknownNameError, match="'random'"):
        make_surface("bump", 1000, sampling="scattered")
    tetrahedron = Surface(points=np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float),
                          faces=np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]))
    with pytest.raises(NotADiskError, match="no boundary"):
        scatter_on_mesh(tetrahedron, 200)


def test_circumradii_match_their_closed_forms():
    points = np.array([[0, 0, 0], [2, 0, 0], [1, np.sqrt(3), 0], [0, 3, 4], [4, 0, 0]], dtype=float)
    faces = np.array([[0, 1, 2], [0, 4, 3], [0, 1, 4]])  # equilateral side 2; right angle at 0; collinear
    radius = circumradii(points, faces)
    assert radius[0] == pytest.approx(2 / np.sqrt(3)) and radius[1] == pytest.approx(np.sqrt(41) / 2)  # hypotenuse / 2
    assert np.isinf(radius[2])


def test_a_mesh_in_metres_scatters_as_its_unit_copy():
    """matplotlib's topobathy DEM in metres (260 km across): libigl's spectral conformal map
    raised on it before the mesh was brought to unit size; the scattered points and their
    reference triangulation are the unit copy's, scaled."""
    from dataclasses import replace

    from parambench.datasets_gen.elevation import matplotlib_dem

    mesh = matplotlib_dem("topobathy")
    unit = replace(mesh, points=mesh.points / 1e5)
    big, small = scatter_on_mesh(mesh, 2000, seed=0), scatter_on_mesh(unit, 2000, seed=0)
    np.testing.assert_allclose(big.points / 1e5, small.points, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(big.faces, small.faces)
    assert len(big.boundary_loops) == 1
