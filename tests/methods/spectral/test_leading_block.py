"""L_II read in place from the Laplacian's leading rows, against a copy of the block."""

from __future__ import annotations

import igl
import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as sla

from parambench.datasets_gen.registry import make_surface
from parambench.methods.pointset.subsample import poisson_disk_subsample
from parambench.methods.spectral.leading_block import LeadingBlock, as_leading_block
from parambench.methods.spectral.multilevel import interpolation_matrix, leaf_ordered
from parambench.methods.spectral.reduction import BoundaryReduction
from parambench.methods.spectral.sparse_eigen import SparseFactor
from parambench.methods.spectral.twogrid import TwoGridSolver


def _random_csr(n: int, m: int, seed: int) -> sp.csr_matrix:
    a = sp.random(n, m, density=0.2, random_state=seed, format="csr")
    # Unsorted indices, as scipy leaves them after some operations.
    rng = np.random.default_rng(seed)
    for i in range(n):
        lo, hi = a.indptr[i], a.indptr[i + 1]
        shuffled = rng.permutation(hi - lo) + lo
        a.indices[lo:hi], a.data[lo:hi] = a.indices[shuffled].copy(), a.data[shuffled].copy()
    a.has_sorted_indices = False
    return a


@pytest.mark.parametrize("n", [0, 1, 7, 19, 25])
def test_the_block_s_rows_are_the_leading_block(n):
    a = _random_csr(25, 30, seed=n)
    dense = a.toarray()
    block = LeadingBlock(a, n)
    assert block.shape == (n, n)
    np.testing.assert_array_equal(block.tocsr().toarray(), dense[:n, :n])
    np.testing.assert_array_equal(block.diagonal(), np.diag(dense)[:n])
    assert block.nnz == np.count_nonzero(dense[:n, :n])
    for i in range(n):
        cols = block.indices[block.starts[i]:block.stops[i]]
        assert np.all(cols < n) and np.all(np.diff(cols) > 0)
        row = np.zeros(n)
        row[cols] = block.data[block.starts[i]:block.stops[i]]
        np.testing.assert_array_equal(row, dense[i, :n])
    # The whole matrix is unchanged (only its indices' order within rows).
    np.testing.assert_array_equal(a.toarray(), dense)


def test_bad_blocks_are_refused():
    with pytest.raises(TypeError, match="CSR"):
        LeadingBlock(sp.csc_matrix(np.eye(3)), 2)
    with pytest.raises(ValueError, match="between 0 and 3"):
        LeadingBlock(sp.csr_matrix(np.eye(3)), 4)
    with pytest.raises(ValueError, match="square"):
        as_leading_block(sp.csr_matrix(np.ones((2, 3))))
    block = LeadingBlock(sp.csr_matrix(np.eye(3)), 2)
    assert as_leading_block(block) is block


@pytest.fixture(scope="module")
def boundary_last():
    """A jittered cap's cotangent Laplacian with its boundary rows numbered last, and a prolongation."""
    surf = make_surface("cap", 5000, sampling="jittered", seed=1)
    boundary = np.concatenate(surf.boundary_loops)
    lap, order, inverse = leaf_ordered(sp.csr_matrix(-igl.cotmatrix(surf.points, surf.faces)), surf.points,
                                       last=boundary)
    points, boundary = surf.points[order], inverse[boundary]
    n_i = surf.n_points - boundary.size
    spacing = np.median(np.linalg.norm(surf.points[surf.faces[:, 0]] - surf.points[surf.faces[:, 1]], axis=1))
    coarse = np.sort(poisson_disk_subsample(points, 2.0 * spacing, boundary, seed=0))
    normals = igl.per_vertex_normals(surf.points, surf.faces)[order]
    prolong = sp.csr_matrix(interpolation_matrix(points, coarse, normals))
    coarse_interior = np.flatnonzero(coarse < n_i)
    p_ii = prolong[:n_i][:, coarse_interior]
    return lap, boundary, n_i, p_ii


def test_leaf_order_puts_the_given_rows_last(boundary_last):
    _, boundary, n_i, _ = boundary_last
    np.testing.assert_array_equal(np.sort(boundary), np.arange(n_i, n_i + boundary.size))


def test_two_grid_solves_on_the_rows_in_place_equal_those_on_a_copy(boundary_last):
    lap, _, n_i, p_ii = boundary_last
    copy = sp.csr_matrix(lap[:n_i][:, :n_i])
    coarse = sla.splu(sp.csc_matrix(p_ii.T @ copy @ p_ii)).solve
    in_place = TwoGridSolver(LeadingBlock(lap, n_i), p_ii, coarse, order=np.arange(n_i))
    copied = TwoGridSolver(copy, p_ii, coarse, order=np.arange(n_i))
    b = np.random.default_rng(3).standard_normal((n_i, 4))
    x = in_place.solve(b)
    # The same entries in the same order: the same iterates, bit for bit.
    np.testing.assert_array_equal(x, copied.solve(b))
    assert np.linalg.norm(copy @ x - b) <= 1e-9 * np.linalg.norm(b)
    assert in_place.n_cycles == copied.n_cycles > 0 and not in_place.fell_back
    # A fallback factorises the block itself, not the whole matrix.
    in_place._fall_back()
    np.testing.assert_allclose(in_place.solve(b), sla.spsolve(sp.csc_matrix(copy), b), rtol=1e-9, atol=1e-12)


def test_the_reduction_hands_its_solver_the_laplacian_s_own_rows(boundary_last):
    lap, boundary, n_i, p_ii = boundary_last
    given = []

    def factory(block, rows):
        given.append(block)
        return SparseFactor(block)

    red = BoundaryReduction(lap, boundary, interior_solver=factory)
    assert isinstance(given[0], LeadingBlock) and given[0].shape == (n_i, n_i)
    assert np.shares_memory(given[0].data, lap.data)
    exact = BoundaryReduction(lap, boundary)
    np.testing.assert_allclose(red.schur, exact.schur, rtol=1e-9, atol=1e-9 * np.abs(exact.schur).max())
    # Kept vertices that are not the last ones: the solver gets a copy of the block.
    shuffled = np.roll(np.arange(lap.shape[0]), 5)
    BoundaryReduction(lap[shuffled][:, shuffled].tocsr(), np.argsort(shuffled)[boundary], interior_solver=factory)
    assert isinstance(given[1], sp.csr_matrix) and given[1].shape == (n_i, n_i)
