"""The Dirichlet eigen-solve (SDP, LEM, LLE) with single-precision factors refined to its tolerance."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as sla

import parambench.methods.spectral.sparse_eigen as sparse_eigen
from parambench.datasets_gen.registry import make_surface
from parambench.methods.base import StageTimer
from parambench.methods.pointset.plugin_support import FRONTEND_DEFAULTS, run_frontend
from parambench.methods.spectral.dirichlet import b_orthonormalize, smallest_nontrivial_pair
from parambench.methods.spectral.ordering import nested_dissection


def _sin_subspace_angle(a: np.ndarray, b: np.ndarray) -> float:
    """Sine of the largest principal angle between the spans of two centred column blocks.

    Taken as the norm of the part of one orthonormal basis outside the other span, which is
    accurate down to round-off (~1e-16). The form ``sqrt(1 - cos**2)`` cannot resolve angles
    below ``sqrt(2 eps)`` ~ 2e-8: a one-ulp change in ``cos`` moves it by that much.
    """
    qa, _ = np.linalg.qr(a - a.mean(axis=0))
    qb, _ = np.linalg.qr(b - b.mean(axis=0))
    return float(np.linalg.norm(qb - qa @ (qa.T @ qb), 2))


def _pair_gap_amplification(lap: sp.spmatrix, b_mat: sp.spmatrix, perm: np.ndarray) -> float:
    """How much a relative error of the shift-invert operator can turn the pair's span.

    The solver iterates on ``(L - sigma B)^{-1} B`` (constants deflated), whose eigenvalues
    are ``mu_i = 1 / (lambda_i - sigma)``. A relative operator error ``eps`` turns the
    invariant plane of ``mu_1, mu_2`` by at most ``eps |mu_2| / (|mu_2| - |mu_3|)`` to first
    order (the sin-theta bound, for a near-normal operator), that is by
    ``eps (lambda_3 - sigma) / (lambda_3 - lambda_2)``: the factor returned here.
    """
    n = lap.shape[0]
    # The solver's own shift (parambench.methods.spectral.dirichlet.smallest_nontrivial_pair).
    sigma = -1e-6 * (abs(lap).sum() / n) / (abs(b_mat).sum() / n)
    factor = sparse_eigen.SparseFactor((lap - sigma * b_mat).tocsc(), perm, precision="double")

    def op(x: np.ndarray) -> np.ndarray:
        y = factor.solve(b_mat @ (x - x.mean()))
        return y - y.mean()

    mu = sla.eigs(sla.LinearOperator((n, n), matvec=op, dtype=np.float64), k=3, ncv=20, which="LM", tol=1e-12,
                  v0=np.random.default_rng(0).standard_normal(n), return_eigenvectors=False)
    lam = np.sort(sigma + 1.0 / mu.real)
    return float((lam[2] - sigma) / (lam[2] - lam[1]))


def test_sdp_pair_from_a_mixed_precision_factor_matches_double(monkeypatch):
    # The SDP pencil of a point set: non-symmetric W^tan Laplacian, B the boundary
    # indicator, two near-equal smallest eigenvalues (a roughly symmetric bump).
    surface = make_surface("bump", 3000, sampling="jittered", seed=0).points_only()
    front = run_frontend(surface, dict(FRONTEND_DEFAULTS), StageTimer())
    lap = front.L.tocsc()
    b_diag = front.boundary_mask.astype(np.float64)
    b_mat = sp.diags(b_diag).tocsc()
    perm = nested_dissection(front.points, lap)

    vals_double, pair_double = smallest_nontrivial_pair(lap, b_mat, perm=perm)
    built = []
    original = sparse_eigen.SparseFactor

    def recording_factor(*args, **kwargs):
        factor = original(*args, **kwargs)
        built.append(factor)
        return factor

    monkeypatch.setattr(sparse_eigen, "MIXED_PRECISION_FROM", 0)
    monkeypatch.setattr("parambench.methods.spectral.dirichlet.SparseFactor", recording_factor)
    vals_mixed, pair_mixed = smallest_nontrivial_pair(lap, b_mat, perm=perm)

    assert built and built[0].mixed  # the single-precision path really ran
    # Both runs start ARPACK (tol = 1e-8) from the same vector; they differ only in the
    # solves, which the mixed factor refines to a residual below solve_rtol = 0.1 tol =
    # 1e-9 of the right-hand side: a backward error of at most solve_rtol relative to
    # L - sigma B, so each shift-invert product carries a relative error <= solve_rtol.
    # To first order that moves the eigenvalues by solve_rtol relative, and turns the
    # pair's span by at most solve_rtol times the gap amplification (about 2 here).
    # ARPACK's own 1e-8 does not enter: the two iterations follow the same Krylov path.
    # Measured on numpy 2.4.6 / scipy 1.17.1: 2e-12 (eigenvalues) and 3e-12 (angle) with
    # refinement; refined only to 1e-6: 1.2e-8 and 1.2e-8; to 1e-5: 5e-9 and 7e-9
    # (both fail here); 1e-2: 2e-5 and 2e-5.
    solve_rtol = 0.1 * 1e-8
    np.testing.assert_allclose(vals_mixed, vals_double, rtol=solve_rtol)
    # Only the span matters for SDP (the map is made B-orthonormal afterwards).
    bound = solve_rtol * _pair_gap_amplification(lap, b_mat, perm)
    assert _sin_subspace_angle(pair_mixed, pair_double) < bound
    uv_double = b_orthonormalize(pair_double, b_diag)
    uv_mixed = b_orthonormalize(pair_mixed, b_diag)
    # B-orthonormal bases of the same span differ by an orthogonal 2x2 matrix.
    rot, *_ = np.linalg.lstsq(uv_mixed, uv_double, rcond=None)
    np.testing.assert_allclose(rot.T @ rot, np.eye(2), atol=1e-8)
    assert np.abs(uv_mixed @ rot - uv_double).max() < 1e-8 * np.abs(uv_double).max()


def test_a_double_eigenvalue_in_complex_combinations_gives_its_plane():
    """ARPACK may return a double real eigenvalue's plane as v and conj(v): their real parts
    coincide, and sdp failed with "cannot make them B-orthonormal" (a 61 x 61 grid with a slit)."""
    from parambench.methods.spectral.dirichlet import real_pair

    rng = np.random.default_rng(0)
    e1, e2 = np.linalg.qr(rng.standard_normal((50, 2)))[0].T
    v = (e1 + 1j * e2) * np.exp(0.3j)
    vals, pair = real_pair(np.array([2.0 + 0j, 2.0 + 0j]), np.column_stack([v, np.conj(v)]))
    assert np.allclose(vals, [2.0, 2.0])
    # The two columns span exactly the plane of e1 and e2.
    basis = np.column_stack([e1, e2])
    assert np.allclose(basis @ (basis.T @ pair), pair, atol=1e-12)
    assert abs(np.linalg.det(basis.T @ pair)) > 0.5
    # Distinct real eigenvectors are left as they are.
    vals, pair = real_pair(np.array([1.0 + 0j, 2.0 + 0j]), np.column_stack([e1 + 0j, e2 + 0j]))
    assert np.allclose(pair, np.column_stack([e1, e2]))
