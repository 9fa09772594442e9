"""The Neumann point-set Laplacian: moment weights, gradients, edge normals, planar exactness."""

from __future__ import annotations

import numpy as np
import pytest

from parambench.datasets_gen.errors import InvalidInputError
from parambench.datasets_gen.registry import make_surface
from parambench.methods.pointset.frontend import build_frontend
from parambench.methods.pointset.neumann_laplacian import (
    boundary_cell_areas,
    boundary_edge_normals,
    gradient_stencils,
    moment_weights,
    neumann_laplacian,
)
from parambench.methods.spectral.operators import area_matrix


def _random_balls(n=50, b=14, seed=0):
    rng = np.random.default_rng(seed)
    coords = rng.uniform(-1, 1, size=(n, b, 2))
    mask = np.ones((n, b), dtype=bool)
    mask[:, -3:] = rng.random((n, 3)) < 0.5  # some padding
    coords[~mask] = 99.0  # padding values must be ignored
    return coords, mask


@pytest.mark.parametrize("order", ["linear", "quadratic"])
def test_moment_weights_satisfy_their_constraints(order):
    coords, mask = _random_balls()
    w = moment_weights(coords, mask, order)
    t = np.where(mask[..., None], coords, 0.0)
    assert np.all(w[~mask] == 0)
    np.testing.assert_allclose(w.sum(1), 1.0, atol=1e-12)
    np.testing.assert_allclose(np.einsum("nb,nbc->nc", w, t), 0.0, atol=1e-8)
    second = [(w * (t[..., 0] ** 2 - t[..., 1] ** 2)).sum(1), (w * t[..., 0] * t[..., 1]).sum(1)]
    if order == "quadratic":
        np.testing.assert_allclose(second, 0.0, atol=1e-8)
        # Hence [(I - W) f] = -(q/4) Lap f exactly for any quadratic f (here Lap f = 2a + 2c).
        a, bq, c = 0.7, -0.3, 1.9
        f = a * t[..., 0] ** 2 + bq * t[..., 0] * t[..., 1] + c * t[..., 1] ** 2 + 3 * t[..., 0] - t[..., 1]
        q = (w * (t**2).sum(-1)).sum(1)
        np.testing.assert_allclose(-(w * f).sum(1), -(q / 4) * (2 * a + 2 * c), atol=1e-8)
    else:
        assert np.abs(second).max() > 1e-3  # not imposed


def test_moment_weights_errors():
    coords, mask = _random_balls()
    with pytest.raises(InvalidInputError):
        moment_weights(coords, mask, "cubic")
    small = mask.copy()
    small[0, 3:] = False
    with pytest.raises(InvalidInputError):
        moment_weights(coords, small, "quadratic")


def test_gradient_stencils_exact_for_linear_functions():
    coords, mask = _random_balls()
    p = gradient_stencils(coords, mask)
    t = np.where(mask[..., None], coords, 0.0)
    g = np.array([2.5, -1.25])
    np.testing.assert_allclose(np.einsum("ncb,nb->nc", p, t @ g), np.broadcast_to(g, (len(t), 2)), atol=1e-9)


@pytest.fixture(scope="module")
def plane_front():
    surf = make_surface("plane", 700, sampling="jittered", seed=1)
    return build_frontend(surf.points), surf


def test_edge_normals_point_outward_and_sum_to_zero(plane_front):
    front, _ = plane_front
    pts, b = boundary_edge_normals(front.ball_indices, front.tangent_coords, front.boundary_loops)
    assert pts.size == sum(loop.size for loop in front.boundary_loops)
    # Outward: away from the ball's centroid (the ball is a half disk at the boundary).
    valid = front.ball_indices[pts] >= 0
    cen = (front.tangent_coords[pts] * valid[..., None]).sum(1)
    assert np.all((b * cen).sum(1) < 0)
    # Length ~ boundary length per point.
    assert 0.3 < np.median(np.linalg.norm(b, axis=1)) / front.mean_spacing < 2.0


def test_planar_identity_is_an_exact_zero_energy_map(plane_front):
    """On a plane the identity map solves (L/2 - M) z = 0 exactly: k_opt = 1."""
    front, surf = plane_front
    lap = neumann_laplacian(front.ball_indices, front.tangent_coords, front.boundary_loops, front.mean_spacing)
    n = front.n_points
    np.testing.assert_allclose(lap @ np.ones(n), 0.0, atol=1e-9)
    # The plane shape lies in a plane: take its in-plane coordinates as z.
    centred = surf.points - surf.points.mean(0)
    _, _, vt = np.linalg.svd(centred, full_matrices=False)
    xy = centred @ vt[:2].T
    z = xy[:, 0] + 1j * xy[:, 1]
    m = area_matrix(front.boundary_loops, n)
    residual = 0.5 * (lap @ z) - m @ z
    # Exact up to the DEM's rounding on a plane (~1e-7 relative); the paper's I - W^tan
    # leaves a residual of the order of the boundary rows themselves.
    assert np.abs(residual).max() < 1e-5 * np.abs(lap @ z).max()
    # 1/2 z^H L z is the enclosed area, as z^H M z (up to a reflection of the frame).
    area = np.real(np.vdot(z, m @ z))
    assert abs(abs(0.5 * np.real(np.vdot(z, lap @ z))) - abs(area)) < 1e-5 * abs(area)


