"""Compiled per-point small fits: PCA plane fits, normal smoothing, moment and LLE weights.

At a million points numpy's batched ``eigh`` and ``solve`` on 3x3 to 5x5 matrices cost
about 2 microseconds per matrix in LAPACK call overhead (the normals stage's PCA fit
1.6-1.7 s and smoothing 1.4-1.9 s, the Laplacian's moment weights 3.1 s, on two cores);
these kernels do the same arithmetic per row in a few hundred nanoseconds: the PCA fit
0.21-0.42 s at a million points (bump, plane, noisy random cap). The scatter matrix's eigen-decomposition is cyclic Jacobi, as accurate as LAPACK's
on symmetric 3x3 matrices (normals within 4.4e-16 of ``|n . n_lapack| = 1``, eigenvalues
within 2.7e-15 of the largest; tested against numpy).

Every kernel writes rows ``lo:hi`` of its outputs only, so callers share rows out among
threads (:func:`parambench.methods.pointset.row_chunks.for_each_chunk`).
"""

from __future__ import annotations

from pathlib import Path

import numba
import numpy as np

from ..numba_cache import configure_numba_cache

__all__ = ["sym3_eigen", "pca_rows", "linear_smooth_rows", "solve_small", "solve_first_unit", "moment_rows", "lle_rows"]

_CACHE, _ = configure_numba_cache(Path(__file__).resolve().parent)

#: Jacobi sweeps stop when the off-diagonal mass is below this share of the diagonal's
#: (squared norms: 1e-16 relative, the rounding level of the entries).
_JACOBI_TOL = 1e-32

#: Upper bound on sweeps (3x3 converges quadratically, in 4-6).
_JACOBI_SWEEPS = 50


@numba.njit(cache=_CACHE, nogil=True)
def _rotate(a, v, p, q):
    """One Jacobi rotation zeroing ``a[p, q]`` of the symmetric 3x3 ``a``, accumulated into ``v``."""
    apq = a[p, q]
    if apq == 0.0:
        return
    theta = (a[q, q] - a[p, p]) / (2.0 * apq)
    t = 1.0 / (abs(theta) + np.sqrt(theta * theta + 1.0))
    if theta < 0.0:
        t = -t
    c = 1.0 / np.sqrt(t * t + 1.0)
    s = t * c
    tau = s / (1.0 + c)
    a[p, p] -= t * apq
    a[q, q] += t * apq
    a[p, q] = 0.0
    a[q, p] = 0.0
    r = 3 - p - q  # the third index
    arp = a[r, p]
    arq = a[r, q]
    a[r, p] = a[p, r] = arp - s * (arq + tau * arp)
    a[r, q] = a[q, r] = arq + s * (arp - tau * arq)
    for k in range(3):
        vkp = v[k, p]
        vkq = v[k, q]
        v[k, p] = vkp - s * (vkq + tau * vkp)
        v[k, q] = vkq + s * (vkp - tau * vkq)


@numba.njit(cache=_CACHE, nogil=True)
def sym3_eigen(a00, a01, a02, a11, a12, a22, vals, vecs):
    """Eigen-decomposition of a symmetric 3x3 matrix by cyclic Jacobi rotations.

    Parameters
    ----------
    a00, a01, a02, a11, a12, a22 : float
        The upper triangle.
    vals : (3,) numpy.ndarray of float64
        Out: eigenvalues, ascending.
    vecs : (3, 3) numpy.ndarray of float64
        Out: ``vecs[:, i]`` the unit eigenvector of ``vals[i]`` (orthonormal columns).
    """
    a = np.empty((3, 3))
    a[0, 0] = a00
    a[0, 1] = a[1, 0] = a01
    a[0, 2] = a[2, 0] = a02
    a[1, 1] = a11
    a[1, 2] = a[2, 1] = a12
    a[2, 2] = a22
    v = np.eye(3)
    for _ in range(_JACOBI_SWEEPS):
        off = a[0, 1] * a[0, 1] + a[0, 2] * a[0, 2] + a[1, 2] * a[1, 2]
        if off == 0.0 or off <= _JACOBI_TOL * (a[0, 0] * a[0, 0] + a[1, 1] * a[1, 1] + a[2, 2] * a[2, 2]):
            break
        _rotate(a, v, 0, 1)
        _rotate(a, v, 0, 2)
        _rotate(a, v, 1, 2)
    # Sort the three diagonal entries ascending, carrying their columns.
    order = np.array([0, 1, 2])
    for i in range(1, 3):
        j = i
        while j > 0 and a[order[j - 1], order[j - 1]] > a[order[j], order[j]]:
            order[j - 1], order[j] = order[j], order[j - 1]
            j -= 1
    for i in range(3):
        vals[i] = a[order[i], order[i]]
        for k in range(3):
            vecs[k, i] = v[k, order[i]]


