"""The report section of the scaling benchmark (``bench/benchmarks/bench_scaling.py``), side by side.

That benchmark times each method end to end on the same jittered bump at each size and
stores, in ``extra_info``, the seconds and peak resident memory of every stage and the
ratio of the whole run to ``scp-igl`` on the ground-truth mesh, timed in the same process
(issue 14, "Done when" 5). This module lays the runs out per size: one row per method,
its total, its ratio to ``scp-igl`` and peak memory, and its stages.
"""

from __future__ import annotations

import json
import math

import pandas as pd

from .html import Note, Section
from .tables import Cell, Table, format_number

__all__ = ["METHOD_KEY", "SCALING_COLUMNS", "scaling_benchmark_rows", "scaling_benchmark_table",
           "scaling_benchmark_section"]

#: extra_info key that marks a run of the scaling benchmark (the variant's name).
METHOD_KEY = "scaling_method"

#: Columns of :func:`scaling_benchmark_rows`.
SCALING_COLUMNS = ("n_points", "method", "seconds", "time_ratio_vs_scp_igl", "peak_rss_mb", "stages")


def _number(value) -> float:
    """A JSON value as float; None, text and non-finite values give NaN."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return math.nan
    return float(value) if math.isfinite(value) else math.nan


def scaling_benchmark_rows(stats: pd.DataFrame) -> pd.DataFrame:
    """The scaling benchmark's runs, one row each, sorted by size then time.

    Parameters
    ----------
    stats : pandas.DataFrame
        Output of :func:`parambench.reports.benchmarks.load_benchmarks`; benchmarks
        without :data:`METHOD_KEY` in their ``extra_info`` are left out.

    Returns
    -------
    pandas.DataFrame
        Columns :data:`SCALING_COLUMNS`: ``n_points`` int, ``method`` the variant,
        ``seconds`` the benchmark's minimum, ``time_ratio_vs_scp_igl`` and ``peak_rss_mb``
        floats (NaN where missing), ``stages`` a list of (stage, seconds, peak MB) by stage
        name (the loaded ``extra`` is key-sorted; ``total`` is one of them), peak MB NaN
        where the run stored none.
    """
    records = []
    for row in stats.itertuples():
        try:
            extra = json.loads(row.extra)
        except (TypeError, ValueError):
            continue
        if not isinstance(extra, dict) or METHOD_KEY not in extra:
            continue
        timings = extra.get("stage_timings") if isinstance(extra.get("stage_timings"), dict) else {}
        peaks = extra.get("stage_peak_rss_mb") if isinstance(extra.get("stage_peak_rss_mb"), dict) else {}
        stages = [(str(name), _number(sec), _number(peaks.get(name))) for name, sec in timings.items()]
        n_points = _number(extra.get("n_points"))
        records.append({"n_points": -1 if math.isnan(n_points) else int(n_points),
                        "method": str(extra[METHOD_KEY]), "seconds": _number(row.min),
                        "time_ratio_vs_scp_igl": _number(extra.get("time_ratio_vs_scp_igl")),
                        "peak_rss_mb": _number(extra.get("peak_rss_mb")), "stages": stages})
    frame = pd.DataFrame.from_records(records, columns=list(SCALING_COLUMNS))
    return frame.sort_values(["n_points", "seconds"], kind="stable").reset_index(drop=True)


def _stages_text(stages: list) -> str:
    parts = []
    for name, sec, peak in stages:
        memory = "" if math.isnan(peak) else f", {format_number(peak / 1024, 'time')} GB"
        parts.append(f"{name} {format_number(sec, 'time')} s{memory}")
    return "; ".join(parts) if parts else "—"


def scaling_benchmark_table(stats: pd.DataFrame) -> Table | None:
    """The runs as one report table (a row per size and method), or None when ``stats`` holds none."""
    rows = scaling_benchmark_rows(stats)
    if rows.empty:
        return None
    body = [[Cell(format_number(r.n_points, "count")), Cell(r.method, ("method",)),
             Cell(format_number(r.seconds, "time")), Cell(format_number(r.time_ratio_vs_scp_igl, "time")),
             Cell(format_number(r.peak_rss_mb / 1024, "time")), Cell(_stages_text(r.stages))]
            for r in rows.itertuples()]
    return Table(["Points", "Method", "Time (s)", "Time / scp-igl", "Peak RSS (GB)", "Stages: seconds, peak RSS"],
                 body, "Time and peak memory per stage, each method against scp-igl on the ground-truth mesh "
                 "timed in the same process", "scaling-benchmark", numeric={0, 2, 3, 4})


def scaling_benchmark_section(stats: pd.DataFrame | None) -> Section | None:
    """The side-by-side scaling section, or None when there is no scaling benchmark in ``stats``.

    Parameters
    ----------
    stats : pandas.DataFrame or None
        Output of :func:`parambench.reports.benchmarks.load_benchmarks` (None: no benchmark file).

    Returns
    -------
    Section or None
        A note with the sizes and methods covered, and :func:`scaling_benchmark_table`.
    """
    if stats is None:
        return None
    table = scaling_benchmark_table(stats)
    if table is None:
        return None
    rows = scaling_benchmark_rows(stats)
    sizes = ", ".join(format_number(n, "count") for n in sorted(rows["n_points"].unique()))
    note = Note(f"{len(rows)} run(s) at {sizes} points; methods: {', '.join(sorted(rows['method'].unique()))}. "
                "Peak memory is the process's resident set while the stage ran.")
    return Section("Time and memory per stage, side by side", [note, table], intro=(
        "From bench/benchmarks/bench_scaling.py: a jittered bump at each size, every method on the same "
        "points (point-set methods get positions only), ratios over scp-igl's time in the same process."))
