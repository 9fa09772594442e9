"""The Dirichlet eigen-solve (SDP, LEM, LLE) with single-precision factors refined to its tolerance."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

import methods.spectral.sparse_eigen as sparse_eigen
from datasets_gen.registry import make_surface
from methods.base import StageTimer
from methods.pointset.plugin_support import FRONTEND_DEFAULTS, run_frontend
from methods.spectral.dirichlet import b_orthonormalize, smallest_nontrivial_pair
from methods.spectral.ordering import nested_dissection


def _sin_subspace_angle(a: np.ndarray, b: np.ndarray) -> float:
    qa, _ = np.linalg.qr(a - a.mean(axis=0))
    qb, _ = np.linalg.qr(b - b.mean(axis=0))
    cos = np.linalg.svd(qa.T @ qb, compute_uv=False).min()
    return float(np.sqrt(max(0.0, 1.0 - cos**2)))


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
    monkeypatch.setattr("methods.spectral.dirichlet.SparseFactor", recording_factor)
    vals_mixed, pair_mixed = smallest_nontrivial_pair(lap, b_mat, perm=perm)

    assert built and built[0].mixed  # the single-precision path really ran
    # Measured: 5e-12 relative with refinement to a tenth of ARPACK's tolerance, 3e-9
    # refined only to 1e-4, 2e-5 with no refinement.
    np.testing.assert_allclose(vals_mixed, vals_double, rtol=1e-9)
    # Only the span matters for SDP (the map is made B-orthonormal afterwards).
    assert _sin_subspace_angle(pair_mixed, pair_double) < 1e-8
    uv_double = b_orthonormalize(pair_double, b_diag)
    uv_mixed = b_orthonormalize(pair_mixed, b_diag)
    # B-orthonormal bases of the same span differ by an orthogonal 2x2 matrix.
    rot, *_ = np.linalg.lstsq(uv_mixed, uv_double, rcond=None)
    np.testing.assert_allclose(rot.T @ rot, np.eye(2), atol=1e-8)
    assert np.abs(uv_mixed @ rot - uv_double).max() < 1e-8 * np.abs(uv_double).max()