@numba.njit(cache=_CACHE, nogil=True)
def pca_rows(points, nbh, valid, lo, hi, normals, lam):
    """PCA plane fit of rows lo:hi: point i with its ``valid`` neighbours ``nbh[i]``.

    Writes the unit eigenvector of the smallest eigenvalue of the scatter matrix (sums
    about the neighbourhood's mean) to ``normals[i]`` and the eigenvalues, ascending and
    clipped at 0, to ``lam[i]``.
    """
    k_max = nbh.shape[1]
    vals = np.empty(3)
    vecs = np.empty((3, 3))
    for i in range(lo, hi):
        cx, cy, cz = points[i, 0], points[i, 1], points[i, 2]
        count = 1.0
        for j in range(k_max):
            if valid[i, j]:
                q = nbh[i, j]
                cx += points[q, 0]
                cy += points[q, 1]
                cz += points[q, 2]
                count += 1.0
        cx /= count
        cy /= count
        cz /= count
        dx, dy, dz = points[i, 0] - cx, points[i, 1] - cy, points[i, 2] - cz
        s00, s01, s02, s11, s12, s22 = dx * dx, dx * dy, dx * dz, dy * dy, dy * dz, dz * dz
        for j in range(k_max):
            if valid[i, j]:
                q = nbh[i, j]
                dx, dy, dz = points[q, 0] - cx, points[q, 1] - cy, points[q, 2] - cz
                s00 += dx * dx
                s01 += dx * dy
                s02 += dx * dz
                s11 += dy * dy
                s12 += dy * dz
                s22 += dz * dz
        sym3_eigen(s00, s01, s02, s11, s12, s22, vals, vecs)
        norm = np.sqrt(vecs[0, 0] * vecs[0, 0] + vecs[1, 0] * vecs[1, 0] + vecs[2, 0] * vecs[2, 0])
        for c in range(3):
            normals[i, c] = vecs[c, 0] / norm
            lam[i, c] = max(vals[c], 0.0)


@numba.njit(cache=_CACHE, nogil=True)
def solve_small(m, b, size, out):
    """``out[:size]`` = the solution y of ``m y = b`` on the leading ``size`` x ``size`` block
    of ``m`` (``m`` and ``b`` destroyed), by Gaussian elimination with partial pivoting."""
    for col in range(size):
        piv = col
        for r in range(col + 1, size):
            if abs(m[r, col]) > abs(m[piv, col]):
                piv = r
        if piv != col:
            for c in range(size):
                m[col, c], m[piv, c] = m[piv, c], m[col, c]
            b[col], b[piv] = b[piv], b[col]
        for r in range(col + 1, size):
            f = m[r, col] / m[col, col]
            for c in range(col, size):
                m[r, c] -= f * m[col, c]
            b[r] -= f * b[col]
    for r in range(size - 1, -1, -1):
        acc = b[r]
        for c in range(r + 1, size):
            acc -= m[r, c] * out[c]
        out[r] = acc / m[r, r]


@numba.njit(cache=_CACHE, nogil=True)
def solve_first_unit(m, size, out):
    """``out[:size]`` = the solution y of ``m y = e_0`` (:func:`solve_small`); for a
    symmetric ``m`` this is also row 0 of its inverse."""
    b = np.zeros(size)
    b[0] = 1.0
    solve_small(m, b, size, out)


@numba.njit(cache=_CACHE, nogil=True)
def lle_rows(offsets, mask, reg_eps, lo, hi, out):
    """Regularised LLE weights of rows lo:hi in Woodbury form (see
    :func:`parambench.methods.pointset.tangent_weights.lle_weights`) into ``out``.

    Per row, with member offsets ``x_b`` (d = 2 or 3 columns) and Gram matrix
    ``G = sum_b x_b x_b^T``: ``y = (G + reg_eps trace(G) I)^{-1} sum_b x_b`` and
    ``w_b = 1 - x_b . y``, scaled to sum to 1; padding gets 0. Returns the first row whose
    members all sit on the centre (trace 0: no weights exist), or -1.
    """
    n_b = offsets.shape[1]
    d = offsets.shape[2]
    g = np.empty((3, 3))
    rhs = np.empty(3)
    y = np.empty(3)
    for i in range(lo, hi):
        for p in range(d):
            rhs[p] = 0.0
            for q in range(d):
                g[p, q] = 0.0
        for b in range(n_b):
            if mask[i, b]:
                for p in range(d):
                    xp = offsets[i, b, p]
                    rhs[p] += xp
                    for q in range(d):
                        g[p, q] += xp * offsets[i, b, q]
        trace = 0.0
        for p in range(d):
            trace += g[p, p]
        lam = reg_eps * trace
        if not lam > 0.0:
            return i
        for p in range(d):
            g[p, p] += lam
        solve_small(g, rhs, d, y)
        total = 0.0
        for b in range(n_b):
            if mask[i, b]:
                w = 1.0
                for p in range(d):
                    w -= offsets[i, b, p] * y[p]
                out[i, b] = w
                total += w
            else:
                out[i, b] = 0.0
        for b in range(n_b):
            out[i, b] /= total
    return -1


