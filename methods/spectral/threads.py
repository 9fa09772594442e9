"""BLAS threading for the solvers.

SuperLU's supernodal kernels and LAPACK call a multi-threaded BLAS. On the 2-core
machines this project runs on, with other jobs on the cores, the BLAS threads spin and
lose far more than they win: at 100k vertices the complex factorisation took 4.0 s with
two threads and 0.93 s with one; a 280 x 280 complex eigen-solve 1.2 s instead of 0.11 s;
231 Schur right-hand sides 1.5 s instead of 0.07 s; even a 368 x 70 SVD (the boundary
basis of :mod:`.subspace` at 10k points) took 0.6-1.2 s with two busy threads and 2 ms
with one. The solvers therefore run their dense and sparse kernels single-threaded.

Entering ``threadpool_limits`` scans the loaded libraries (1-7 ms a time), so the context
is re-entrant: only the outermost entry of each thread sets the limit and nested entries cost nothing,
which lets a whole solve be wrapped once around its many small dense calls.
"""

from __future__ import annotations

import os
import sys
import threading
from contextlib import contextmanager

from threadpoolctl import threadpool_limits

__all__ = ["single_threaded_blas", "solver_threads"]

#: Open contexts per thread: OpenBLAS's thread count set from one thread is not reliably
#: restored from another (measured: a restore from a second thread left the limit at 1),
#: so each thread sets and restores its own limit, as a plain ``threadpool_limits`` does.
_STATE = threading.local()


@contextmanager
def single_threaded_blas():
    """Context manager limiting BLAS (OpenBLAS/MKL) to one thread; cheap when nested.

    The outermost context of each thread sets the limit and restores the previous one
    on exit; nested contexts in the same thread do nothing.
    """
    depth = getattr(_STATE, "depth", 0)
    limiter = threadpool_limits(1, user_api="blas") if depth == 0 else None
    _STATE.depth = depth + 1
    try:
        yield
    finally:
        _STATE.depth = depth
        if limiter is not None:
            limiter.restore_original_limits()


def solver_threads() -> int:
    """Threads for work split by columns (triangular solves): as many as the compiled kernels use.

    ``numba.config.NUMBA_NUM_THREADS`` when numba is loaded (the point-set front end's
    kernels), otherwise the ``NUMBA_NUM_THREADS`` environment variable or the cores this
    process may run on, so one setting governs both; importing numba only for this
    number would cost a mesh method 0.24 s.
    """
    numba = sys.modules.get("numba")
    if numba is not None and hasattr(numba, "config"):
        return max(1, int(numba.config.NUMBA_NUM_THREADS))
    env = os.environ.get("NUMBA_NUM_THREADS", "").strip()
    if env.isdigit() and int(env) > 0:
        return int(env)
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)
