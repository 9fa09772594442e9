"""Spectral Dirichlet embeddings: the two smallest non-trivial eigenvectors of ``A f = lambda B f``.

LEM (``L f = lambda D f``), LLE (``L^T L f = lambda f``) and SDP (``L f = lambda B f``
with B the boundary indicator, Sec. 4.1) differ only in A and B. Rows of A sum to zero,
so the constant vector is an eigenvector with eigenvalue 0; it is removed explicitly
(the iteration runs on ``P (A - sigma B)^{-1} B P``, P subtracting the mean), never by
skipping a fixed number of eigenvectors. B may be singular (SDP): shift-invert only needs
``A - sigma B`` to be invertible.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as sla

from parambench.datasets_gen.errors import ConvergenceError, SolverError

from ..hints import Hint, hinted
from .sparse_eigen import SparseFactor
from .threads import single_threaded_blas

__all__ = ["smallest_nontrivial_pair", "fix_signs", "b_orthonormalize", "real_pair", "direct_sdp_pair"]


def fix_signs(vectors: np.ndarray) -> np.ndarray:
    """Flip each column so that its entry of largest magnitude is positive (deterministic output)."""
    idx = np.argmax(np.abs(vectors), axis=0)
    signs = np.sign(vectors[idx, np.arange(vectors.shape[1])])
    signs[signs == 0] = 1.0
    return vectors * signs


#: Two real parts this close to parallel (|cosine|) are one direction, not two.
_DEPENDENT_COS = 0.999


def real_pair(vals: np.ndarray, vecs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two real vectors spanning the two smallest eigen-directions (a complex pair gives Re, Im;
    a double real eigenvalue whose vectors' real parts coincide gives its plane)."""
    order = np.argsort(vals.real)
    vals, vecs = vals[order], vecs[:, order]
    first = vecs[:, 0]
    if abs(vals[0].imag) > 1e-9 * max(abs(vals[0]), 1e-300):
        # Complex conjugate pair: Re and Im span the real invariant plane of both.
        pair = np.column_stack([first.real, first.imag])
        return np.array([vals[0].real, vals[0].real]), pair
    second = vecs[:, 1]
    pair = np.column_stack([first.real if np.abs(first.real).max() >= np.abs(first.imag).max() else first.imag,
                            second.real if np.abs(second.real).max() >= np.abs(second.imag).max() else second.imag])
    unit = pair / np.maximum(np.linalg.norm(pair, axis=0), 1e-300)
    if abs(float(unit[:, 0] @ unit[:, 1])) > _DEPENDENT_COS:
        # A double real eigenvalue (a square lattice's x and y modes): ARPACK returns two
        # complex combinations of its plane whose real parts can coincide (sdp on a 61 x 61
        # grid: "cannot make them B-orthonormal"). The plane is the span of all four parts.
        parts = np.column_stack([first.real, first.imag, second.real, second.imag])
        pair = np.linalg.svd(parts, full_matrices=False)[0][:, :2]
    return vals[:2].real, pair


