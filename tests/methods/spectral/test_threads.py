"""The solvers' single-threaded BLAS context: limit inside, restored after, nesting free."""

from threadpoolctl import threadpool_info

import parambench.methods.spectral.threads as threads
from parambench.methods.spectral.threads import single_threaded_blas


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
    assert getattr(threads._STATE, "depth", 0) == 0


def test_restored_after_an_exception():
    before = _blas_threads()
    try:
        with single_threaded_blas():
            raise ValueError("boom")
    except ValueError:
        pass
    assert _blas_threads() == before
    assert getattr(threads._STATE, "depth", 0) == 0


def test_usable_as_decorator():
    @single_threaded_blas()
    def inside() -> list[int]:
        return _blas_threads()

    assert all(n == 1 for n in inside())
    assert all(n == 1 for n in inside())  # a second call re-enters the context


def test_each_thread_keeps_its_own_depth():
    import threading

    before = _blas_threads()
    seen: list[list[int]] = []

    def worker():
        # The main thread is inside a context; this thread's first context is still its outermost.
        assert getattr(threads._STATE, "depth", 0) == 0
        with single_threaded_blas():
            seen.append(_blas_threads())
        seen.append([getattr(threads._STATE, "depth", 0)])

    with single_threaded_blas():
        t = threading.Thread(target=worker)
        t.start()
        t.join(10)
        assert threads._STATE.depth == 1
    assert seen[0] and all(n == 1 for n in seen[0])
    assert seen[1] == [0]
    assert _blas_threads() == before
