"""The sweep: run every unfinished cell of a suite, in-process or on a Dask cluster.

Before any folder is created the suite and options are validated and the results folder's
writability is checked. The sweep then holds the folder exclusively
(:mod:`parambench.bench.folder_lock`), reads what it already holds, moves unreadable cell files aside,
says what it will do ("12 done, 84 to run (81 new, 3 failed before and retried)") and runs
the rest. Cells that failed before are retried unless ``retry_failed=False``; every other
status (``ok``, ``suspect``, ...) counts as finished.
"""

from __future__ import annotations

import sys
from dataclasses import asdict, dataclass
from typing import Callable, Iterable, Iterator

import pandas as pd
from tqdm import tqdm

from parambench.reports.labels import variant_labels

from .cells import Cell
from .dataset_diagnostics import store_missing_diagnostics
from .folder_lock import hold_folder
from .run_cell import compute_cell, store_cell
from .runmeta import run_metadata
from .schema import STATUS_FAILED, STATUS_OK, STATUS_SUSPECT
from .storage import ResultStore, StoredCells, check_output_dir
from .suites import Suite, check_workers, expand_cells, real_dataset_note

__all__ = ["run_sweep", "summary_table", "SweepPlan", "plan_sweep"]

#: Unreadable cell files named one per line at the start of a sweep; the rest are counted.
MAX_LISTED_UNREADABLE = 10


def _note(text: str) -> None:
    print(f"parambench: {text}", file=sys.stderr)


@dataclass(frozen=True)
class SweepPlan:
    """Which cells of a sweep run, and why.

    Attributes
    ----------
    todo : list of Cell
        Cells to compute, in suite order.
    n_done : int
        Cells with a finished row (any status but ``failed``); skipped.
    n_new : int
        Cells with no row yet.
    n_retried : int
        Cells whose row says ``failed``, computed again.
    n_kept_failed : int
        Cells whose row says ``failed``, skipped (``retry_failed=False``).
    n_unreadable : int
        Cells whose file could not be read back; computed again.
    """

    todo: list
    n_done: int
    n_new: int
    n_retried: int
    n_kept_failed: int
    n_unreadable: int

    def describe(self) -> str:
        """One line, e.g. ``"12 done, 84 to run (81 new, 3 failed before and retried)"``."""
        parts = [f"{self.n_new} new"]
        if self.n_retried:
            parts.append(f"{self.n_retried} failed before and retried")
        if self.n_unreadable:
            parts.append(f"{self.n_unreadable} unreadable and recomputed")
        text = f"{self.n_done} done, {len(self.todo)} to run ({', '.join(parts)})"
        if self.n_kept_failed:
            text += f", {self.n_kept_failed} failed before and kept (--keep-failed; drop it to retry them)"
        return text


def plan_sweep(cells: list[Cell], stored: StoredCells, *, retry_failed: bool = True) -> SweepPlan:
    """Split a suite's cells by what the results folder holds.

    Parameters
    ----------
    cells : list of Cell
    stored : StoredCells
        From :meth:`ResultStore.scan`, taken while holding the folder.
    retry_failed : bool
        Compute cells whose row says ``failed`` again (the default); False skips them.

    Returns
    -------
    SweepPlan
    """
    todo, counts = [], dict(done=0, new=0, retried=0, kept=0, unreadable=0)
    for cell in cells:
        status = stored.status.get(cell.cell_id)
        if cell.cell_id in stored.unreadable:
            kind = "unreadable"
        elif status is None:
            kind = "new"
        elif status != STATUS_FAILED:
            kind = "done"
        else:
            kind = "retried" if retry_failed else "kept"
        counts[kind] += 1
        if kind not in ("done", "kept"):
            todo.append(cell)
    return SweepPlan(todo, counts["done"], counts["new"], counts["retried"], counts["kept"],
                     counts["unreadable"])


def _set_aside_unreadable(store: ResultStore, stored: StoredCells, cells: list[Cell]) -> None:
    """Report each unreadable cell file on one line and move it aside (cells of this sweep are recomputed)."""
    ours = {c.cell_id for c in cells}
    for i, (cell_id, why) in enumerate(sorted(stored.unreadable.items())):
        target = store.quarantine(cell_id)
        fate = "the cell is recomputed" if cell_id in ours else "not a cell of this sweep, so not recomputed"
        if i < MAX_LISTED_UNREADABLE:
            _note(f"cells/{cell_id}.json {why}; moved to {target.name}, {fate}.")
    hidden = len(stored.unreadable) - MAX_LISTED_UNREADABLE
    if hidden > 0:
        _note(f"... and {hidden} more unreadable cell files, moved aside (see cells/*.unreadable).")