@single_threaded_blas()  # ARPACK's small dense steps; see parambench.methods.spectral.threads
def smallest_nontrivial_pair(a_mat: sp.spmatrix, b_mat: sp.spmatrix, *, perm: np.ndarray | None = None,
                             nev: int = 2, ncv: int | None = None, tol: float = 1e-8,
                             seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """The two eigenpairs of ``A f = lambda B f`` with smallest real part, constants excluded.

    Parameters
    ----------
    a_mat : (N, N) scipy.sparse matrix of float64
        Rows sum to zero (a Laplacian or ``L^T L``); may be non-symmetric.
    b_mat : (N, N) scipy.sparse matrix of float64
        Positive semi-definite (a degree matrix, the identity or a boundary indicator),
        with ``A - sigma B`` invertible for small negative sigma.
    perm : (N,) numpy.ndarray of int64, optional
        Fill-reducing elimination order.
    nev : int
        Eigenvalues computed (at least 2).
    ncv : int, optional
        Krylov vectors kept between ARPACK restarts; default ``max(12, 2 nev + 4)``.
        A wider space than ARPACK's default ``2 nev + 1`` separates the near-equal
        pair of a roughly symmetric patch in fewer restarts (measured on 300k-point SDP:
        23 solves with these defaults, 34 with the former nev = 4, default ncv and
        tol = 1e-10; the same span to a subspace angle of 6e-8).
    tol : float
        ARPACK relative tolerance. The solves with a mixed-precision factorisation
        (:class:`~parambench.methods.spectral.sparse_eigen.SparseFactor`) are refined to a tenth
        of it, not to full double precision: each refinement step is a triangular
        solve, and the Krylov iteration cannot use more accuracy than ``tol``.
    seed : int
        Seed of the ARPACK start vector.

    Returns
    -------
    eigenvalues : (2,) numpy.ndarray of float64
        Real parts, ascending.
    vectors : (N, 2) numpy.ndarray of float64
        Zero-mean columns of unit 2-norm, signs fixed by :func:`fix_signs`.

    Raises
    ------
    SolverError
        Singular shifted matrix, or an eigenvalue with negative real part (the energy is
        not bounded below: bad weights).
    ConvergenceError
        ARPACK did not converge.
    """
    n = a_mat.shape[0]
    a = sp.csc_matrix(a_mat, dtype=np.float64)
    b = sp.csc_matrix(b_mat, dtype=np.float64)
    scale = max(float(abs(a).sum()) / n, 1e-300) / max(float(abs(b).sum()) / n, 1e-300)
    sigma = -1e-6 * scale
    factor = SparseFactor(a - sigma * b, perm, refine_rtol=0.1 * tol)

    def op(x: np.ndarray) -> np.ndarray:
        x = x - x.mean()
        y = factor.solve(b @ x)
        return y - y.mean()

    linop = sla.LinearOperator((n, n), matvec=op, dtype=np.float64)
    v0 = np.random.default_rng(seed).standard_normal(n)
    nev = max(2, min(nev, n - 2))
    ncv = min(n - 1, max(12, 2 * nev + 4) if ncv is None else ncv)
    try:
        mu, vecs = sla.eigs(linop, k=nev, ncv=ncv, which="LM", tol=tol, v0=v0 - v0.mean(),
                            maxiter=max(1000, 20 * n))
    except sla.ArpackNoConvergence:
        raise hinted(ConvergenceError, "the eigen-solver (ARPACK, shift-invert) did not converge",
                     Hint("try a larger k_nn", "k_nn"), Hint("try a larger reg_eps", "reg_eps")) from None
    keep = np.abs(mu) > 1e-12 * np.abs(mu).max()
    vals = sigma + 1.0 / mu[keep]
    vals, pair = real_pair(vals, vecs[:, keep])
    if vals[0] < -1e-8 * scale:
        raise hinted(SolverError, f"the Dirichlet problem has a negative eigenvalue ({vals[0]:.3e}): the energy "
                     "is not bounded below with these weights", Hint("try a larger reg_eps", "reg_eps"),
                     Hint("try other weights", "weights"))
    pair = pair - pair.mean(axis=0)
    norms = np.linalg.norm(pair, axis=0)
    if np.any(norms == 0) or not np.all(np.isfinite(pair)):
        raise SolverError("the Dirichlet eigenvectors are degenerate (zero or non-finite).")
    return vals, fix_signs(pair / norms)


def b_orthonormalize(pair: np.ndarray, b_diag: np.ndarray) -> np.ndarray:
    """Make two coordinate functions B-orthonormal: ``f_u^T B f_v = 0``, ``f^T B f = 1``.

    Both are first centred in the B inner product (translations do not count), then
    Gram-Schmidt orthogonalised. The two axes then have equal B-weighted spread, which
    removes the shear of independent eigenvectors (Sec. 4.2, Fig. 8b).

    Parameters
    ----------
    pair : (N, 2) numpy.ndarray of float64
    b_diag : (N,) numpy.ndarray of float64
        Diagonal of B (non-negative, not all zero).

    Returns
    -------
    (N, 2) numpy.ndarray of float64

    Raises
    ------
    SolverError
        The two functions are linearly dependent on the support of B.
    """
    w = b_diag / b_diag.sum()
    f = pair - w @ pair
    gram = f.T @ (b_diag[:, None] * f)
    try:
        chol = np.linalg.cholesky(gram)
    except np.linalg.LinAlgError:
        # A slit whose lips coincide (a cut mesh's seam as bare points) left both
        # eigenvectors alike on the boundary: the message said so and offered nothing.
        raise hinted(SolverError, "the two eigenvectors are dependent on the boundary, so they cannot be made "
                     "B-orthonormal (a boundary the points do not show well, such as a slit whose lips coincide)",
                     Hint("use b_orthonormal=False (the paper's variant)", "b_orthonormal", False),
                     Hint("lower boundary_angle_deg (e.g. 100)", "boundary_angle_deg", 100.0, -1)) from None
    return fix_signs(f @ np.linalg.inv(chol).T)


def direct_sdp_pair(laplacian: sp.spmatrix, boundary_mask: np.ndarray, points: np.ndarray, *,
                    b_orthonormal: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """SDP's two coordinate functions on every point: ``L f = lambda B f``, B the boundary indicator.

    One shift-invert factorisation of ``L`` in the points' nested-dissection order
    (:func:`smallest_nontrivial_pair`), then, by default, :func:`b_orthonormalize`.

    Parameters
    ----------
    laplacian : (N, N) scipy.sparse matrix
    boundary_mask : (N,) numpy.ndarray of bool
    points : (N, 3) numpy.ndarray of float64
        For the ordering.
    b_orthonormal : bool

    Returns
    -------
    eigenvalues : (2,) numpy.ndarray of float64
    pair : (N, 2) numpy.ndarray of float64

    Raises
    ------
    SolverError, ConvergenceError
        From :func:`smallest_nontrivial_pair` or :func:`b_orthonormalize`.
    """
    from .ordering import nested_dissection  # local: ordering compiles numba kernels

    lap = sp.csc_matrix(laplacian)
    b_diag = np.asarray(boundary_mask, dtype=np.float64)
    vals, pair = smallest_nontrivial_pair(lap, sp.diags(b_diag).tocsc(), perm=nested_dissection(points, lap))
    return vals, (b_orthonormalize(pair, b_diag) if b_orthonormal else pair)
