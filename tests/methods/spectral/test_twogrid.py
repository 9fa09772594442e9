"""The two-grid interior solver of the multilevel path against exact sparse solves."""

from __future__ import annotations

import igl
import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as sla

from parambench.datasets_gen.registry import make_surface
from parambench.methods.pointset.subsample import poisson_disk_subsample
from parambench.methods.spectral.multilevel import interpolation_matrix
from parambench.methods.spectral.reduction import BoundaryReduction
from parambench.methods.spectral.subspace import BoundarySubspace
from parambench.methods.spectral.twogrid import TwoGridSolver


@pytest.fixture(scope="module")
def cap_problem():
    """Cotangent Laplacian of a jittered cap, its interior block and a two-grid hierarchy."""
    surf = make_surface("cap", 6000, sampling="jittered", seed=0)
    lap = sp.csr_matrix(-igl.cotmatrix(surf.points, surf.faces))
    boundary = np.concatenate(surf.boundary_loops)
    mask = np.ones(surf.n_points, dtype=bool)
    mask[boundary] = False
    interior = np.flatnonzero(mask)
    spacing = np.median(np.linalg.norm(surf.points[surf.faces[:, 0]] - surf.points[surf.faces[:, 1]], axis=1))
    coarse = poisson_disk_subsample(surf.points, 2.0 * spacing, boundary, seed=0)
    normals = igl.per_vertex_normals(surf.points, surf.faces)
    prolong = interpolation_matrix(surf.points, coarse, normals)
    coarse_interior = np.flatnonzero(mask[coarse])
    p_ii = prolong[interior][:, coarse_interior]
    l_ii = sp.csr_matrix(lap[interior][:, interior])
    return lap, interior, boundary, l_ii, p_ii


def _coarse_solver(l_ii, p_ii):
    return sla.splu(sp.csc_matrix(p_ii.T @ l_ii @ p_ii)).solve


def test_solves_to_the_tolerance_in_few_cycles(cap_problem):
    _, _, _, l_ii, p_ii = cap_problem
    solver = TwoGridSolver(l_ii, p_ii, _coarse_solver(l_ii, p_ii), rtol=1e-10)
    b = np.random.default_rng(0).standard_normal((l_ii.shape[0], 3))
    x = solver.solve(b)
    exact = sla.spsolve(sp.csc_matrix(l_ii), b)
    assert np.linalg.norm(x - exact) <= 1e-8 * np.linalg.norm(exact)
    assert not solver.fell_back
    # A working coarse correction: a fixed factor per cycle (19 cycles measured) ...
    assert solver.n_cycles <= 25
    assert solver.n_solves == 3
    # ... where the same sweeps without it creep and are given up on as stalled.
    plain = TwoGridSolver(l_ii, p_ii, lambda r: np.zeros_like(r), rtol=1e-10)
    plain.solve(b)
    assert plain.fell_back


def test_complex_and_vector_right_hand_sides_keep_their_shape(cap_problem):
    _, _, _, l_ii, p_ii = cap_problem
    solver = TwoGridSolver(l_ii, p_ii, _coarse_solver(l_ii, p_ii))
    rng = np.random.default_rng(1)
    b = rng.standard_normal(l_ii.shape[0]) + 1j * rng.standard_normal(l_ii.shape[0])
    x = solver.solve(b)
    assert x.shape == b.shape and np.iscomplexobj(x)
    assert np.linalg.norm(l_ii @ x - b) <= 1e-9 * np.linalg.norm(b)


def test_a_useless_coarse_level_falls_back_to_a_factorisation(cap_problem):
    _, _, _, l_ii, p_ii = cap_problem
    # A coarse "correction" that overshoots by a factor 50 makes the cycles diverge.
    good = _coarse_solver(l_ii, p_ii)
    solver = TwoGridSolver(l_ii, p_ii, lambda r: 50.0 * good(r), max_cycles=30)
    b = np.random.default_rng(2).standard_normal((l_ii.shape[0], 2))
    x = solver.solve(b)
    assert solver.fell_back
    assert solver.n_cycles < 30  # it noticed the stall, it did not run out the cycles
    assert np.linalg.norm(l_ii @ x - b) <= 1e-9 * np.linalg.norm(b)