def _cell_labels(cells: list[Cell]) -> dict[str, str]:
    """Cell id -> the report's variant label (``"ocp [energy=paper]"``) within this sweep."""
    if not cells:
        return {}
    frame = pd.DataFrame([{"method": c.method, "params": c.params_json} for c in cells])
    return dict(zip((c.cell_id for c in cells), variant_labels(frame)))


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
              progress: bool = True, diagnostics: bool = True, isolate: bool = False,
              retry_failed: bool = True, wait: bool = False,
              then: Callable[[pd.DataFrame], None] | None = None) -> pd.DataFrame:
    """Run the cells of ``suite`` that ``results_dir`` does not hold finished yet.

    Each finished cell is written at once (see :class:`parambench.bench.storage.ResultStore`); a
    failing cell is recorded with its error and the sweep goes on. A one-line plan and a
    line per unreadable cell file go to stderr before the first cell runs.

    Parameters
    ----------
    suite : Suite
    results_dir : str
        Created if missing (after every check has passed).
    scheduler : str, optional
        Address of an existing Dask distributed scheduler.
    workers : int, optional
        Start a local Dask cluster with this many single-threaded workers (>= 1).
    progress : bool
        Show a progress bar on stderr.
    diagnostics : bool
        Also store per-surface weight histograms and detected boundaries for the report.
    isolate : bool
        Run each cell in a fresh process (in-process runs only) and record its peak
        resident memory as ``peak_rss_mb``; costs an interpreter start per cell.
    retry_failed : bool
        Compute cells stored as ``failed`` again (default). False skips them.
    wait : bool
        When another sweep holds ``results_dir``, wait for it instead of refusing.
    then : callable, optional
        Called with the consolidated table while the folder is still held (the command
        line builds the report there, so a sweep waiting for the folder starts after it).

    Returns
    -------
    pandas.DataFrame
        All readable rows in the results directory (old and new), also written to
        ``results.parquet`` and ``results.csv``.

    Raises
    ------
    UnknownNameError, TooFewPointsError, InvalidInputError
        Bad suite fields or ``workers`` (see :func:`parambench.bench.suites.validate_suite`); raised
        before anything is created.
    InputFileError
        ``results_dir`` cannot be created or written; raised before anything is created.
    ResultsInUseError
        Another sweep holds ``results_dir`` and ``wait`` is False.
    """
    check_workers(workers)
    cells = expand_cells(suite)
    store = ResultStore(check_output_dir(results_dir))
    with hold_folder(store.root, wait=wait,
                     on_wait=lambda holder: _note(f"{results_dir} is in use ({holder}); waiting for it.")):
        store.remove_stale_temporaries()
        stored = store.scan()
        _set_aside_unreadable(store, stored, cells)
        plan = plan_sweep(cells, stored, retry_failed=retry_failed)
        _note(plan.describe())
        real_note = real_dataset_note(suite)
        if real_note:
            _note(real_note)
        store.write_metadata(run_metadata(
            suite=suite.name, parameters=asdict(suite), seeds=list(suite.seeds), n_cells=len(cells),
            n_skipped=len(cells) - len(plan.todo), n_retried=plan.n_retried, n_unreadable=plan.n_unreadable,
            scheduler=scheduler or (f"local-dask:{workers}" if workers else "in-process")))
        _run_cells(store, plan.todo, _cell_labels(cells), suite.name, scheduler=scheduler, workers=workers,
                   isolate=isolate, progress=progress)
        if diagnostics:
            for problem in store_missing_diagnostics(store, cells):
                _note(f"note: no surface diagnostics for {problem}")
        table = store.consolidate()
        if then is not None:
            then(table)
        return table


def _run_cells(store: ResultStore, todo: list[Cell], labels: dict[str, str], name: str, *,
               scheduler: str | None, workers: int | None, isolate: bool, progress: bool) -> None:
    if not todo:
        return
    if scheduler or workers:
        results: Iterable = _dask(todo, scheduler, workers)
    elif isolate:
        results = _isolated(todo)
    else:
        results = _serial(todo)
    bar = tqdm(total=len(todo), desc=f"parambench {name}", unit="cell", disable=not progress, file=sys.stderr)
    with bar:
        for row, arrays in results:
            store_cell(store, row, arrays)
            label = labels.get(row["cell_id"], row["method"])
            bar.set_postfix_str(f"{row['dataset']} {label} {row['status']}", refresh=False)
            bar.update(1)


#: Appended to a summary figure whose mean includes a ``suspect`` cell.
SUSPECT_MARK = "*"


