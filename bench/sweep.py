"""The sweep: run every unfinished cell of a suite, in-process or on a Dask cluster."""

from __future__ import annotations

import sys
from dataclasses import asdict
from typing import Iterable, Iterator

import pandas as pd
from tqdm import tqdm

from .cells import Cell
from .dataset_diagnostics import store_missing_diagnostics
from .run_cell import compute_cell, store_cell
from .runmeta import run_metadata
from .storage import ResultStore
from .suites import Suite, expand_cells

__all__ = ["run_sweep", "summary_table"]


def _serial(cells: list[Cell]) -> Iterator[tuple[dict, dict | None]]:
    for cell in cells:
        yield compute_cell(cell)


def _compute_with_peak(cell: Cell) -> tuple[dict, dict | None]:
    from .memory import high_water_mb

    row, arrays = compute_cell(cell)
    row["peak_rss_mb"] = high_water_mb()
    return row, arrays


def _isolated(cells: list[Cell]) -> Iterator[tuple[dict, dict | None]]:
    """Each cell in a fresh process: its peak resident memory is then the cell's own."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor
    from concurrent.futures.process import BrokenProcessPool

    from .run_cell import failed_row

    context = multiprocessing.get_context("spawn")
    for cell in cells:
        with ProcessPoolExecutor(max_workers=1, mp_context=context) as pool:
            try:
                yield pool.submit(_compute_with_peak, cell).result()
            except BrokenProcessPool:
                yield failed_row(cell, "WorkerDied", "the cell's process died (killed, or out of memory); "
                                 "run it alone or on a larger machine."), None


def _dask(cells: list[Cell], scheduler: str | None, workers: int | None) -> Iterator[tuple[dict, dict | None]]:
    from .dask_backend import dask_results

    yield from dask_results(cells, scheduler=scheduler, workers=workers)


def run_sweep(suite: Suite, results_dir: str, *, scheduler: str | None = None, workers: int | None = None,
              progress: bool = True, diagnostics: bool = True, isolate: bool = False) -> pd.DataFrame:
    """Run the cells of ``suite`` that ``results_dir`` does not hold yet.

    Each finished cell is written at once (see :class:`bench.storage.ResultStore`); a
    failing cell is recorded with its error and the sweep goes on.

    Parameters
    ----------
    suite : Suite
    results_dir : str
    scheduler : str, optional
        Address of an existing Dask distributed scheduler.
    workers : int, optional
        Start a local Dask cluster with this many single-threaded workers.
    progress : bool
        Show a progress bar on stderr.
    diagnostics : bool
        Also store per-surface weight histograms and detected boundaries for the report.
    isolate : bool
        Run each cell in a fresh process (in-process runs only) and record its peak
        resident memory as ``peak_rss_mb``; costs an interpreter start per cell.

    Returns
    -------
    pandas.DataFrame
        All rows in the results directory (old and new), also written to
        ``results.parquet`` and ``results.csv``.
    """
    store = ResultStore(results_dir)
    cells = expand_cells(suite)
    done = store.finished_ids()
    todo = [c for c in cells if c.cell_id not in done]
    store.write_metadata(run_metadata(suite=suite.name, parameters=asdict(suite), seeds=list(suite.seeds),
                                      n_cells=len(cells), n_skipped=len(cells) - len(todo),
                                      scheduler=scheduler or (f"local-dask:{workers}" if workers else "in-process")))
    if scheduler or workers:
        results: Iterable = _dask(todo, scheduler, workers)
    elif isolate:
        results = _isolated(todo)
    else:
        results = _serial(todo)
    bar = tqdm(total=len(todo), desc=f"parambench {suite.name}", unit="cell", disable=not progress,
               file=sys.stderr)
    with bar:
        for row, arrays in results:
            store_cell(store, row, arrays)
            bar.set_postfix_str(f"{row['dataset']} {row['method']} {row['status']}", refresh=False)
            bar.update(1)
    if diagnostics:
        for problem in store_missing_diagnostics(store, cells):
            print(f"parambench: note: no surface diagnostics for {problem}", file=sys.stderr)
    return store.consolidate()


def summary_table(table: pd.DataFrame) -> str:
    """A compact text table for the terminal: per method, mean QC per dataset plus failures."""
    if table.empty:
        return "no results"
    ok = table[table["status"] == "ok"]
    lines = []
    if not ok.empty:
        pivot = ok.pivot_table(index="method", columns="dataset", values="qc_mean", aggfunc="mean")
        lines.append("QC distortion (area-weighted mean; 1 is conformal):")
        lines.append(pivot.to_string(float_format=lambda v: f"{v:.3f}"))
        folds = ok.groupby("method")["foldovers"].sum().astype(int)
        times = ok.groupby("method")["time_total"].median()
        lines.append("")
        lines.append(pd.DataFrame({"foldovers (sum)": folds, "median time (s)": times.round(3)}).to_string())
    suspect = table[table["status"] == "suspect"]  # metrics stored, but the map failed its self-check
    failed = table[~table["status"].isin(("ok", "suspect"))]
    lines.append("")
    lines.append(f"{len(ok)} ok, {len(suspect)} suspect, {len(failed)} failed of {len(table)} cells")
    for _, r in suspect.head(5).iterrows():
        lines.append(f"  SUSPECT {r['dataset']} / {r['method']}: {str(r['error'])[:150]}")
    for _, r in failed.head(10).iterrows():
        lines.append(f"  FAILED {r['dataset']} / {r['method']}: {r['error_type']}: {str(r['error'])[:150]}")
    if len(failed) > 10:
        lines.append(f"  ... and {len(failed) - 10} more (see results.csv)")
    return "\n".join(lines)