def test_a_non_positive_diagonal_goes_straight_to_the_factorisation(cap_problem):
    _, _, _, l_ii, p_ii = cap_problem
    bad = sp.csr_matrix(l_ii - sp.diags(np.where(np.arange(l_ii.shape[0]) == 5, 2 * l_ii.diagonal()[5], 0.0)))
    solver = TwoGridSolver(bad, p_ii, _coarse_solver(l_ii, p_ii))
    assert solver.fell_back
    b = np.ones(bad.shape[0])
    assert np.linalg.norm(bad @ solver.solve(b) - b) <= 1e-9 * np.linalg.norm(b)
    assert solver.n_cycles == 0


def test_boundary_reduction_with_the_two_grid_solver_matches_the_factorised_one(cap_problem):
    lap, interior, boundary, l_ii, p_ii = cap_problem
    coarse_solve = _coarse_solver(l_ii, p_ii)
    exact = BoundaryReduction(lap, boundary)
    made = []

    def factory(block, rows):
        np.testing.assert_array_equal(rows, interior)
        made.append(TwoGridSolver(block, p_ii, coarse_solve))
        return made[0]

    iterative = BoundaryReduction(lap, boundary, interior_solver=factory)
    assert iterative.interior_factor is made[0]
    x = np.random.default_rng(3).standard_normal((boundary.size, 4))
    s_exact, s_iter = exact.apply_schur(x), iterative.apply_schur(x)
    assert np.abs(s_iter - s_exact).max() <= 1e-7 * np.abs(s_exact).max()
    z = np.exp(2j * np.pi * np.arange(boundary.size) / boundary.size)
    assert np.abs(iterative.extend(z) - exact.extend(z)).max() <= 1e-8


def test_a_subspace_on_the_two_grid_solver_extends_its_maps_without_a_further_solve(cap_problem):
    """The interior values the Schur products computed are reused: same map, no extra solve."""
    lap, interior, boundary, l_ii, p_ii = cap_problem
    coarse_solve = _coarse_solver(l_ii, p_ii)
    iterative = BoundaryReduction(lap, boundary, interior_solver=lambda block, rows: TwoGridSolver(block, p_ii, coarse_solve))
    exact = BoundaryReduction(lap, boundary)
    assert iterative.solves_are_iterative and not exact.solves_are_iterative
    area = sp.identity(lap.shape[0], format="csr", dtype=np.complex128)
    sub = BoundarySubspace(iterative, area, [boundary], n_modes=4)
    y = np.random.default_rng(5).standard_normal(sub.size) + 1j * np.random.default_rng(6).standard_normal(sub.size)
    z_b = sub.basis @ y
    before = iterative.n_solves
    z = sub.extend(z_b)
    assert iterative.n_solves == before
    assert np.abs(z - exact.extend(z_b)).max() <= 1e-7 * np.abs(z_b).max()
    # Values outside the basis's span take the solve.
    off = np.exp(2j * np.pi * 7.3 * np.arange(boundary.size) / boundary.size)
    assert np.abs(sub.extend(off) - exact.extend(off)).max() <= 1e-7
    assert iterative.n_solves == before + 2


def test_refinement_on_iterative_solves_stops_at_their_accuracy(cap_problem):
    """Davidson steps cannot beat the interior solves' tolerance: refine stops there, spending no solve."""
    lap, interior, boundary, l_ii, p_ii = cap_problem
    coarse_solve = _coarse_solver(l_ii, p_ii)
    red = BoundaryReduction(lap, boundary,
                            interior_solver=lambda block, rows: TwoGridSolver(block, p_ii, coarse_solve, rtol=1e-6))
    assert red.solve_rtol == 1e-6
    area = sp.diags(np.isin(np.arange(lap.shape[0]), boundary).astype(np.complex128) * 1e-3).tocsr()
    sub = BoundarySubspace(red, area, [boundary], n_modes=6)
    first, info = sub.refine(1.0, absorb=True)
    floor = BoundarySubspace.SOLVE_FLOOR * red.solve_rtol
    assert info["boundary_residual"] <= floor or info["refine_steps"] == 12
    before = red.n_solves
    again, info = sub.refine(1.0)
    assert info["refine_steps"] == 0 and red.n_solves == before
    assert abs(again.energy - first.energy) <= 1e-12 * max(abs(first.energy), 1.0)


