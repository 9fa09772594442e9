"""Row moves between the kd-tree and the input order: compiled kernels against numpy indexing."""

from __future__ import annotations

import numpy as np
import pytest

from parambench.methods.pointset.reorder import renumbered_rows, take_rows


@pytest.mark.parametrize("shape", [(50,), (50, 7), (50, 7, 2), (0, 3)])
def test_take_rows_is_fancy_indexing(shape):
    rng = np.random.default_rng(0)
    a = rng.normal(size=shape)
    rows = rng.permutation(shape[0])
    out = take_rows(a, rows)
    assert out.dtype == a.dtype and out.flags.c_contiguous
    np.testing.assert_array_equal(out, a[rows])
    ints = rng.integers(-5, 5, size=shape)
    np.testing.assert_array_equal(take_rows(ints, rows[::2]), ints[rows[::2]])
    if shape[0]:
        with pytest.raises(IndexError):
            take_rows(a, np.array([shape[0]]))


def test_renumbered_rows_keeps_padding():
    rng = np.random.default_rng(1)
    n, b = 80, 9
    order = rng.permutation(n)
    idx = rng.integers(-1, n, size=(n, b))
    rows = rng.permutation(n)
    want = np.where(idx[rows] >= 0, order[np.maximum(idx[rows], 0)], -1)
    got = renumbered_rows(idx, rows, order)
    assert got.dtype == np.int64
    np.testing.assert_array_equal(got, want)
