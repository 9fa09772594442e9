"""Area matrix, B, conformal operator, turning numbers: hand-computed cases and invariants."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from parambench.datasets_gen.errors import InvalidInputError
from parambench.methods.spectral.operators import (
    area_matrix,
    boundary_indicator,
    check_loops,
    conformal_operator,
    is_symmetric,
    rayleigh_energy,
)
from parambench.methods.spectral.turning import is_regular_turning, loop_turning_numbers, turning_penalty


def test_area_of_unit_square_and_hole():
    # outer square 0..3 counter-clockwise, inner square 4..7 clockwise (a hole)
    z = np.array([0, 4, 4 + 4j, 4j, 1 + 1j, 1 + 2j, 2 + 2j, 2 + 1j], dtype=complex)
    m = area_matrix([np.arange(4), np.arange(4, 8)], 8)
    assert np.isclose(np.vdot(z, m @ z), 16.0 - 1.0)
    assert abs(m - m.conj().T).max() == 0  # Hermitian
    assert np.isclose(m[0, 1], -0.25j) and np.isclose(m[1, 0], 0.25j)
    # translation and rotation invariance, reflection flips the sign
    w = (z + (3 - 7j)) * np.exp(0.3j)
    assert np.isclose(np.vdot(w, m @ w).real, 15.0)
    assert np.isclose(np.vdot(z.conj(), m @ z.conj()).real, -15.0)
    assert np.allclose(m @ np.ones(8), 0)


def test_boundary_indicator_marks_every_loop():
    b = boundary_indicator([np.array([0, 1, 2]), np.array([5, 6, 7])], 9)
    assert np.array_equal(b.diagonal(), [1, 1, 1, 0, 0, 1, 1, 1, 0])


def test_bad_loops():
    with pytest.raises(InvalidInputError, match="no boundary loop"):
        check_loops([], 5)
    with pytest.raises(InvalidInputError, match="at least 3"):
        check_loops([np.array([0, 1])], 5)
    with pytest.raises(InvalidInputError, match="twice"):
        check_loops([np.array([0, 1, 2]), np.array([2, 3, 4])], 5)
    with pytest.raises(InvalidInputError, match=r"\[0, 4\]"):
        check_loops([np.array([0, 1, 9])], 5)


def test_conformal_energy_of_identity_on_flat_mesh_is_zero(plane):
    # Flat mesh, identity map: Dirichlet energy = area exactly for cotangent weights.
    z = plane.points[:, 0] + 1j * plane.points[:, 1]
    m = area_matrix(plane.loops, len(z))
    k_op = conformal_operator(plane.lap, m, 1.0)
    area = np.vdot(z, m @ z).real
    assert np.isclose(area, 1.0, rtol=1e-12)  # unit square
    assert abs(np.vdot(z, k_op @ z)) < 1e-12
    # the map is also an exact eigenvector with eigenvalue 0
    assert np.abs(k_op @ z).max() < 1e-12
    # an anti-conformal map (reflection) has energy 2 * area
    assert np.isclose(np.vdot(z.conj(), k_op @ z.conj()).real, 2.0)
    assert is_symmetric(plane.lap) and not is_symmetric(sp.csr_matrix([[1.0, 2.0], [0.0, 1.0]]))


def test_rayleigh_energy_is_similarity_invariant(saddle):
    m = area_matrix(saddle.loops, len(saddle.points))
    k_op = conformal_operator(saddle.lap, m, 1.0)
    w = np.zeros(len(saddle.points))
    w[np.concatenate(saddle.loops)] = 1.0
    z = saddle.points[:, 0] + 1j * saddle.points[:, 1]
    e = rayleigh_energy(z, k_op, w)
    assert np.isclose(rayleigh_energy(3.0 * np.exp(1j) * z + 5 - 2j, k_op, w), e)
    assert np.isclose(rayleigh_energy(z, k_op, sp.diags(w)), e)
    with pytest.raises(InvalidInputError, match="constant"):
        rayleigh_energy(np.ones(len(z), dtype=complex), k_op, w)


def test_turning_numbers_and_penalty():
    t = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    circle = np.exp(1j * t)
    twice = np.exp(2j * t)
    z = np.concatenate([circle, 0.3 * circle[::-1], twice])
    loops = [np.arange(40), np.arange(40, 80), np.arange(80, 120)]
    assert loop_turning_numbers(z, loops).tolist() == [1, -1, 2]
    assert loop_turning_numbers(np.column_stack([z.real, z.imag]), loops[:1]).tolist() == [1]
    assert is_regular_turning(np.array([1, -1])) and is_regular_turning(np.array([-1, 1, -1]))
    assert not is_regular_turning(np.array([1, 1])) and not is_regular_turning(np.array([2]))
    assert turning_penalty(np.array([1, -1, -1])) == 0
    assert turning_penalty(np.array([3, -1])) == 2 and turning_penalty(np.array([0])) == 1


@pytest.mark.parametrize("asymmetry, expected", [(0.0, True), (1e-14, True), (1e-9, False), (0.3, False)])
def test_is_symmetric_decides_by_the_entrywise_tolerance(asymmetry, expected):
    """The quick two-product test may only say no where the entrywise test does."""
    n = 400
    rng = np.random.default_rng(1)
    a = sp.random(n, n, density=0.02, random_state=2, format="csr")
    sym = (a + a.T).tocsr()
    bump = sp.csr_matrix(([asymmetry * abs(sym).max()], ([3], [int(rng.integers(4, n))])), shape=(n, n))
    assert is_symmetric(sym + bump) is expected
