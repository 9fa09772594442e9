"""Row-chunked numpy work on worker threads, for the front end's per-point batches.

Most of the front end's vectorised steps work on consecutive rows (points) in chunks to
bound temporary memory. numpy releases the GIL inside its loops (gathers, einsum,
ufuncs), so two threads each taking a chunk use both cores on that work, and each row's
arithmetic is unchanged (the same numpy calls on fewer rows at a time; the tests check
this bit for bit). The batched 3x3 LAPACK calls (``eigh``, ``solve``) release the GIL
too but were measured not to run faster on two threads here (numpy 2.x with its
bundled OpenBLAS); the rest of each batch overlaps with them.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from typing import Callable

import numba

__all__ = ["worker_count", "for_each_chunk"]


def worker_count() -> int:
    """Threads to use: ``NUMBA_NUM_THREADS`` (default: the number of cores), as the DEM kernels.

    Read from numba's config, not from ``numba.get_num_threads()``, which would start a
    threading layer (see :func:`parambench.methods.pointset.dem.dem_balls`).
    """
    return max(1, int(numba.config.NUMBA_NUM_THREADS))


def for_each_chunk(work: Callable[[slice], None], n: int, chunk: int) -> None:
    """Call ``work(rows)`` for the consecutive slices of ``range(n)`` of ``chunk`` rows, on threads.

    Parameters
    ----------
    work : callable
        Takes a ``slice`` of rows and writes its results for those rows only (disjoint
        slices: no locking needed).
    n : int
        Rows.
    chunk : int
        Rows per call (the last call may get fewer).

    Raises
    ------
    Exception
        The first (in row order) exception raised by ``work``, as a plain loop would.
    """
    slices = [slice(lo, min(lo + chunk, n)) for lo in range(0, n, max(1, int(chunk)))]
    workers = min(worker_count(), len(slices))
    if workers <= 1:
        for rows in slices:
            work(rows)
        return
    with ThreadPoolExecutor(max_workers=workers) as pool:
        # map yields in submission order, so the first failing chunk's error is raised.
        for _ in pool.map(work, slices):
            pass
