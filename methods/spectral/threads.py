"""BLAS threading for the solvers.

SuperLU's supernodal kernels and LAPACK call a multi-threaded BLAS. On the 2-core
machines this project runs on, with other jobs on the cores, the BLAS threads spin and
lose far more than they win: at 100k vertices the complex factorisation took 4.0 s with
two threads and 0.93 s with one; a 280 x 280 complex eigen-solve 1.2 s instead of 0.11 s;
231 Schur right-hand sides 1.5 s instead of 0.07 s; even a 368 x 70 SVD (the boundary
basis of :mod:`.subspace` at 10k points) took 0.6-1.2 s with two busy threads and 2 ms
with one. The solvers therefore run their dense and sparse kernels single-threaded.

Entering ``threadpool_limits`` scans the loaded libraries (1-7 ms a time), so the context
is re-entrant: only the outermost entry sets the limit and nested entries cost nothing,
which lets a whole solve be wrapped once around its many small dense calls.
"""

from __future__ import annotations

import threading
from contextlib import contextmanager

from threadpoolctl import threadpool_limits

__all__ = ["single_threaded_blas"]

_LOCK = threading.Lock()
_DEPTH = 0


@contextmanager
def single_threaded_blas():
    """Context manager limiting BLAS (OpenBLAS/MKL) to one thread; cheap when nested.

    The limit is process-wide (as BLAS's own setting is); it is restored when the
    outermost context exits.
    """
    global _DEPTH
    with _LOCK:
        outer = _DEPTH == 0
        _DEPTH += 1
    limiter = threadpool_limits(1, user_api="blas") if outer else None
    try:
        yield
    finally:
        if limiter is not None:
            limiter.restore_original_limits()
        with _LOCK:
            _DEPTH -= 1
