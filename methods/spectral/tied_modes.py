"""Tied lowest modes: which of an annulus's two conformal maps SCP returns.

On a surface with two boundary loops, ``e^z`` and ``e^-z`` (z = height + i angle on an open
cylinder) are both exact conformal maps: each rim goes outside in one of them. Their
discrete energies differ only by discretization error, so the two smallest eigenvalues of
``(k L / 2 - M) z = lambda B z`` nearly tie, and every combination of the two
eigenvectors is as good a minimiser. The eigen-solver's roundoff then picks a mix: rims
that are not round and a map with critical points. Measured on an open cylinder of 100 x 17
vertices (cotangent weights, k = 1): the two values agree to 2e-12 relative on the exact
mesh, 8e-8 to 3.6e-4 with its vertices moved by 1e-6 to 1e-2 of an edge, and the first
eigenvector mixed the two maps 16-44 % (QC mean 1.05-1.06, max 2.4; libigl's SCP the
same); on frustums (rims 2 % and 30 % apart in radius) the gap was 8 % and 71 % and the
eigenvector pure to 4e-11.

Where the two smallest of three eigenvalues tie (:func:`tied_pair`: their gap is at most
:data:`TIE` of the gap to the third, which also holds at a k search's zero crossing),
:func:`outer_rim_mode` takes, within the span of the two eigenvectors, the combination that
puts the most B-mass on the longest loop: the map whose outer rim is that loop (for
``a e^z + b e^-z`` the loops' B-masses are diagonal in (a, b), so the extreme is a pure
map). The same holds for the non-symmetric point-set Laplacians: 1,700 jittered points of
that cylinder gave a pair 1.6 % apart, 0.5 % of the gap to the next, and a mixed map that
failed its self-check until the fourth retry.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp

__all__ = ["TIE", "outer_rim_mode", "outer_rim_if_tied", "tied_pair"]

#: Two eigenvalues tie when their gap is at most this share of the gap to the third (an
#: open cylinder's pair, k = 1: 1e-12 to 4e-5 of it, vertices exact or moved by up to 1e-2
#: of an edge; 1,700 jittered points 5e-3; 2,000 random points of a cylinder with dense
#: rims 7e-3 to 7e-2 over a k search, whose mix at 1e-2 passed with rims 24 % off round;
#: frustums with rims 2 % / 30 % apart in radius 9.6e-3 / 0.18, where the first eigenvector
#: was pure to 4e-11 either way: the first of them now gets the map with the wider rim
#: outside, whichever of the two ranked lower). 1e-2 before; 0.1 left every map of 9
#: meshes (``scp``, ``dncp-opt``) and of 48 multi-loop point sets (``ocp``, ``fbcp-pc``)
#: bit for bit the same, and 83 of the 84 real-data benchmark cases (bunny10k 18 -> 9
#: foldovers, failing either way). The ratio cannot tell two maps near zero from one at zero
#: and a small second; there the combination with the most mass on the outer loop is the
#: first map (up to a rotation: ``scp`` on the ``slit`` plane, ``holes-bumped`` and
#: ``real/bunny10k``, 1e-16 apart after a similarity fit).
TIE = 0.1


def outer_rim_mode(vectors: np.ndarray, b: sp.spmatrix | np.ndarray | None, loops: Sequence[np.ndarray],
                   points: np.ndarray | None = None) -> np.ndarray:
    """Of the span of two tied eigenvectors, the map with the longest loop outside.

    The caller decides that they tie (:func:`tied_pair`).

    Parameters
    ----------
    vectors : (V, m) numpy.ndarray of complex128, m >= 2
        Eigenvectors by increasing real part of their eigenvalues; the first two are
        combined (of a non-Hermitian problem too: the combination is chosen by the loops'
        B-mass alone).
    b : (V, V) scipy.sparse matrix or numpy.ndarray of float64, or None
        The problem's B (None: the identity).
    loops : sequence of (L_i,) numpy.ndarray of int64
        Boundary loops as indices into the rows of ``vectors``, two or more.
    points : (V, 3) numpy.ndarray of float64, optional
        To measure the loops' lengths; without it the loop with the most vertices is the
        longest.

    Returns
    -------
    (V,) numpy.ndarray of complex128
        Unit 2-norm, mean-free.
    """
    basis = vectors[:, :2]
    outer = np.asarray(loops[int(np.argmax([_length(loop, points) for loop in loops]))], dtype=np.int64)
    b_all = sp.identity(basis.shape[0], format="csr") if b is None else b
    gram = basis.conj().T @ (b_all @ basis)
    outer_gram = basis[outer].conj().T @ (_restricted(b_all, outer) @ basis[outer])
    _, coef = la.eigh(0.5 * (outer_gram + outer_gram.conj().T), 0.5 * (gram + gram.conj().T))
    z = basis @ coef[:, -1]
    z = z - z.mean()
    return z / np.linalg.norm(z)


def _length(loop: np.ndarray, points: np.ndarray | None) -> float:
    if points is None:
        return float(len(loop))
    q = points[loop]
    return float(np.linalg.norm(q - np.roll(q, -1, axis=0), axis=1).sum())


def _restricted(b, rows: np.ndarray):
    """B's block on ``rows`` (a dense array or a sparse matrix)."""
    if sp.issparse(b):
        return sp.csr_matrix(b)[rows][:, rows]
    return np.asarray(b)[np.ix_(rows, rows)]


def tied_pair(values: np.ndarray) -> bool:
    """Whether the two smallest of three eigenvalues tie, measured against the gap to the third.

    Scale-free, and meaningful where the smallest is zero (a k search's crossing, DNCP's
    k_opt): an annulus's second map is then zero too, up to the discretization, while the
    next mode stays apart (the open cylinder above: a gap of 2e-12 against 1.1e-4 at k = 1).

    Parameters
    ----------
    values : (m,) numpy.ndarray, m >= 3
        By increasing real part.
    """
    lam = np.real(np.asarray(values))
    return lam.size >= 3 and lam[1] - lam[0] <= TIE * (lam[2] - lam[0])


def outer_rim_if_tied(values: np.ndarray, vectors: np.ndarray, b: sp.spmatrix | np.ndarray | None,
                      loops: Sequence[np.ndarray], points: np.ndarray | None = None) -> np.ndarray | None:
    """:func:`outer_rim_mode` where the surface has two or more loops and the two smallest of
    ``values`` tie (:func:`tied_pair`); None otherwise (the caller keeps its first vector).

    Parameters are those of :func:`outer_rim_mode`, with ``values`` (m,), m >= 3, the
    eigenvalues of ``vectors`` by increasing real part.
    """
    if len(loops) < 2 or not tied_pair(values):
        return None
    return outer_rim_mode(vectors, b, loops, points)