def test_options_are_checked(plane_front):
    front, _ = plane_front
    args = (front.ball_indices, front.tangent_coords, front.boundary_loops, front.mean_spacing)
    with pytest.raises(InvalidInputError):
        neumann_laplacian(*args, interior="cubic")
    with pytest.raises(InvalidInputError):
        neumann_laplacian(*args, interior="tangent")  # needs tangent_w
    lap = neumann_laplacian(*args, interior="tangent", boundary="tangent", tangent_w=front.W)
    np.testing.assert_allclose(lap @ np.ones(front.n_points), 0.0, atol=1e-9)


def _boundary_vertex_areas(surf) -> np.ndarray:
    """A third of the mesh faces' areas around each vertex (the barycentric cells)."""
    p, f = surf.points, surf.faces
    area = 0.5 * np.linalg.norm(np.cross(p[f[:, 1]] - p[f[:, 0]], p[f[:, 2]] - p[f[:, 0]]), axis=1)
    return np.bincount(f.ravel(), np.repeat(area / 3.0, 3), len(p))


def test_boundary_cell_areas_match_the_mesh_where_the_spacing_model_does_not():
    """Graded plane with holes: the measured half cells are the true mesh's boundary cells.

    The spacing model (``area_factor * h^2 / 2``, h from interior neighbours) is off by
    a factor 2 or more at a tenth of the boundary points here (boundary sampled sparser
    than the inside next to it); the measured cells are within 1 % in the median.
    """
    surf = make_surface("holes", 2000, sampling="graded", seed=0)
    front = build_frontend(surf.points)
    pts, cells = boundary_cell_areas(front.ball_indices, front.tangent_coords, front.boundary_loops)
    assert pts.size == sum(loop.size for loop in front.boundary_loops)
    truth = _boundary_vertex_areas(surf)[pts]
    ok = np.isfinite(cells)
    assert ok.mean() > 0.95
    ratio = cells[ok] / truth[ok]
    assert abs(np.median(ratio) - 1.0) < 0.01
    assert np.mean(np.abs(np.log(ratio)) < np.log(1.25)) > 0.9
    model = 0.5 * 0.65 * front.local_spacing[pts] ** 2
    assert np.mean(np.abs(np.log(model / truth)) > np.log(2.0)) > 0.1  # what the measurement replaces


def test_boundary_options_are_checked(plane_front):
    front, _ = plane_front
    args = (front.ball_indices, front.tangent_coords, front.boundary_loops, front.mean_spacing)
    with pytest.raises(InvalidInputError):
        neumann_laplacian(*args, boundary_area="voronoi")
    with pytest.raises(InvalidInputError):
        neumann_laplacian(*args, boundary_width=0.0)
    for kw in ({"boundary_area": "spacing"}, {"boundary_width": 0.5}):
        np.testing.assert_allclose(neumann_laplacian(*args, **kw) @ np.ones(front.n_points), 0.0, atol=1e-9)


def _stencil_sum(ball, w, rows, flux):
    from parambench.methods.pointset.neumann_laplacian import stencil_matrix

    n = ball.shape[0]
    return (-stencil_matrix(ball, w, n) + stencil_matrix(ball[rows], flux, n, rows=rows)).tocsr()


def test_assembled_laplacian_is_the_stencils_sum_entry_for_entry():
    """One compiled pass gives the matrix scipy's stencil subtraction and sum give, storage
    order and rounding included: zero weights and fluxes (dropped, or kept where the other
    part is not zero), rows summing to zero, padding in the middle of a ball."""
    from parambench.methods.pointset.neumann_laplacian import assembled_laplacian

    rng = np.random.default_rng(5)
    n, b = 300, 12
    ball = np.stack([rng.permutation(np.delete(np.arange(n), i))[:b] for i in range(n)])
    ball[rng.random((n, b)) < 0.15] = -1
    w = rng.normal(size=(n, b))
    w[rng.random((n, b)) < 0.2] = 0.0
    w[7, :] = 0.0  # an empty row
    w[8, :2], w[8, 2:] = [0.5, -0.5], 0.0  # a row summing to zero
    ball[8, :2] = [3, 4]
    rows = np.sort(rng.choice(n, 60, replace=False))
    rows = np.union1d(rows, [7, 8])
    flux = rng.normal(size=(rows.size, b))
    flux[rng.random(flux.shape) < 0.3] = 0.0
    new = assembled_laplacian(ball, w, rows, flux)
    old = _stencil_sum(ball, w, rows, flux)
    assert new.indices.dtype == old.indices.dtype
    np.testing.assert_array_equal(new.indptr, old.indptr)
    np.testing.assert_array_equal(new.indices, old.indices)
    np.testing.assert_array_equal(new.data, old.data)
    assert abs(new.sum(axis=1)).max() < 1e-12  # rows of a Laplacian


def test_neumann_laplacian_of_a_front_end_is_the_stencils_sum(monkeypatch):
    import parambench.methods.pointset.neumann_laplacian as nl

    front = build_frontend(make_surface("holes", 2000, sampling="random", seed=0).points)
    new = neumann_laplacian(front.ball_indices, front.tangent_coords, front.boundary_loops, front.local_spacing)
    monkeypatch.setattr(nl, "assembled_laplacian", _stencil_sum)
    old = neumann_laplacian(front.ball_indices, front.tangent_coords, front.boundary_loops, front.local_spacing)
    for attr in ("indptr", "indices", "data"):
        np.testing.assert_array_equal(getattr(new, attr), getattr(old, attr))
