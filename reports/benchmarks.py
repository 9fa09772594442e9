"""Read pytest-benchmark JSON files (``pytest --benchmark-json=FILE``)."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pandas as pd

from parambench.datasets_gen.errors import InputFileError

__all__ = ["BENCHMARK_COLUMNS", "load_benchmarks"]

BENCHMARK_COLUMNS = ("source", "group", "name", "min", "max", "mean", "stddev", "median", "rounds", "extra")
_STATS = ("min", "max", "mean", "stddev", "median", "rounds")


def load_benchmarks(paths) -> pd.DataFrame:
    """Statistics of every benchmark in the given files.

    Parameters
    ----------
    paths : iterable of str or path-like
        pytest-benchmark JSON files.

    Returns
    -------
    pandas.DataFrame
        Columns :data:`BENCHMARK_COLUMNS`: ``source`` is the file name, ``group`` "" when
        the benchmark has none, the statistics are float seconds (``rounds`` a count),
        ``extra`` the ``extra_info`` dict as compact JSON. Sorted by group then median.

    Raises
    ------
    InputFileError
        A file is missing, is not JSON, or has no ``benchmarks`` list.
    """
    records = []
    for path in map(Path, paths):
        try:
            data = json.loads(path.read_text())
        except (OSError, UnicodeDecodeError, ValueError) as exc:
            raise InputFileError(
                f"Benchmark file {path} is not readable JSON ({exc}); pass a file written by "
                f"`pytest --benchmark-json=FILE`.") from exc
        benchmarks = data.get("benchmarks") if isinstance(data, dict) else None
        if not isinstance(benchmarks, list):
            raise InputFileError(
                f"Benchmark file {path} has no 'benchmarks' list; pass a file written by "
                f"`pytest --benchmark-json=FILE`.")
        for bench in benchmarks:
            stats = bench.get("stats") or {}
            record = {"source": os.path.basename(path), "group": bench.get("group") or "",
                      "name": bench.get("name") or bench.get("fullname") or "?"}
            for key in _STATS:
                value = stats.get(key)
                record[key] = float(value) if isinstance(value, (int, float)) else float("nan")
            record["extra"] = json.dumps(bench.get("extra_info") or {}, sort_keys=True, default=str)
            records.append(record)
    frame = pd.DataFrame.from_records(records, columns=list(BENCHMARK_COLUMNS))
    return frame.sort_values(["group", "median", "name"], kind="stable").reset_index(drop=True)
