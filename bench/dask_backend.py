"""Run sweep cells on a Dask distributed cluster.

Workers receive only :class:`~parambench.bench.cells.Cell` records (a few strings and numbers) and
regenerate the surfaces from their seeds; they return the row and arrays, and the client
writes them, so workers need no shared file system. Tasks lost with a dying worker are
rescheduled by the scheduler on the remaining workers.
"""

from __future__ import annotations

from typing import Iterator

from .cells import Cell
from .run_cell import compute_cell

__all__ = ["dask_results", "check_scheduler_reachable", "SCHEDULER_TIMEOUT"]

#: Seconds to wait for a scheduler to answer before the sweep starts.
SCHEDULER_TIMEOUT = 10.0


def check_scheduler_reachable(address: str, timeout: float | None = None) -> None:
    """Connect to the scheduler once, before the sweep creates its folder.

    An unreachable address failed only after the folder was made, 30 s later, with the
    file-system advice of a generic OSError ("check the path and its permissions").

    Raises
    ------
    InvalidInputError
        No scheduler answered at ``address`` within ``timeout`` seconds (default
        :data:`SCHEDULER_TIMEOUT`).
    """
    from distributed import Client

    from parambench.datasets_gen.errors import InvalidInputError

    timeout = SCHEDULER_TIMEOUT if timeout is None else timeout
    try:
        Client(address, timeout=f"{timeout:g}s").close()
    except (OSError, TimeoutError) as exc:
        raise InvalidInputError(f"--scheduler: no Dask scheduler answered at {address} within {timeout:g} s "
                                f"({type(exc).__name__}); start one (`dask scheduler`, then `dask worker "
                                f"{address}`), or leave out --scheduler to run in this process.") from None


def dask_results(cells: list[Cell], *, scheduler: str | None = None, workers: int | None = None,
                 retries: int = 2) -> Iterator[tuple[dict, dict | None]]:
    """Yield ``compute_cell`` results as the cluster finishes them.

    Parameters
    ----------
    cells : list of Cell
    scheduler : str, optional
        Address of a running scheduler (``tcp://host:8786``).
    workers : int, optional
        When no scheduler is given, start a local cluster of this many single-threaded
        worker processes.
    retries : int
        Extra attempts for a task whose worker died.
    """
    from distributed import Client, LocalCluster, as_completed

    cluster = None
    if scheduler:
        client = Client(scheduler)
    else:
        cluster = LocalCluster(n_workers=workers or 1, threads_per_worker=1, processes=True,
                               dashboard_address=None)
        client = Client(cluster)
    try:
        # Cells have distinct ids; pure=False keeps Dask from merging equal-looking tasks.
        futures = [client.submit(compute_cell, cell, key=f"cell-{cell.cell_id}", pure=False, retries=retries)
                   for cell in cells]
        for future in as_completed(futures):
            yield future.result()
            future.release()
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
