"""BLAS threading for the solvers.

SuperLU's supernodal kernels and LAPACK call a multi-threaded BLAS. On the 2-core
machines this project runs on, with other jobs on the cores, the BLAS threads spin and
lose far more than they win: at 100k vertices the complex factorisation took 4.0 s with
two threads and 0.93 s with one; a 280 x 280 complex eigen-solve 1.2 s instead of 0.11 s;
231 Schur right-hand sides 1.5 s instead of 0.07 s. The solvers therefore run their
dense and sparse kernels single-threaded.
"""

from __future__ import annotations

from threadpoolctl import threadpool_limits

__all__ = ["single_threaded_blas"]


def single_threaded_blas():
    """Context manager limiting BLAS (OpenBLAS/MKL) to one thread."""
    return threadpool_limits(1, user_api="blas")
