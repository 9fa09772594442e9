"""The report's tables, as data (:class:`Table`); :mod:`parambench.reports.html` renders them.

Seeds are repeats: a summary row is one (configuration, method variant) and shows the
median over its ok seeds. Every metric is "lower is better" (QC >= 1 with 1 conformal,
foldovers, area distortion, exact-map error, time); the best value of each column within a
configuration is marked among the acceptable maps only (:data:`ACCEPTABLE_RULE`, printed under
the tables), when at least two of them have a value. Failed cells keep their row, with a
short error text in the status column; the failures table gives each message once, in full,
with the cells it hit. "Suspect" cells (a point-set map that failed its self-check) have metrics:
they count in the medians, are named in the status column and listed in their own table.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from .labels import CONFIG_COLUMNS

__all__ = [
    "Cell",
    "Table",
    "SUMMARY_METRICS",
    "summarise",
    "best_mask",
    "acceptable_mask",
    "QC_BOUND",
    "ACCEPTABLE_RULE",
    "summary_tables",
    "overview_table",
    "failures_table",
    "suspect_table",
    "MEASURED_STATUSES",
    "metadata_table",
    "benchmark_table",
    "exponent_table",
    "stage_memory_table",
    "format_number",
    "SUSPECT_MARK",
]

#: Statuses of cells whose metrics were computed ("suspect": the map failed its self-check).
MEASURED_STATUSES = ("ok", "suspect")
#: QC mean of an acceptable map: at most this factor times the best foldover-free QC of its surface.
QC_BOUND = 1.10

#: The rule behind "acceptable" and "best", printed under the tables that use it.
ACCEPTABLE_RULE = (
    f"Shading rule: a value is shaded best only among acceptable maps, those with every seed measured and passing "
    f"its self-check (not suspect, not failed), no foldovers, and QC mean within {round((QC_BOUND - 1) * 100)} % of "
    f"the lowest QC mean among the foldover-free, self-check-passing maps of the same surface. A value of an "
    f"unacceptable map is never shaded, however low (an affine stretch has near-zero area distortion).")

#: (column, header, kind) of the summary's metric columns; all lower-is-better.
SUMMARY_METRICS = (
    ("qc_mean", "QC mean", "ratio"),
    ("qc_p95", "QC p95", "ratio"),
    ("qc_max", "QC max", "ratio"),
    ("foldovers", "Foldovers", "count"),
    ("area_distortion", "Area dist.", "ratio"),
    ("exact_error", "Exact-map err.", "small"),
    ("time_total", "Time (s)", "time"),
)

_ERROR_SHORT = 300  # characters of an error shown in the overview's tooltips; the failures table has all of it
_STATUS_SHORT = 60  # characters of a summary row's status; the full text is its tooltip
_MISSING = "—"
#: Appended to an overview figure that includes a suspect cell (the terminal summary's mark).
SUSPECT_MARK = "*"


@dataclass
class Cell:
    """One table cell: its text, CSS classes and a tooltip."""

    text: str
    classes: tuple = ()
    title: str = ""


@dataclass
class Table:
    """A table ready to render.

    Attributes
    ----------
    columns : list of str
        Header texts.
    rows : list of list of Cell
        Body rows, each as long as ``columns``.
    caption : str
    css_class : str
        Class of the ``<table>`` element (tests count rows per class).
    numeric : set of int
        Indices of right-aligned columns.
    row_keys : list of dict, optional
        Per body row, data attributes for the HTML page (``{"config": ..., "variant": ...}``
        lets a click on the row open that cell's pictures).
    interactive : bool
        Sortable by a click on a header and filterable by a search box (in the HTML).
    note : str
        A line printed under the table (e.g. the shading rule).
    """

    columns: list
    rows: list
    caption: str = ""
    css_class: str = ""
    numeric: set = field(default_factory=set)
    row_keys: list = field(default_factory=list)
    interactive: bool = True
    note: str = ""


def format_number(value, kind: str = "ratio") -> str:
    """Text for a metric value; NaN and None give an em dash.

    ``kind`` is "ratio" (4 significant digits), "count" (an integer when it is one),
    "small" (3 significant digits, scientific when tiny) or "time" (3 significant digits).
    """
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return _MISSING
    value = float(value)
    if kind == "count":
        return f"{int(round(value))}" if float(value).is_integer() else f"{value:.1f}"
    if kind == "small":
        return f"{value:.3g}"
    if kind == "time":
        return f"{value:.3g}"
    return f"{value:.4g}"


def _short(text: str, limit: int = _ERROR_SHORT) -> str:
    text = " ".join(str(text).split())
    return text if len(text) <= limit else text[: limit - 1] + "…"


def _error_text(error_type: str, error: str) -> str:
    if error_type and error:
        return f"{error_type}: {error}"
    return error_type or error or "failed (no error text recorded)"


def _status(group: pd.DataFrame) -> tuple[str, bool, bool]:
    measured = group["status"].isin(MEASURED_STATUSES)
    suspect = group["status"] == "suspect"
    n_measured, n, n_suspect = int(measured.sum()), len(group), int(suspect.sum())
    failed = group[~measured]
    errors = list(dict.fromkeys(_error_text(t, e) for t, e in zip(failed["error_type"], failed["error"])))
    collapsed = bool((group.loc[measured, "collapsed"].fillna(0) > 0).any())
    reasons = " | ".join(_short(e) for e in dict.fromkeys(group.loc[suspect, "error"].fillna("")) if e)
    suspect_text = (f"suspect: {n_suspect} of {n} seeds fail the self-check" + (f": {reasons}" if reasons else "")
                    if n_suspect else "")
    if n_measured == n:
        if n_suspect:
            return suspect_text, False, True
        return ("ok (collapsed)" if collapsed else "ok"), False, False
    text = "failed: " if n_measured == 0 else f"{n - n_measured} of {n} seeds failed: "
    text += " | ".join(_short(e) for e in errors)
    return text + (f"; {suspect_text}" if n_suspect else ""), True, bool(n_suspect)


def summarise(rows: pd.DataFrame) -> pd.DataFrame:
    """One row per (configuration, variant): medians over measured (ok or suspect) seeds and a status text.

    Parameters
    ----------
    rows : pandas.DataFrame
        Labelled rows (see :func:`parambench.reports.labels.add_labels`).

    Returns
    -------
    pandas.DataFrame
        Columns: the configuration columns, ``config``, ``variant``, ``method``,
        ``n_cells``, ``n_ok``, ``n_suspect``, ``n_points`` and the :data:`SUMMARY_METRICS`
        columns (NaN when no seed is measured), ``status`` (text), ``has_failure`` and
        ``has_suspect`` (bool); sorted by configuration then variant.
    """
    metric_cols = [m[0] for m in SUMMARY_METRICS]
    keys = [*CONFIG_COLUMNS, "config", "variant"]
    out = []
    for key, group in rows.groupby(keys, sort=True, dropna=False):
        ok = group[group["status"].isin(MEASURED_STATUSES)]
        record = dict(zip(keys, key))
        record["method"] = group["method"].iloc[0]
        record["n_cells"] = len(group)
        record["n_suspect"] = int((group["status"] == "suspect").sum())
        record["n_ok"] = len(ok) - record["n_suspect"]
        record["n_points"] = float(group["n_points"].median()) if group["n_points"].notna().any() else np.nan
        for col in metric_cols:
            values = ok[col].dropna()
            record[col] = float(values.median()) if len(values) else np.nan
        record["status"], record["has_failure"], record["has_suspect"] = _status(group)
        out.append(record)
    return pd.DataFrame(out, columns=[*keys, "method", "n_cells", "n_ok", "n_suspect", "n_points", *metric_cols,
                                      "status", "has_failure", "has_suspect"])


def acceptable_mask(summary: pd.DataFrame, by: str = "config") -> pd.Series:
    """Which summary rows are acceptable maps (see :data:`ACCEPTABLE_RULE`).

    Parameters
    ----------
    summary : pandas.DataFrame
        Output of :func:`summarise`.
    by : str
        The column whose groups are compared (one surface configuration each).

    Returns
    -------
    pandas.Series of bool, aligned with ``summary``.
    """
    clean = ((summary["n_ok"] == summary["n_cells"]) & (summary["foldovers"].fillna(np.inf) == 0)
             & summary["qc_mean"].notna())
    best = summary["qc_mean"].where(clean).groupby(summary[by]).transform("min")
    return clean & (summary["qc_mean"] <= QC_BOUND * best)


def best_mask(summary: pd.DataFrame, by: str = "config") -> pd.DataFrame:
    """Where each metric column reaches its minimum among the acceptable maps of each group.

    Parameters
    ----------
    summary : pandas.DataFrame
        Output of :func:`summarise`.
    by : str
        Grouping column; the best value is marked within each group.

    Returns
    -------
    pandas.DataFrame of bool
        Same index as ``summary``, one column per metric. Only acceptable rows
        (:func:`acceptable_mask`) are candidates; a column of a group is marked only when at
        least two of them have a value; values that print the same as the minimum (see
        :func:`format_number`) are all marked.
    """
    mask = pd.DataFrame(False, index=summary.index, columns=[m[0] for m in SUMMARY_METRICS])
    acceptable = acceptable_mask(summary, by)
    for _, group in summary[acceptable].groupby(by, sort=False):
        for col, _, kind in SUMMARY_METRICS:
            values = group[col].dropna()
            if len(values) < 2:
                continue
            # Ties as the reader sees them: every value that prints like the minimum.
            shown = values.map(lambda v, k=kind: format_number(v, k))
            mask.loc[values.index[shown == format_number(values.min(), kind)], col] = True
    return mask


def summary_tables(summary: pd.DataFrame) -> dict[str, Table]:
    """One summary table per configuration, rows = method variants.

    Parameters
    ----------
    summary : pandas.DataFrame
        Output of :func:`summarise`.

    Returns
    -------
    dict of str to Table
        Keyed by the configuration label, in the summary's order.
    """
    mask = best_mask(summary)
    columns = ["Method", "Seeds ok", *[m[1] for m in SUMMARY_METRICS], "Status"]
    tables: dict[str, Table] = {}
    for config, group in summary.groupby("config", sort=False):
        body, keys = [], []
        for idx, rec in group.iterrows():
            keys.append({"config": str(config), "variant": str(rec["variant"])})
            row = [Cell(str(rec["variant"]), ("method",)),
                   Cell(f"{int(rec['n_ok'])}/{int(rec['n_cells'])}")]
            for col, _, kind in SUMMARY_METRICS:
                best = bool(mask.at[idx, col])
                row.append(Cell(format_number(rec[col], kind), ("best",) if best else (),
                                "best in this table" if best else ""))
            status_class = (("status", "failed") if rec["has_failure"] else
                            ("status", "suspect") if rec["has_suspect"] else ("status", "ok"))
            status = str(rec["status"])
            row.append(Cell(_short(status, _STATUS_SHORT), status_class, status if len(status) > _STATUS_SHORT else ""))
            body.append(row)
        n_points = group["n_points"].median()
        caption = str(config) + ("" if n_points != n_points else f" — {int(n_points)} points")
        tables[str(config)] = Table(columns, body, caption, "summary",
                                    numeric=set(range(1, 2 + len(SUMMARY_METRICS))), row_keys=keys)
    return tables


def overview_table(summary: pd.DataFrame) -> Table:
    """Method variants x datasets at a glance: median QC mean, failures counted, suspect figures marked.

    A dataset's value is the median, over its configurations (sizes, samplings, noise),
    of the per-configuration medians; the lowest value of each column among the variants
    acceptable on every configuration of the dataset is marked when at least two have one.
    A value that includes a suspect cell (a map that failed its self-check) ends in
    :data:`SUSPECT_MARK`, as in the terminal summary, and says so in its tooltip.

    Parameters
    ----------
    summary : pandas.DataFrame
        Output of :func:`summarise`.
    """
    datasets = list(dict.fromkeys(summary["dataset"]))
    variants = sorted(dict.fromkeys(summary["variant"]))
    summary = summary.assign(_acceptable=acceptable_mask(summary))
    cells: dict = {}
    for (dataset, variant), group in summary.groupby(["dataset", "variant"], sort=False):
        values = group["qc_mean"].dropna()
        cells[(dataset, variant)] = {
            "value": float(values.median()) if len(values) else np.nan,
            "n_failed": int((group["n_cells"] - group["n_ok"] - group["n_suspect"]).sum()),
            "n_suspect": int(group["n_suspect"].sum()), "n_cells": int(group["n_cells"].sum()),
            "errors": "; ".join(dict.fromkeys(s for s, f in zip(group["status"], group["has_failure"]) if f)),
            "acceptable": bool(group["_acceptable"].all())}
    best = {}
    for dataset in datasets:
        values = [cells[(dataset, v)]["value"] for v in variants
                  if (dataset, v) in cells and cells[(dataset, v)]["acceptable"]]
        values = [v for v in values if v == v]
        best[dataset] = min(values) if len(values) >= 2 else None
    body = []
    for variant in variants:
        row = [Cell(variant, ("method",))]
        for dataset in datasets:
            cell = cells.get((dataset, variant))
            row.append(Cell("·", ("absent",), "not run") if cell is None else _overview_cell(cell, best[dataset]))
        body.append(row)
    caption = "Median QC mean per method and dataset (1 = conformal)"
    if any(c["n_suspect"] and c["value"] == c["value"] for c in cells.values()):
        caption += f"; {SUSPECT_MARK} = includes suspect cells, maps that failed their self-check"
    return Table(["Method", *datasets], body, caption, "overview", numeric=set(range(1, 1 + len(datasets))))


def _overview_cell(cell: dict, best: float | None) -> Cell:
    """One overview figure: failures counted in the text, suspect cells marked like the terminal summary's."""
    value, n_failed, n_suspect = cell["value"], cell["n_failed"], cell["n_suspect"]
    errors = _short(cell["errors"], 200)
    if value != value:
        return Cell("failed" if n_failed else _MISSING, ("failed",) if n_failed else (), errors)
    text = format_number(value, "ratio")
    is_best = cell["acceptable"] and best is not None and text == format_number(best, "ratio")
    classes = ["best"] if is_best else []
    titles = [errors] if errors else []
    if n_suspect:
        # The figure includes maps that failed their self-check: never shown as a plain number.
        text += SUSPECT_MARK
        classes.append("suspect")
        titles.insert(0, f"{SUSPECT_MARK} {n_suspect} of {cell['n_cells']} cells suspect: their maps failed the "
                         "self-check and are included in this median")
    if n_failed:
        text += f" ({n_failed} of {cell['n_cells']} failed)"
        classes.append("partial")
    return Cell(text, tuple(classes), " | ".join(titles))


def _cell_names(group: pd.DataFrame, limit: int = 12) -> str:
    names = [f"{c} / {v}" + (f" (seed {int(sd)})" if sd == sd and sd else "")
             for c, v, sd in zip(group["config"], group["variant"], group["seed"])]
    return "; ".join(names[:limit]) + (f"; and {len(names) - limit} more" if len(names) > limit else "")


def failures_table(rows: pd.DataFrame) -> Table:
    """Failed cells grouped by their error text: each message once, with the cells it hit.

    Parameters
    ----------
    rows : pandas.DataFrame
        Labelled rows.
    """
    failed = rows[~rows["status"].isin(MEASURED_STATUSES)].sort_values(["config", "variant", "seed"], kind="stable")
    failed = failed.assign(_message=[_error_text(t, e) for t, e in zip(failed["error_type"], failed["error"])])
    body = []
    for message, group in failed.groupby("_message", sort=False):
        body.append([Cell(message, ("error",)), Cell(str(len(group))), Cell(_cell_names(group))])
    return Table(["Error", "Cells", "Where (surface / method)"], body,
                 f"{len(failed)} failed cell(s), {len(body)} distinct error(s)", "failures", numeric={1})


def suspect_table(rows: pd.DataFrame) -> Table:
    """Suspect cells (their map failed the self-check) grouped by the checks that failed.

    Parameters
    ----------
    rows : pandas.DataFrame
        Labelled rows.
    """
    suspect = rows[rows["status"] == "suspect"].sort_values(["config", "variant", "seed"], kind="stable")

    def failed_checks(diagnostics: str, error: str) -> str:
        check = (json.loads(diagnostics) if diagnostics else {}).get("selfcheck") or {}
        kinds = check.get("failed") or []
        return ", ".join(kinds) if kinds else _short(error or "self-check failed", 80)

    suspect = suspect.assign(_kind=[failed_checks(d, e) for d, e in zip(suspect["diagnostics"], suspect["error"])])
    body = []
    for kind, group in suspect.groupby("_kind", sort=False):
        details = "; ".join(f"{v} on {c}: {_short(e, 90)}" for c, v, e in
                            zip(group["config"], group["variant"], group["error"]))
        body.append([Cell(kind, ("key",)), Cell(str(len(group))), Cell(details, ("error",))])
    return Table(["Failed checks", "Cells", "Cells and the self-check's words"], body,
                 f"{len(suspect)} suspect cell(s): metrics computed, but the map failed its self-check",
                 "suspects", numeric={1})


def _meta_value(value) -> str:
    if isinstance(value, dict):
        # One line of key=value pairs: the run's parameters printed one token per line filled a page.
        return "; ".join(f"{k}={_meta_value(v)}" for k, v in value.items() if v not in (None, [], {}, ""))
    if isinstance(value, list):
        return ", ".join(_meta_value(v) if isinstance(v, (dict, list)) else str(v) for v in value) or _MISSING
    return _MISSING if value is None or value == "" else str(value)


def metadata_table(run: dict) -> Table:
    """Run metadata: version, commit, machine, date, command, suite, parameters, seeds.

    Parameters
    ----------
    run : dict
        Contents of ``run.json`` (may be empty or partial).
    """
    machine = run.get("machine") or {}
    if not isinstance(machine, dict):
        machine = {"description": machine}
    items = [
        ("Package version", run.get("package_version")),
        ("Git commit", run.get("git_commit")),
        ("Date", run.get("date")),
        ("Command", run.get("command")),
        ("Suite", run.get("suite")),
        ("Machine", ", ".join(f"{k}: {machine[k]}" for k in ("hostname", "platform", "python", "cpu_count",
                                                             "memory_gb") if k in machine)
         or _meta_value(machine or None)),
        ("Seeds", ", ".join(str(s) for s in run["seeds"]) if isinstance(run.get("seeds"), list)
         else run.get("seeds")),
        ("Parameters", run.get("parameters")),
    ]
    known = {"package_version", "git_commit", "date", "command", "suite", "machine", "seeds", "parameters"}
    items += [(k.replace("_", " ").capitalize(), v) for k, v in sorted(run.items()) if k not in known]
    body = [[Cell(k, ("key",)), Cell(_meta_value(v))] for k, v in items]
    return Table(["Item", "Value"], body, "", "metadata", interactive=False)


def benchmark_table(stats: pd.DataFrame) -> Table:
    """pytest-benchmark statistics, one row per benchmark.

    Parameters
    ----------
    stats : pandas.DataFrame
        Output of :func:`parambench.reports.benchmarks.load_benchmarks`.
    """
    cols = [("min", "Min (s)"), ("median", "Median (s)"), ("mean", "Mean (s)"), ("stddev", "Std dev (s)"),
            ("max", "Max (s)")]
    body = []
    for r in stats.itertuples():
        row = [Cell(str(r.group) or _MISSING), Cell(str(r.name), ("method",))]
        row += [Cell(format_number(getattr(r, c), "time")) for c, _ in cols]
        row += [Cell(format_number(r.rounds, "count")), Cell(_short(r.extra, 160))]
        body.append(row)
    return Table(["Group", "Benchmark", *[h for _, h in cols], "Rounds", "Extra info"], body,
                 "pytest-benchmark statistics", "benchmarks", numeric=set(range(2, 8)))


def _family(dataset, sampling, noise) -> str:
    """Label of a surface family: "bump · jittered", with " · noise 0.1" when noisy."""
    label = " · ".join(str(x) for x in (dataset, sampling) if x)
    return label + (f" · noise {noise:g}" if noise and not (isinstance(noise, float) and math.isnan(noise)) else "")


def exponent_table(fits: pd.DataFrame) -> Table:
    """Fitted exponents p of time = c * points**p, one row per surface family and variant.

    Parameters
    ----------
    fits : pandas.DataFrame
        Output of :func:`parambench.reports.figures.scaling.scaling_fits`.
    """
    body = []
    for r in fits.itertuples():
        body.append([Cell(_family(r.dataset, r.sampling, r.noise)), Cell(str(r.variant), ("method",)), Cell(f"{r.exponent:.2f}"),
                     Cell(format_number(r.n_sizes, "count")),
                     Cell(f"{int(r.n_min)}–{int(r.n_max)}")])
    return Table(["Surface", "Method", "Exponent p", "Sizes", "Points"], body,
                 "Fitted exponents of time against points", "exponents", numeric={2, 3, 4})


#: Stage columns of :func:`stage_memory_table`, in pipeline order; others follow sorted.
_STAGE_ORDER = ("knn", "normals", "dem", "weights", "boundary", "laplacian", "topology", "weights_mesh", "solve",
                "other")


def stage_memory_table(rows: pd.DataFrame) -> Table | None:
    """Peak resident memory per stage, for each method at the largest size of each surface.

    Parameters
    ----------
    rows : pandas.DataFrame
        Labelled rows with ``stage_memory_mb`` (canonical JSON of stage -> MiB).

    Returns
    -------
    Table or None
        None when no ok cell recorded stage memory (results from older versions).
    """
    ok = rows[(rows["status"] == "ok") & (rows["stage_memory_mb"].fillna("{}") != "{}")]
    if ok.empty:
        return None
    ok = ok.assign(n=ok["n_points"].where(ok["n_points"] > 0, ok["size"]))
    picked = ok.sort_values("n").groupby(["dataset", "sampling", "noise", "variant"], sort=True).tail(1)
    memories = [json.loads(v) for v in picked["stage_memory_mb"]]
    seen = set().union(*memories)
    stages = [s for s in _STAGE_ORDER if s in seen] + sorted(seen - set(_STAGE_ORDER))
    body = []
    order = np.lexsort((picked["variant"].to_numpy(), picked["dataset"].to_numpy()))
    for i in order:
        r = picked.iloc[i]
        mem = memories[i]
        body.append([Cell(_family(r["dataset"], r["sampling"], r["noise"])), Cell(str(r["variant"]), ("method",)), Cell(format_number(r["n"], "count"))]
                    + [Cell(f"{mem[s]:.0f}" if s in mem else _MISSING) for s in stages]
                    + [Cell(f"{max(mem.values()):.0f}")])
    return Table(["Surface", "Method", "Points", *stages, "Peak"], body,
                 "Peak resident memory (MiB, whole process) while each stage ran, at the largest size "
                 "(a cell's own figures with parambench run --isolate)", "stage-memory",
                 numeric=set(range(2, len(stages) + 4)))