@pytest.mark.parametrize("workers", [1, 2, 3])
def test_the_same_solution_whatever_the_workers_and_the_row_order(cap_problem, workers):
    """Columns shared out among workers, and a caller's order, change no digit that matters."""
    _, interior, _, l_ii, p_ii = cap_problem
    b = np.random.default_rng(2).standard_normal((l_ii.shape[0], 7))
    exact = sla.spsolve(sp.csc_matrix(l_ii), b)
    order = np.random.default_rng(3).permutation(l_ii.shape[0])
    for kwargs in (dict(workers=workers), dict(workers=workers, order=order)):
        solver = TwoGridSolver(l_ii, p_ii, _coarse_solver(l_ii, p_ii), rtol=1e-10, **kwargs)
        x = solver.solve(b)
        assert np.linalg.norm(x - exact) <= 1e-8 * np.linalg.norm(exact)
        assert not solver.fell_back


def test_row_blocks_solve_to_the_tolerance_with_the_same_digits_on_any_number_of_cores(cap_problem, monkeypatch):
    """The sweeps shared out by rows (large problems) converge as the single sweep does, and
    the iterates depend on the block count only: 1, 2 or 3 workers give the same bits."""
    from parambench.methods.spectral import twogrid

    _, _, _, l_ii, p_ii = cap_problem
    monkeypatch.setattr(twogrid, "ROW_SPLIT_MIN_ROWS", 0)
    b = np.random.default_rng(9).standard_normal((l_ii.shape[0], 6))
    exact = sla.spsolve(sp.csc_matrix(l_ii), b)
    single = TwoGridSolver(l_ii, p_ii, _coarse_solver(l_ii, p_ii), rtol=1e-10, order=np.arange(l_ii.shape[0]))
    assert len(single._blocks) == 2 and single._halo_rows.size > 0
    solutions = []
    for workers in (1, 2, 3):
        solver = TwoGridSolver(l_ii, p_ii, _coarse_solver(l_ii, p_ii), rtol=1e-10, workers=workers,
                               order=np.arange(l_ii.shape[0]))
        solutions.append(solver.solve(b))
        assert np.linalg.norm(solutions[-1] - exact) <= 1e-8 * np.linalg.norm(exact)
        assert not solver.fell_back and solver.n_cycles <= 25
    for other in solutions[1:]:
        np.testing.assert_array_equal(other, solutions[0])


def test_an_order_that_is_not_a_permutation_is_refused(cap_problem):
    _, _, _, l_ii, p_ii = cap_problem
    with pytest.raises(ValueError, match="permutation"):
        TwoGridSolver(l_ii, p_ii, _coarse_solver(l_ii, p_ii), order=np.zeros(l_ii.shape[0], dtype=int))


def test_compiled_kernels_and_permutation_match_scipy(cap_problem):
    from parambench.methods.spectral.ordering import symmetric_permutation
    from parambench.methods.spectral.twogrid import _add_csr_product, _restricted_residual

    _, _, _, l_ii, p_ii = cap_problem
    p_ii = sp.csr_matrix(p_ii)
    rng = np.random.default_rng(4)
    # A worker's rows 100:700 of the residual, restricted; its rows of the prolongation.
    x, b = rng.standard_normal((l_ii.shape[0], 5)), rng.standard_normal((l_ii.shape[0], 5))
    rows = slice(100, 700)
    residual = b - l_ii @ x
    restricted, squares = np.empty((p_ii.shape[1], 5)), np.empty(5)
    _restricted_residual(l_ii.indptr[:-1], l_ii.indptr[1:], l_ii.indices, l_ii.data, b, x, 100, 700, p_ii.indptr, p_ii.indices,
                         p_ii.data, restricted, squares)
    expected = p_ii[rows].T @ residual[rows]
    np.testing.assert_allclose(restricted, expected, rtol=0, atol=1e-12 * np.abs(expected).max())
    np.testing.assert_allclose(np.sqrt(squares), np.linalg.norm(residual[rows], axis=0), rtol=1e-12)
    e = rng.standard_normal((p_ii.shape[1], 5))
    total = x.copy()
    _add_csr_product(p_ii.indptr, p_ii.indices, p_ii.data, e, total, 100, 700)
    want = x.copy()
    want[rows] += p_ii[rows] @ e
    np.testing.assert_allclose(total, want, rtol=0, atol=1e-12 * np.abs(want).max())
    order = rng.permutation(l_ii.shape[0])
    permuted = symmetric_permutation(l_ii, order)
    expected = sp.csr_matrix(l_ii[order][:, order])
    expected.sort_indices()
    assert permuted.has_sorted_indices
    np.testing.assert_array_equal(permuted.indptr, expected.indptr)
    np.testing.assert_array_equal(permuted.indices, expected.indices)
    np.testing.assert_array_equal(permuted.data, expected.data)


