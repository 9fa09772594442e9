"""The boundary reduction's Schur complement from the trailing block of one LU."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

import parambench.methods.spectral.reduction as reduction
from parambench.methods.spectral.ordering import nested_dissection, nested_dissection_with_root
from parambench.datasets_gen.registry import make_surface
from parambench.methods.spectral.reduction import BoundaryReduction


def _reductions(case, kind, monkeypatch):
    lap = case.lap if kind == "cotangent" else case.weights_laplacian(kind)
    keep = np.concatenate(case.loops)
    interior = np.setdiff1d(np.arange(lap.shape[0]), keep)
    perm = nested_dissection(case.points[interior], sp.csr_matrix(lap)[interior][:, interior])
    trailing = BoundaryReduction(lap, keep, perm)
    with monkeypatch.context() as patch:
        patch.setattr(reduction, "TRAILING_SCHUR_MAX", 0)
        solves = BoundaryReduction(lap, keep, perm)
    return trailing, solves


@pytest.mark.parametrize("kind", ["cotangent", "mean-value"])  # symmetric and not
def test_trailing_block_gives_the_same_schur_complement_and_extensions(holes, kind, monkeypatch):
    trailing, solves = _reductions(holes, kind, monkeypatch)
    s_ref = solves.schur
    assert trailing.schur is not None and trailing._trailing is not None and solves._trailing is None
    assert trailing._factor is None  # S and extensions need no interior factorisation
    scale = np.abs(s_ref).max()
    np.testing.assert_allclose(trailing.schur, s_ref, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(trailing.schur.sum(axis=1), 0.0, atol=1e-10 * scale)  # L's zero row sums survive
    x = np.random.default_rng(0).standard_normal((trailing.keep.size, 3))
    sx, interior = trailing.apply_schur_extended(x)
    sx_ref, interior_ref = solves.apply_schur_extended(x)
    np.testing.assert_allclose(sx, sx_ref, rtol=0, atol=1e-11 * np.abs(sx_ref).max())
    np.testing.assert_allclose(interior, interior_ref, rtol=0, atol=1e-11 * np.abs(interior_ref).max())
    z = x[:, 0] + 1j * x[:, 1]
    full = trailing.extend(z)
    np.testing.assert_allclose(full, solves.extend(z), rtol=0, atol=1e-11 * np.abs(full).max())
    # The extension is harmonic: the interior rows of L z vanish.
    rows = np.asarray(sp.csr_matrix(holes.lap if kind == "cotangent" else holes.weights_laplacian(kind)) @ full)
    assert np.abs(rows[trailing.interior]).max() <= 1e-10 * np.abs(rows[trailing.keep]).max()
    # The interior factor is still there for whoever needs it (the two-grid coarse level).
    b = np.random.default_rng(1).standard_normal(trailing.interior.size)
    np.testing.assert_allclose(trailing.interior_factor.solve(b), solves.interior_factor.solve(b), rtol=1e-9)


def test_extensions_without_s_use_the_interior_factor_only(holes):
    """The subspace search extends a few columns and never asks for S: no whole-matrix LU
    with its dense trailing block then."""
    keep = np.concatenate(holes.loops)
    interior = np.setdiff1d(np.arange(holes.lap.shape[0]), keep)
    red = BoundaryReduction(holes.lap, keep, nested_dissection(holes.points[interior], holes.lap[interior][:, interior]))
    sx, _ = red.apply_schur_extended(np.eye(keep.size)[:, :4])
    assert red._trailing is None and red._factor is not None
    np.testing.assert_allclose(sx, red.schur[:, :4], rtol=0, atol=1e-12 * np.abs(sx).max())


@pytest.fixture(scope="module")
def point_laplacians():
    """ocp's Laplacians (W^tan, 27-30 nonzeros per row) of bare points, with their loops."""
    from parambench.methods.plugins.ocp import ocp_laplacian
    from parambench.methods.pointset.frontend import build_frontend

    out = {}
    for name in ("bump", "holes"):
        front = build_frontend(make_surface(name, 3000, sampling="jittered", seed=0).points)
        lap = ocp_laplacian(front)
        out[name] = (sp.csr_matrix(lap[0] if isinstance(lap, tuple) else lap), front.points, front.boundary_loops)
    return out


