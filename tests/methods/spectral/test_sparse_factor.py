"""SparseFactor's mixed precision: single-precision factor, double-precision answers."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
import scipy.sparse as sp

from parambench.datasets_gen.errors import UnknownNameError
from parambench.methods.spectral.sparse_eigen import MIXED_PRECISION_FROM, SparseFactor


def _grid_laplacian(side: int, shift: float = 1e-3) -> sp.csc_matrix:
    one = sp.diags([-np.ones(side - 1), 2 * np.ones(side), -np.ones(side - 1)], [-1, 0, 1])
    eye = sp.identity(side)
    lap = sp.kron(one, eye) + sp.kron(eye, one)
    # A non-symmetric perturbation, as in the point-set Laplacians.
    skew = sp.kron(sp.diags([np.ones(side - 1), -np.ones(side - 1)], [-1, 1]), eye) * 0.1
    return sp.csc_matrix(lap + skew + shift * sp.identity(side * side))


def test_mixed_precision_solves_to_double_accuracy():
    a = _grid_laplacian(120)
    rhs = np.random.default_rng(0).standard_normal((a.shape[0], 3))
    exact = SparseFactor(a, precision="double").solve(rhs)
    mixed = SparseFactor(a, precision="mixed")
    assert mixed.mixed
    x = mixed.solve(rhs)
    assert np.linalg.norm(x - exact) <= 1e-10 * np.linalg.norm(exact)
    assert np.linalg.norm(a @ x - rhs) <= 1e-11 * np.linalg.norm(rhs)
    # Complex right-hand sides go through the real factor part by part.
    z = mixed.solve(rhs[:, 0] + 1j * rhs[:, 1])
    assert np.allclose(z, exact[:, 0] + 1j * exact[:, 1], rtol=0, atol=1e-10 * np.abs(exact).max())


def test_with_an_elimination_order_too():
    a = _grid_laplacian(60)
    perm = np.random.default_rng(1).permutation(a.shape[0])
    rhs = np.random.default_rng(2).standard_normal(a.shape[0])
    f = SparseFactor(a, perm, precision="mixed")
    x = f.solve(rhs)
    assert np.linalg.norm(a @ x - rhs) <= 1e-11 * np.linalg.norm(rhs)
    # Refinement steps are not counted as solves; a complex right-hand side is one.
    f.solve(rhs + 1j * rhs)
    assert f.n_solves == 2


def test_refinement_stops_at_the_requested_tolerance():
    a = _grid_laplacian(60)
    rhs = np.random.default_rng(3).standard_normal(a.shape[0])
    loose, tight = (SparseFactor(a, precision="mixed", refine_rtol=rtol) for rtol in (1e-6, 1e-13))
    r_loose = np.linalg.norm(a @ loose.solve(rhs) - rhs) / np.linalg.norm(rhs)
    r_tight = np.linalg.norm(a @ tight.solve(rhs) - rhs) / np.linalg.norm(rhs)
    assert r_loose <= 1e-6 and r_tight <= 1e-13
    assert r_tight < r_loose


def test_auto_keeps_double_precision_below_the_threshold_and_for_complex_matrices():
    a = _grid_laplacian(30)
    assert a.shape[0] < MIXED_PRECISION_FROM
    assert not SparseFactor(a).mixed
    assert not SparseFactor(sp.csc_matrix(a, dtype=np.complex128), precision="mixed").mixed


def test_too_ill_conditioned_for_single_precision_falls_back_to_double():
    # 1 - 1e-9 rounds to 1 in single precision: the float32 matrix is exactly singular.
    a = sp.csc_matrix(np.array([[1.0, 1.0 - 1e-9], [1.0, 1.0]]))
    f = SparseFactor(a, precision="mixed")
    x = f.solve(np.array([1.0, 2.0]))
    assert not f.mixed
    assert np.allclose(a @ x, [1.0, 2.0], rtol=1e-6)


def test_unknown_precision_is_refused():
    with pytest.raises(UnknownNameError, match="precision"):
        SparseFactor(_grid_laplacian(5), precision="half")


@pytest.mark.parametrize("precision", ["double", "mixed"])
@pytest.mark.parametrize("ordered", [False, True])
@pytest.mark.parametrize("kind", ["real", "complex"])
def test_many_right_hand_sides_are_shared_out_among_threads_and_solved_exactly(monkeypatch, precision,
                                                                               ordered, kind):
    """A block of 37 right-hand sides, split by columns over two threads, gives each
    column the solution of a one-column solve (to rounding: SuperLU's supernodal kernels
    sum in another order for a block), in the caller's order, in the factors' type (real
    or complex) and, in mixed precision, to double accuracy."""
    from parambench.methods.spectral import sparse_eigen

    if kind == "complex" and precision == "mixed":
        pytest.skip("mixed precision is for real matrices")
    monkeypatch.setattr(sparse_eigen, "solver_threads", lambda: 2)
    a = _grid_laplacian(40)
    if kind == "complex":
        a = sp.csc_matrix(a + 0.3j * sp.identity(a.shape[0]))
    perm = np.random.default_rng(1).permutation(a.shape[0]) if ordered else None
    factor = SparseFactor(a, perm=perm, precision=precision)
    rng = np.random.default_rng(2)
    rhs = rng.standard_normal((a.shape[0], 37))
    if kind == "complex":
        rhs = rhs + 1j * rng.standard_normal(rhs.shape)
    calls = []
    original = factor._lu.solve

    class Spy:  # SuperLU objects' attributes are read-only: wrap the factor instead
        def solve(self, b):
            calls.append(b.shape[1] if b.ndim == 2 else 1)
            return original(b)

    factor._lu = Spy()
    block = factor.solve(rhs)
    assert len(calls) >= 4 and sum(calls) >= 37  # shared out in chunks (plus refinement steps)
    one_by_one = np.column_stack([factor.solve(rhs[:, j]) for j in range(rhs.shape[1])])
    assert block.dtype == one_by_one.dtype == (np.complex128 if kind == "complex" else np.float64)
    if precision == "double":
        np.testing.assert_allclose(block, one_by_one, rtol=0, atol=1e-13 * np.abs(one_by_one).max())
    # Under two chunks of 8 per thread the block stays whole: the chunk copies solved at
    # once would exceed half the block.
    calls.clear()
    factor.solve(rhs[:, :31])
    assert calls[0] == 31
    # From a worker thread (a two-grid cycle's coarse correction) the block stays whole.
    calls.clear()
    with ThreadPoolExecutor(max_workers=1) as pool:
        pool.submit(factor.solve, rhs).result()
    assert calls[0] == 37
    assert np.linalg.norm(a @ block - rhs) <= 1e-10 * np.linalg.norm(rhs)
