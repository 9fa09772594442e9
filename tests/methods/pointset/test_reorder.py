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


def test_spatial_order_is_reused_for_the_same_array_only(monkeypatch):
    """The front end and the two-level solve order the same point array: the second call
    returns the kept order without another kd-tree; another array (even with the same
    values) is ordered afresh, and the order is read-only."""
    from parambench.methods.pointset import reorder

    pts = np.random.default_rng(3).random((500, 3))
    built = []
    real = reorder.cKDTree
    monkeypatch.setattr(reorder, "cKDTree", lambda *a, **k: built.append(1) or real(*a, **k))
    first = reorder.spatial_order(pts)
    again = reorder.spatial_order(pts)
    assert again is first and len(built) == 1
    assert np.array_equal(np.sort(first), np.arange(500))
    with pytest.raises(ValueError):
        first[0] = 1
    other = reorder.spatial_order(pts.copy())
    assert len(built) == 2 and np.array_equal(other, first)
    assert reorder.spatial_order(pts[:400]).size == 400 and len(built) == 3
    listed = pts.tolist()  # not an array: ordered, never recognised again
    assert np.array_equal(reorder.spatial_order(listed), first) and reorder._LAST_ORDER is None
    assert len(built) == 4