@pytest.mark.parametrize("name,from_lu", [("bump", True), ("holes", False)])
def test_products_come_from_the_whole_matrix_lu_when_the_boundary_is_short(point_laplacians, name, from_lu,
                                                                           monkeypatch):
    """bump: one loop of 200 points around 2962, K / s = 1.3 for the interior ordering's
    root separator s: the subspace search's products are matmuls with S from the trailing
    block, never interior solves. holes: four loops, 324 points against s = 113 (2.9):
    interior solves. Either way products and extensions agree with interior solves'."""
    lap, points, loops = point_laplacians[name]
    keep = np.concatenate(loops)
    interior = np.setdiff1d(np.arange(lap.shape[0]), keep)
    perm, root = nested_dissection_with_root(points[interior], lap[interior][:, interior])
    assert (keep.size <= reduction.TRAILING_PRODUCTS_PER_SEPARATOR * root) == from_lu
    red = BoundaryReduction(lap, keep, perm, root_separator=root)
    with monkeypatch.context() as patch:
        patch.setattr(reduction, "TRAILING_PRODUCTS_MAX", 0)
        patch.setattr(reduction, "TRAILING_SCHUR_MAX", 0)
        ref = BoundaryReduction(lap, keep, perm, root_separator=root)
    x = np.random.default_rng(2).standard_normal((keep.size, 5))
    sx = red.apply_schur(x)
    assert (red._trailing is not None) == from_lu and (red._factor is None) == from_lu
    sx_ref = ref.apply_schur(x)
    assert ref._trailing is None and ref._factor is not None
    np.testing.assert_allclose(sx, sx_ref, rtol=0, atol=1e-11 * np.abs(sx_ref).max())
    z = x[:, 0] + 1j * x[:, 1]
    np.testing.assert_allclose(red.extend(z), ref.extend(z), rtol=0, atol=1e-10 * np.abs(z).max())


def test_root_separator_is_the_end_of_the_permutation(saddle):
    """The root separator splits the rest: no edge of the graph joins the vertices ordered
    before it on the two sides of the first split."""
    perm, root = nested_dissection_with_root(saddle.points, saddle.lap)
    assert 0 < root < perm.size // 4
    np.testing.assert_array_equal(perm, nested_dissection(saddle.points, saddle.lap))
    rest = perm[:-root]
    pattern = (abs(saddle.lap) > 0).astype(np.int8).tocsr()[rest][:, rest]
    n_components, _ = connected_components(pattern, directed=False)
    assert n_components >= 2


def test_pivoting_across_the_blocks_falls_back_to_interior_solves():
    """A zero interior diagonal whose column is largest in a kept row: SuperLU swaps that
    row into the interior block, so the trailing block is not S; the interior solves give
    S = 3 - [5 0] [[0 1] [1 2]]^-1 [5 0]^T = 53."""
    lap = sp.csr_matrix(np.array([[0.0, 1.0, 5.0], [1.0, 2.0, 0.0], [5.0, 0.0, 3.0]]))
    red = BoundaryReduction(lap, np.array([2]), np.array([0, 1]))
    np.testing.assert_allclose(red.schur, [[53.0]])
    assert red._trailing is None


def test_pencil_k_estimates_on_a_numerically_singular_s_keep_the_true_ones_without_a_warning():
    """A range scan's S/2 had rcond ~1e-18: scipy warned on every k search (four lines on the
    user's terminal). The estimates come from the pencil without an inverse then."""
    import warnings

    from parambench.methods.spectral.reduction import pencil_k_estimates

    q, _ = np.linalg.qr(np.random.default_rng(1).standard_normal((6, 6)))
    s_half = q @ np.diag([1.0, 2.0, 3.0, 1.5, 1.0, 1e-19]) @ q.T
    m = (q @ np.diag([2.0, 5.0, 7.0, 3.0, 4.0, 0.0]) @ q.T).astype(np.complex128)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        found = pencil_k_estimates(s_half, m)
    assert np.isfinite(found).all() and (found > 0).all()
    for mu in (2.0, 2.5, 7.0 / 3.0, 4.0):  # m_i / d_i of the regular directions
        assert np.abs(found - mu).min() < 1e-8 * mu
