"""Names the report gives to groups of rows: method variants and dataset configurations.

A *variant* is a method with one parameter setting; its label names only the parameters
that vary between that method's rows (``"ocp [k=8]"``), so a sweep over one method's
grid reads clearly and a method run with one setting is just its name. A *configuration*
is a surface up to the seed: (dataset, size, sampling, noise). Seeds are repeats.
"""

from __future__ import annotations

import json
import math

import pandas as pd

from .load import parse_json_field

__all__ = ["CONFIG_COLUMNS", "add_labels", "variant_labels", "config_label", "format_param_value"]

#: Columns that identify a surface up to its seed.
CONFIG_COLUMNS = ("dataset", "size", "sampling", "noise")

# Parameters that repeat the seed column: never part of a variant's name.
_IGNORED_PARAMS = frozenset({"seed"})


def format_param_value(value) -> str:
    """Short text for a parameter value (``0.001`` -> ``"0.001"``, lists as JSON)."""
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, (list, dict)):
        return json.dumps(value, sort_keys=True)
    return str(value)


def variant_labels(rows: pd.DataFrame) -> pd.Series:
    """A label per row naming its method and the parameters that distinguish it.

    Parameters
    ----------
    rows : pandas.DataFrame
        Normalised rows (columns ``method`` and ``params``, a JSON object string).

    Returns
    -------
    pandas.Series of str, aligned with ``rows``.
    """
    parsed = rows["params"].map(lambda p: {k: v for k, v in (parse_json_field(p, {}) or {}).items()
                                            if k not in _IGNORED_PARAMS})
    labels = rows["method"].astype(str).copy()
    for method, index in rows.groupby("method", sort=False).groups.items():
        dicts = [parsed[i] for i in index]
        keys = sorted({k for d in dicts for k in d})
        varying = [k for k in keys
                   if len({json.dumps(d.get(k), sort_keys=True, default=str) for d in dicts}) > 1]
        if not varying:
            continue
        for i, d in zip(index, dicts):
            text = ", ".join(f"{k}={format_param_value(d[k])}" for k in varying if k in d)
            labels[i] = f"{method} [{text}]" if text else str(method)
    return labels


def config_label(dataset: str, size: float, sampling: str, noise: float) -> str:
    """Readable name of a configuration, e.g. ``"bump · 2000 pts · poisson · noise 0.1"``.

    Size 0 or NaN (real datasets), empty sampling and zero noise are left out.
    """
    parts = [str(dataset)]
    if size == size and size:
        parts.append(f"{int(size)} pts")
    if sampling:
        parts.append(str(sampling))
    if noise == noise and noise and not math.isclose(noise, 0.0):
        parts.append(f"noise {noise:g}")
    return " · ".join(parts)


def add_labels(rows: pd.DataFrame) -> pd.DataFrame:
    """Rows with two more columns: ``variant`` and ``config`` (see module doc).

    NaN size and noise are read as 0 so that real datasets group together.
    """
    df = rows.copy()
    df["size"] = df["size"].fillna(0.0)
    df["noise"] = df["noise"].fillna(0.0)
    df["variant"] = variant_labels(df)
    df["config"] = [config_label(d, s, m, n) for d, s, m, n in
                    zip(df["dataset"], df["size"], df["sampling"], df["noise"])]
    return df
