"""The compiled per-point fits of the normals stage (methods/pointset/local_fits.py) against numpy/LAPACK."""

from __future__ import annotations

import numpy as np
import pytest

from parambench.methods.pointset.local_fits import linear_smooth_rows, pca_rows, sym3_eigen
from parambench.methods.pointset.normals import smooth_normals, tangent_frames


def _eigen(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    vals, vecs = np.empty(3), np.empty((3, 3))
    sym3_eigen(a[0, 0], a[0, 1], a[0, 2], a[1, 1], a[1, 2], a[2, 2], vals, vecs)
    return vals, vecs


def _symmetric_cases(rng):
    yield np.zeros((3, 3))
    yield np.diag([3.0, 1.0, 2.0])  # already diagonal, unsorted
    yield np.diag([1.0, 1.0, 1.0])
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    yield q @ np.diag([1e-18, 1.0, 1.0]) @ q.T  # a plane: repeated large eigenvalues, a ~0 one
    yield q @ np.diag([2.0, 2.0, 5.0]) @ q.T
    yield 1e-12 * (q @ np.diag([1e-6, 0.3, 1.0]) @ q.T)  # tiny units
    for _ in range(200):
        x = rng.normal(size=(9, 3)) * rng.uniform(0.01, 10.0, size=3)
        x -= x.mean(axis=0)
        yield x.T @ x


def test_jacobi_matches_lapack_on_symmetric_3x3():
    rng = np.random.default_rng(11)
    for a in _symmetric_cases(rng):
        vals, vecs = _eigen(a)
        want = np.linalg.eigvalsh(a)
        scale = max(np.abs(want).max(), np.finfo(float).tiny)
        assert np.all(np.diff(vals) >= 0)
        np.testing.assert_allclose(vals, want, rtol=0, atol=1e-14 * scale)
        np.testing.assert_allclose(vecs.T @ vecs, np.eye(3), atol=1e-14)
        np.testing.assert_allclose(a @ vecs, vecs * vals, rtol=0, atol=1e-14 * scale)


def _pca_reference(points, nbh, valid):
    """The numpy formulation the kernel replaced: centre included, masked neighbours, LAPACK eigh."""
    w = np.concatenate([np.ones((len(nbh), 1)), valid.astype(float)], axis=1)
    pts = np.concatenate([points[:len(nbh), None, :], points[nbh]], axis=1)
    centre = np.einsum("nk,nki->ni", w, pts) / w.sum(axis=1)[:, None]
    d = (pts - centre[:, None, :]) * np.sqrt(w)[:, :, None]
    vals, vecs = np.linalg.eigh(np.einsum("nki,nkj->nij", d, d))
    return vecs[:, :, 0], np.maximum(vals, 0.0)


@pytest.mark.parametrize("masked", [False, True])
def test_pca_rows_match_the_lapack_fit(masked):
    rng = np.random.default_rng(5)
    n, k = 300, 10
    uv = rng.uniform(-1, 1, size=(n, 2))
    points = np.c_[uv, 0.3 * uv[:, 0] ** 2 - 0.2 * uv[:, 1] ** 2 + 0.01 * rng.normal(size=n)]
    nbh = np.argsort(((points[:, None] - points[None]) ** 2).sum(-1), axis=1)[:, 1:k + 1]
    valid = rng.random((n, k)) < 0.7 if masked else np.ones((n, k), dtype=bool)
    valid[:, :3] = True
    normals, lam = np.empty((n, 3)), np.empty((n, 3))
    pca_rows(points, nbh, valid, 0, 150, normals, lam)
    pca_rows(points, nbh, valid, 150, n, normals, lam)  # rows split among calls: the same rows
    want_n, want_lam = _pca_reference(points, nbh, valid)
    np.testing.assert_allclose(np.abs(np.einsum("ij,ij->i", normals, want_n)), 1.0, rtol=0, atol=1e-13)
    np.testing.assert_allclose(lam, want_lam, rtol=0, atol=1e-13 * want_lam[:, 2:].max())


def _smooth_reference(points, normals, knn, dist, spacing):
    """Weighted local-linear least squares by numpy's batched solve (the formulation the kernel replaced)."""
    w = 1.0 / (dist + 1e-4 * spacing)
    e1, e2 = tangent_frames(normals)
    d = points[knn] - points[:, None, :]
    x = np.stack([np.ones(knn.shape), np.einsum("nki,ni->nk", d, e1), np.einsum("nki,ni->nk", d, e2)], axis=-1)
    lhs = np.einsum("nk,nki,nkj->nij", w, x, x)
    lhs = lhs + 1e-9 * np.einsum("nii->n", lhs)[:, None, None] * np.diag([0.0, 1.0, 1.0])
    rhs = np.einsum("nk,nki,nkj->nij", w, x, normals[knn])
    avg = np.linalg.solve(lhs, rhs)[:, 0, :]
    return avg / np.linalg.norm(avg, axis=1, keepdims=True)


def test_linear_smoothing_matches_the_least_squares_fit():
    rng = np.random.default_rng(8)
    n, k = 400, 8
    uv = rng.uniform(-1, 1, size=(n, 2))
    points = np.c_[uv, 0.5 * uv[:, 0] * uv[:, 1]]
    normals = np.c_[-0.5 * uv[:, 1], -0.5 * uv[:, 0], np.ones(n)] + 0.05 * rng.normal(size=(n, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    d2 = ((points[:, None] - points[None]) ** 2).sum(-1)
    knn = np.argsort(d2, axis=1)[:, 1:k + 1]
    dist = np.sqrt(np.take_along_axis(d2, knn, axis=1))
    spacing = float(dist[:, 0].mean())
    got = smooth_normals(points, normals, knn, dist, spacing)
    np.testing.assert_allclose(got, _smooth_reference(points, normals, knn, dist, spacing), rtol=0, atol=1e-12)
    # Collinear neighbours: the ridge keeps the fit solvable, the intercept near the plain average.
    line = np.c_[np.linspace(0, 1, 9), np.zeros(9), np.zeros(9)]
    flat = np.tile([0.0, 0.0, 1.0], (9, 1))
    nb = np.array([[j for j in range(9) if j != i][:4] for i in range(9)])
    out = np.empty((9, 3))
    e1, e2 = tangent_frames(flat)
    linear_smooth_rows(line, flat, e1, e2, nb, np.ones((9, 4)), 1e-9, 0, 9, out)
    np.testing.assert_allclose(out / np.linalg.norm(out, axis=1, keepdims=True), flat, atol=1e-9)


def _moment_reference(t, m, n_con, width, reg):
    """The batched numpy/LAPACK formulation the kernel replaced."""
    tx, ty = t[..., 0], t[..., 1]
    rows = [m.astype(float), tx, ty] + ([tx * tx - ty * ty, 2.0 * tx * ty] if n_con == 5 else [])
    a = np.stack(rows, axis=1)
    r2 = (t ** 2).sum(-1)
    om = np.exp(-r2 / (width * np.maximum(r2.max(axis=1, keepdims=True), np.finfo(float).tiny))) * m
    aoa = np.einsum("ncb,nb,ndb->ncd", a, om, a)
    aoa += reg * np.trace(aoa, axis1=1, axis2=2)[:, None, None] * np.eye(n_con)
    rhs = np.zeros((a.shape[0], n_con, 1))
    rhs[:, 0, 0] = 1.0
    lam = np.linalg.solve(aoa, rhs)[..., 0]
    w = om * np.einsum("ncb,nc->nb", a, lam)
    return w / w.sum(axis=1, keepdims=True)


@pytest.mark.parametrize("n_con", [3, 5])
def test_moment_weights_match_the_batched_solve_and_keep_their_moments(n_con):
    from parambench.methods.pointset.neumann_laplacian import moment_weights

    rng = np.random.default_rng(2)
    n, b = 200, 24
    t = rng.uniform(-1, 1, size=(n, b, 2)) * rng.uniform(0.1, 3.0, size=(n, 1, 1))
    m = np.ones((n, b), dtype=bool)
    m[:, 12:] = rng.random((n, b - 12)) < 0.5  # ragged balls, padding zeroed
    t[~m] = 0.0
    t[0, :, 1] = 0.0  # a collinear ball: the regularisation keeps it solvable
    order = "quadratic" if n_con == 5 else "linear"
    w = moment_weights(t, m, order)
    np.testing.assert_allclose(w, _moment_reference(t, m, n_con, 0.5, 1e-10), rtol=0, atol=1e-11)
    assert (w[~m] == 0).all()
    np.testing.assert_allclose(w.sum(axis=1), 1.0, atol=1e-12)
    ok = slice(1, None)  # the prescribed moments vanish, up to the 1e-10 regularisation (the collinear ball not at all)
    np.testing.assert_allclose(np.einsum("nb,nbi->ni", w[ok], t[ok]), 0.0, atol=1e-7)
    if n_con == 5:
        tx, ty = t[ok, :, 0], t[ok, :, 1]
        np.testing.assert_allclose((w[ok] * (tx * tx - ty * ty)).sum(1), 0.0, atol=1e-7)
        np.testing.assert_allclose((w[ok] * tx * ty).sum(1), 0.0, atol=1e-7)