@pytest.mark.parametrize("backward", [False, True])
def test_a_block_s_sweep_uses_its_newest_rows_and_the_others_as_they_stood(backward):
    """One sweep over rows r0:r1 equals the textbook Gauss-Seidel step on those rows, with
    newest values inside the block and the snapshot (halo) values of the rows outside."""
    from parambench.methods.spectral.leading_block import as_leading_block
    from parambench.methods.spectral.twogrid import _gauss_seidel_rows, _row_blocks

    rng = np.random.default_rng(5)
    n = 40
    a = sp.random(n, n, density=0.15, random_state=6, format="csr")
    a = (a + a.T + sp.diags(np.full(n, 4.0 + n * 0.3))).tocsr()
    a.sort_indices()
    blocks, halo_rows, halo_slot = _row_blocks(as_leading_block(a), 2)
    assert blocks[0][0] == 0 and blocks[-1][1] == n and len(blocks) == 2
    r0, r1 = blocks[1]
    b = rng.standard_normal((n, 4))
    x = rng.standard_normal((n, 4))
    halo = x[halo_rows].copy()
    x[:r0] += 100.0  # the other block changed meanwhile: the sweep must not see it
    expected = x.copy()
    dense = a.toarray()
    stood = np.zeros_like(x)
    stood[halo_rows] = halo
    for i in (range(r1 - 1, r0 - 1, -1) if backward else range(r0, r1)):
        inside = dense[i, r0:r1] @ expected[r0:r1] - dense[i, i] * expected[i]
        outside = dense[i, :r0] @ stood[:r0] + dense[i, r1:] @ stood[r1:]
        expected[i] = (b[i] - inside - outside) / dense[i, i]
    assert np.any(dense[r0:r1, :r0] != 0)  # the test needs couplings across the blocks
    _gauss_seidel_rows(a.indptr[:-1], a.indptr[1:], a.indices, a.data, a.diagonal(), b, x, r0, r1, halo_slot, halo, backward)
    np.testing.assert_allclose(x, expected, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("identity", [True, False])
def test_overwrite_rhs_returns_the_solution_in_the_right_hand_sides_memory(cap_problem, identity):
    """With ``overwrite_rhs`` the solution comes back in rhs's own array (one block-sized
    array less at the peak), equal to the copying solve's; without, rhs is left alone.
    In the caller's order (multilevel's) a solve holds 2 arrays per column, 3 when it
    permutes the rows."""
    _, _, _, l_ii, p_ii = cap_problem
    coarse_solve = _coarse_solver(l_ii, p_ii)
    order = np.arange(l_ii.shape[0]) if identity else None
    assert TwoGridSolver(l_ii, p_ii, coarse_solve, order=order).arrays_per_column == (2 if identity else 3)
    b = np.random.default_rng(8).standard_normal((l_ii.shape[0], 5))
    kept = b.copy()
    copied = TwoGridSolver(l_ii, p_ii, coarse_solve, rtol=1e-10, workers=2, order=order).solve(b)
    np.testing.assert_array_equal(b, kept)
    rhs = b.copy()
    in_place = TwoGridSolver(l_ii, p_ii, coarse_solve, rtol=1e-10, workers=2, order=order).solve(rhs, overwrite_rhs=True)
    assert np.shares_memory(in_place, rhs)
    np.testing.assert_array_equal(in_place, copied)
    exact = sla.spsolve(sp.csc_matrix(l_ii), kept)
    assert np.abs(in_place - exact).max() <= 1e-8 * np.abs(exact).max()
    # A block it cannot write into (Fortran order) is copied, and left as it was.
    fortran = np.asfortranarray(kept)
    out = TwoGridSolver(l_ii, p_ii, coarse_solve, rtol=1e-10, workers=2, order=order).solve(fortran, overwrite_rhs=True)
    assert not np.shares_memory(out, fortran)
    np.testing.assert_array_equal(fortran, kept)
    np.testing.assert_array_equal(out, copied)


def test_a_warm_start_reaches_a_tighter_tolerance_in_fewer_cycles(cap_problem):
    _, _, _, l_ii, p_ii = cap_problem
    coarse_solve = _coarse_solver(l_ii, p_ii)
    b = np.random.default_rng(7).standard_normal((l_ii.shape[0], 2))
    exact = sla.spsolve(sp.csc_matrix(l_ii), b)
    loose = TwoGridSolver(l_ii, p_ii, coarse_solve, rtol=1e-5)
    x_loose = loose.solve(b)
    cold = TwoGridSolver(l_ii, p_ii, coarse_solve, rtol=1e-10)
    x_cold = cold.solve(b)
    loose.rtol = 1e-10
    before = loose.n_cycles
    x_warm = loose.solve(b, guess=x_loose)
    assert np.linalg.norm(x_loose - exact) > 1e-7 * np.linalg.norm(exact)  # the guess is not the answer
    assert np.linalg.norm(x_warm - exact) <= 1e-8 * np.linalg.norm(exact)
    assert np.linalg.norm(x_cold - exact) <= 1e-8 * np.linalg.norm(exact)
    assert 0 < loose.n_cycles - before < cold.n_cycles
    with pytest.raises(ValueError, match="shape"):
        loose.solve(b, guess=x_loose[:, :1])
    with pytest.raises(ValueError, match="real"):
        loose.solve(b + 1j * b, guess=x_loose)


def test_tightened_solves_make_a_subspace_s_products_exact(cap_problem):
    """resolve() solves the kept products again to the new tolerance, from their interior values."""
    lap, interior, boundary, l_ii, p_ii = cap_problem
    coarse_solve = _coarse_solver(l_ii, p_ii)
    red = BoundaryReduction(lap, boundary,
                            interior_solver=lambda block, rows: TwoGridSolver(block, p_ii, coarse_solve, rtol=1e-4))
    exact = BoundaryReduction(lap, boundary)
    area = sp.identity(lap.shape[0], format="csr", dtype=np.complex128)
    sub = BoundarySubspace(red, area, [boundary], n_modes=4)
    s_exact = exact.apply_schur(sub.basis)
    z_b = sub.basis @ np.linspace(1.0, 2.0, sub.size)

    def errors():
        ext = sub.extend(z_b.astype(np.complex128))
        return (np.abs(sub._sq - s_exact).max() / np.abs(s_exact).max(),
                np.abs(ext - exact.extend(z_b.astype(np.complex128))).max() / np.abs(z_b).max())

    loose_s, loose_ext = errors()
    assert loose_s > 1e-7 and loose_ext > 1e-7  # really loose
    assert not exact.tighten(1e-12)  # a factorisation is exact already
    assert not red.tighten(1e-3)  # never loosened
    assert red.tighten(1e-11) and red.solve_rtol == 1e-11
    cycles = red.interior_factor.n_cycles
    solves = sub.n_solves
    sub.resolve()
    tight_s, tight_ext = errors()
    assert tight_s <= 1e-8 and tight_ext <= 1e-8
    assert sub.n_solves == solves + sub.size and red.interior_factor.n_cycles > cycles


@pytest.mark.parametrize("count", [1, 2, 3])
def test_row_blocks_find_every_row_another_block_reads(count):
    """The halo from each row's first and last index equals the one from every entry's owner
    (empty rows and matrices included)."""
    from parambench.methods.spectral.leading_block import as_leading_block
    from parambench.methods.spectral.twogrid import _row_blocks

    for seed in range(60):
        n = 1 + seed % 45
        a = sp.random(n, n, density=0.02 + 0.3 * (seed % 7) / 7, random_state=seed, format="csr")
        a.sort_indices()
        blocks, halo_rows, halo_slot = _row_blocks(as_leading_block(a), count)
        edges = [lo for lo, _ in blocks] + [n]
        assert edges[0] == 0 and np.all(np.diff(edges) > 0)
        owner = np.repeat(np.arange(len(blocks)), np.diff(edges))
        rows = np.repeat(np.arange(n), np.diff(a.indptr))
        np.testing.assert_array_equal(halo_rows, np.unique(a.indices[owner[a.indices] != owner[rows]]))
        np.testing.assert_array_equal(halo_slot[halo_rows], np.arange(halo_rows.size))
