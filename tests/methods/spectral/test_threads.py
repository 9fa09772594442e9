"""The solvers' single-threaded BLAS context: limit inside, restored after, nesting free."""

from threadpoolctl import threadpool_info

import methods.spectral.threads as threads
from methods.spectral.threads import single_threaded_blas


def _blas_threads() -> list[int]:
    return [info["num_threads"] for info in threadpool_info() if info["user_api"] == "blas"]


def test_limit_inside_restored_after_nested_exit():
    before = _blas_threads()
    assert before, "no BLAS library loaded: the test would assert nothing"
    with single_threaded_blas():
        assert all(n == 1 for n in _blas_threads())
        with single_threaded_blas():
            assert all(n == 1 for n in _blas_threads())
        # Leaving the inner context must not lift the outer limit.
        assert all(n == 1 for n in _blas_threads())
    assert _blas_threads() == before
    assert threads._DEPTH == 0


def test_restored_after_an_exception():
    before = _blas_threads()
    try:
        with single_threaded_blas():
            raise ValueError("boom")
    except ValueError:
        pass
    assert _blas_threads() == before
    assert threads._DEPTH == 0


def test_usable_as_decorator():
    @single_threaded_blas()
    def inside() -> list[int]:
        return _blas_threads()

    assert all(n == 1 for n in inside())
    assert all(n == 1 for n in inside())  # a second call re-enters the context