def _qc_pivot(mapped: pd.DataFrame) -> pd.DataFrame:
    """Mean QC per variant and dataset as text, ``SUSPECT_MARK`` where a suspect cell is in
    the mean, ``-`` where no cell has a map."""
    qc = mapped.pivot_table(index="variant", columns="dataset", values="qc_mean", aggfunc="mean", dropna=False)
    flag = (mapped.assign(_suspect=mapped["status"] == STATUS_SUSPECT)
            .pivot_table(index="variant", columns="dataset", values="_suspect", aggfunc="any", dropna=False)
            .reindex(index=qc.index, columns=qc.columns))
    text = qc.copy().astype(object)
    for i in range(qc.shape[0]):
        for j in range(qc.shape[1]):
            v = qc.iat[i, j]
            marked = bool(flag.iat[i, j]) if pd.notna(flag.iat[i, j]) else False
            text.iat[i, j] = "-" if pd.isna(v) else f"{v:.3f}" + (SUSPECT_MARK if marked else "")
    return text


def _where(row) -> str:
    """A cell's surface in a summary line: dataset, size, sampling, noise, seed (so two lines differ)."""
    parts = [str(row["dataset"])]
    if pd.notna(row.get("size")) and row.get("size"):
        parts.append(f"{int(row['size'])} pts")
    if isinstance(row.get("sampling"), str) and row["sampling"]:
        parts.append(row["sampling"])
    if pd.notna(row.get("noise")) and row.get("noise"):
        parts.append(f"noise {float(row['noise']):g}")
    if pd.notna(row.get("seed")):
        parts.append(f"seed {int(row['seed'])}")
    return " · ".join(parts)


def summary_table(table: pd.DataFrame) -> str:
    """A compact text table for the terminal: per method variant, mean QC per dataset plus failures.

    Variants are labelled as in the report (``"ocp [energy=paper]"``, see
    :func:`parambench.reports.labels.variant_labels`). Means cover ``ok`` and ``suspect`` cells (maps
    that failed their self-check still have metrics); a figure that includes a suspect
    cell is marked ``SUSPECT_MARK`` and the suspect cells are counted per variant and
    listed; ``failed`` cells are counted and listed.

    Parameters
    ----------
    table : pandas.DataFrame
        Result rows (as returned by :func:`run_sweep`).

    Returns
    -------
    str
    """
    if table.empty:
        return "no results"
    table = table.assign(variant=variant_labels(table))
    ok = table[table["status"] == STATUS_OK]
    # Suspect cells have a map and metrics: shown, marked, never mixed in silently.
    mapped = table[table["status"].isin([STATUS_OK, STATUS_SUSPECT])]
    lines = []
    if not mapped.empty:
        lines.append("QC distortion (area-weighted mean; 1 is conformal; "
                     f"{SUSPECT_MARK} includes suspect cells, maps that failed their self-check):")
        lines.append(_qc_pivot(mapped).to_string())
        folds = mapped.groupby("variant")["foldovers"].sum().astype(int)
        times = mapped.groupby("variant")["time_total"].median()
        suspect = (mapped["status"] == STATUS_SUSPECT).groupby(mapped["variant"]).sum().astype(int)
        lines.append("")
        lines.append(pd.DataFrame({"foldovers (sum)": folds, "median time (s)": times.round(3),
                                   "suspect cells": suspect})
                     .rename_axis("variant").to_string())
    failed = table[table["status"] == STATUS_FAILED]
    others = table[~table["status"].isin([STATUS_OK, STATUS_FAILED])]
    lines.append("")
    counts = [f"{len(ok)} ok"]
    counts += [f"{n} {status}" for status, n in others["status"].value_counts().sort_index().items()]
    counts.append(f"{len(failed)} failed")
    lines.append(f"{', '.join(counts)} of {len(table)} cells")
    for _, r in others.head(10).iterrows():
        why = r.get("error")
        why = f": {str(why)[:150]}" if isinstance(why, str) and why else ""
        lines.append(f"  {str(r['status']).upper()} {_where(r)} / {r['variant']}{why}")
    if len(others) > 10:
        lines.append(f"  ... and {len(others) - 10} more (see results.csv)")
    for _, r in failed.head(10).iterrows():
        lines.append(f"  FAILED {_where(r)} / {r['variant']}: {r['error_type']}: {str(r['error'])[:150]}")
    if len(failed) > 10:
        lines.append(f"  ... and {len(failed) - 10} more (see results.csv)")
    if len(failed):
        lines.append("  (a rerun of the same command retries failed cells; --keep-failed skips them)")
    return "\n".join(lines)