@numba.njit(cache=_CACHE, nogil=True)
def moment_rows(t, mask, n_con, width, reg, lo, hi, out):
    """Minimum-norm moment weights of rows lo:hi (see
    :func:`parambench.methods.pointset.neumann_laplacian.moment_weights`) into ``out``.

    Per row, with Gaussian ``omega_b = exp(-r_b^2 / (width h^2))`` (``h^2`` the row's
    largest squared radius) at members and moment rows ``a_b = (1, t_x, t_y)`` and, for
    ``n_con = 5``, ``(t_x^2 - t_y^2, 2 t_x t_y)``: ``w = Omega A^T (A Omega A^T + reg
    trace I)^{-1} e_1``, scaled to sum to 1. Padding (``mask`` False) gets 0.
    """
    b_max = t.shape[1]
    aoa = np.empty((5, 5))
    lam = np.empty(5)
    a = np.empty((b_max, 5))
    om = np.empty(b_max)
    tiny = np.finfo(np.float64).tiny
    for i in range(lo, hi):
        h2 = 0.0
        for b in range(b_max):
            r2 = t[i, b, 0] * t[i, b, 0] + t[i, b, 1] * t[i, b, 1]
            if r2 > h2:
                h2 = r2
        h2 = max(h2, tiny)
        for r in range(n_con):
            for c in range(n_con):
                aoa[r, c] = 0.0
        for b in range(b_max):
            if not mask[i, b]:
                om[b] = 0.0
                continue
            tx = t[i, b, 0]
            ty = t[i, b, 1]
            om[b] = np.exp(-(tx * tx + ty * ty) / (width * h2))
            a[b, 0] = 1.0
            a[b, 1] = tx
            a[b, 2] = ty
            if n_con == 5:
                a[b, 3] = tx * tx - ty * ty
                a[b, 4] = 2.0 * tx * ty
            for r in range(n_con):
                f = a[b, r] * om[b]
                for c in range(n_con):
                    aoa[r, c] += f * a[b, c]
        trace = 0.0
        for r in range(n_con):
            trace += aoa[r, r]
        for r in range(n_con):
            aoa[r, r] += reg * trace
        solve_first_unit(aoa, n_con, lam)
        total = 0.0
        for b in range(b_max):
            if not mask[i, b]:
                out[i, b] = 0.0
                continue
            acc = 0.0
            for r in range(n_con):
                acc += a[b, r] * lam[r]
            out[i, b] = om[b] * acc
            total += out[i, b]
        for b in range(b_max):
            out[i, b] /= total


@numba.njit(cache=_CACHE, nogil=True)
def linear_smooth_rows(points, normals, e1, e2, knn, weights, ridge, lo, hi, out):
    """Local-linear regression of the neighbours' normals at rows lo:hi, its intercept into ``out``.

    For point i, with design rows ``x_k = (1, d_k . e1_i, d_k . e2_i)`` (``d_k`` the offset
    of neighbour k) and weights ``w_k``, the intercept of the weighted least-squares fit
    ``n(q) = a + J (q - p)`` is ``a = sum_k w_k (y . x_k) n_k`` with ``y`` the first row of
    ``(sum_k w_k x_k x_k^T + ridge)^-1``; ``ridge`` times the matrix's trace is added to
    the two slope entries of its diagonal. ``out[i]`` is left unnormalised.
    """
    k_max = knn.shape[1]
    m = np.empty((3, 3))
    y = np.empty(3)
    xs = np.empty((k_max, 3))
    for i in range(lo, hi):
        for r in range(3):
            for c in range(3):
                m[r, c] = 0.0
        for j in range(k_max):
            q = knn[i, j]
            dx = points[q, 0] - points[i, 0]
            dy = points[q, 1] - points[i, 1]
            dz = points[q, 2] - points[i, 2]
            xs[j, 0] = 1.0
            xs[j, 1] = dx * e1[i, 0] + dy * e1[i, 1] + dz * e1[i, 2]
            xs[j, 2] = dx * e2[i, 0] + dy * e2[i, 1] + dz * e2[i, 2]
            w = weights[i, j]
            for r in range(3):
                for c in range(3):
                    m[r, c] += w * xs[j, r] * xs[j, c]
        extra = ridge * (m[0, 0] + m[1, 1] + m[2, 2])
        m[1, 1] += extra
        m[2, 2] += extra
        solve_first_unit(m, 3, y)
        ax = ay = az = 0.0
        for j in range(k_max):
            q = knn[i, j]
            f = weights[i, j] * (y[0] * xs[j, 0] + y[1] * xs[j, 1] + y[2] * xs[j, 2])
            ax += f * normals[q, 0]
            ay += f * normals[q, 1]
            az += f * normals[q, 2]
        out[i, 0] = ax
        out[i, 1] = ay
        out[i, 2] = az
