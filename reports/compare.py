"""Compare two results directories cell by cell (``parambench report A B``).

Typical use: the same suite run with two versions of a method. Cells are matched on what
identifies them (dataset, size, sampling, noise, seed, method, parameters), not on the file
name, so renamed or re-hashed cell files still match. Per matched cell the comparison gives
the QC mean, foldovers and time in A and in B; regressions (B worse than A) are listed first.

Regression rule (:data:`RULE`): B's status is worse (ok -> suspect -> failed), or B has
more foldovers, or B's QC mean is more than :data:`QC_TOL` higher (relative), or B takes
more than :data:`TIME_TOL` longer (relative) and at least :data:`TIME_FLOOR` seconds more.
Improvements are the mirror image (B better by the same factor: ratios are compared on a log
scale); everything else is unchanged.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd

from parambench.bench.storage import atomic_write_bytes

from .build import check_out_dir
from .html import Note, Section, render_report
from .labels import add_labels
from .load import load_results
from .tables import Cell, Table, format_number

__all__ = ["QC_TOL", "TIME_TOL", "TIME_FLOOR", "RULE", "compare_rows", "comparison_table", "build_comparison"]

QC_TOL = 0.005
TIME_TOL = 0.25
#: Seconds a time must change by to count: two runs of one command on this 2-core machine
#: differed by up to 0.11 s (x1.3) on cells of 0.3-0.5 s, all noise.
TIME_FLOOR = 0.2
RULE = (f"Regression: B's status is worse (ok → suspect → failed), B has more foldovers, B's QC mean is more than "
        f"{QC_TOL:.1%} higher, or B is more than {TIME_TOL:.0%} and {TIME_FLOOR:g} s slower; an improvement is the "
        f"mirror image. Time alone is noisy on a shared machine: read time-only regressions with care.")

_KEY = ["dataset", "size", "sampling", "noise", "seed", "method", "params"]
_STATUS_RANK = {"ok": 0, "suspect": 1}  # anything else is a failure: 2


def _rank(status: str) -> int:
    return _STATUS_RANK.get(status, 2) if status else 3  # "" = the cell is missing on that side


def _changes(r) -> tuple[list[str], list[str]]:
    worse, better = [], []
    ra, rb = _rank(r["status_a"]), _rank(r["status_b"])
    if ra < 3 and rb < 3 and rb != ra:
        (worse if rb > ra else better).append(f"status {r['status_a']} → {r['status_b']}")
    fa, fb = r["foldovers_a"], r["foldovers_b"]
    if fa == fa and fb == fb and fb != fa:
        (worse if fb > fa else better).append(f"foldovers {int(fa)} → {int(fb)}")
    # Ratios compared on a log scale: B = A / 1.3 is as much an improvement as B = 1.3 A is a
    # regression (a threshold of 1 + tol one way and 1 - tol the other was no mirror image:
    # two runs compared A-B and B-A gave 10 improvements and 12 regressions).
    qa, qb = r["qc_mean_a"], r["qc_mean_b"]
    if qa == qa and qb == qb and qa > 0 and qb > 0 and abs(np.log(qb / qa)) > np.log1p(QC_TOL):
        (worse if qb > qa else better).append(f"QC {qb / qa - 1.0:+.2%}")
    ta, tb = r["time_total_a"], r["time_total_b"]
    if (ta == ta and tb == tb and ta > 0 and tb > 0 and abs(tb - ta) >= TIME_FLOOR
            and abs(np.log(tb / ta)) > np.log1p(TIME_TOL)):
        (worse if tb > ta else better).append(f"time ×{tb / ta:.2f}")
    return worse, better


def compare_rows(rows_a: pd.DataFrame, rows_b: pd.DataFrame) -> pd.DataFrame:
    """Match the cells of two runs and classify each difference.

    Parameters
    ----------
    rows_a, rows_b : pandas.DataFrame
        Normalised rows (:attr:`parambench.reports.load.Results.rows`) of run A (before) and B (after).

    Returns
    -------
    pandas.DataFrame
        One row per cell present in either run: ``config``, ``variant``, ``seed``,
        ``status_a``/``_b`` ("" when missing), ``qc_mean_a``/``_b``, ``foldovers_a``/``_b``,
        ``time_total_a``/``_b``, ``change`` ("regression", "improvement", "unchanged",
        "only in A", "only in B") and ``what`` (the differences in words). Regressions
        come first (most severe first: status, foldovers, QC, time), then cells only in
        one run, improvements, unchanged.
    """
    both = add_labels(pd.concat([rows_a.assign(_side="a"), rows_b.assign(_side="b")], ignore_index=True))
    # Parameters as canonical JSON so that key order does not split a match.
    both["params"] = both["params"].map(lambda p: json.dumps(json.loads(p or "{}"), sort_keys=True))
    cols = ["status", "qc_mean", "foldovers", "time_total"]
    side_a = both[both["_side"] == "a"][_KEY + ["config", "variant"] + cols]
    side_b = both[both["_side"] == "b"][_KEY + ["config", "variant"] + cols]
    merged = side_a.merge(side_b, on=_KEY, how="outer", suffixes=("_a", "_b"))
    merged["config"] = merged["config_a"].fillna(merged["config_b"])
    merged["variant"] = merged["variant_a"].fillna(merged["variant_b"])
    for side in "ab":
        merged[f"status_{side}"] = merged[f"status_{side}"].fillna("")
    changes, whats, severity = [], [], []
    for _, r in merged.iterrows():
        if not r["status_a"] or not r["status_b"]:
            changes.append("only in A" if r["status_a"] else "only in B")
            whats.append("")
            severity.append(4)
            continue
        worse, better = _changes(r)
        if worse:
            changes.append("regression")
            whats.append("; ".join(worse + [f"but {b}" for b in better]))
            first = worse[0]
            severity.append(0 if first.startswith("status") else 1 if first.startswith("fold") else
                            2 if first.startswith("QC") else 3)
        elif better:
            changes.append("improvement")
            whats.append("; ".join(better))
            severity.append(5)
        else:
            changes.append("unchanged")
            whats.append("")
            severity.append(6)
    merged["change"], merged["what"], merged["_severity"] = changes, whats, severity
    out = merged.sort_values(["_severity", "config", "variant", "seed"], kind="stable")
    keep = ["config", "variant", "seed", "status_a", "status_b", "qc_mean_a", "qc_mean_b", "foldovers_a",
            "foldovers_b", "time_total_a", "time_total_b", "change", "what"]
    return out[keep].reset_index(drop=True)


def comparison_table(diff: pd.DataFrame) -> Table:
    """The per-cell comparison as a table (regressions first, as :func:`compare_rows` sorts)."""
    body, keys = [], []
    for _, r in diff.iterrows():
        ratio = (r["time_total_b"] / r["time_total_a"]
                 if r["time_total_a"] == r["time_total_a"] and r["time_total_a"] > 0 else np.nan)
        kind = {"regression": ("status", "failed"), "improvement": ("status", "ok")}.get(r["change"], ("status",))
        body.append([Cell(str(r["change"]), kind), Cell(str(r["config"])), Cell(str(r["variant"]), ("method",)),
                     Cell(format_number(r["seed"], "count")),
                     Cell(f"{r['status_a'] or '—'} → {r['status_b'] or '—'}"),
                     Cell(format_number(r["qc_mean_a"])), Cell(format_number(r["qc_mean_b"])),
                     Cell(format_number(r["foldovers_a"], "count")), Cell(format_number(r["foldovers_b"], "count")),
                     Cell(format_number(r["time_total_a"], "time")), Cell(format_number(r["time_total_b"], "time")),
                     Cell("—" if ratio != ratio else f"{ratio:.2f}"), Cell(str(r["what"]))])
        keys.append({"change": r["change"]})
    return Table(["Change", "Surface", "Method", "Seed", "Status A → B", "QC A", "QC B", "Folds A", "Folds B",
                  "Time A (s)", "Time B (s)", "Time B/A", "What changed"], body,
                 f"{len(diff)} cell(s) compared", "comparison", numeric=set(range(3, 12)), row_keys=keys, note=RULE)


def build_comparison(dir_a, dir_b, *, out_dir=None, formats=("html",)) -> tuple[dict, pd.DataFrame]:
    """Write the comparison of two results directories.

    Parameters
    ----------
    dir_a, dir_b : str or path-like
        Results directories of ``parambench run``: A is the baseline, B the new run.
    out_dir : str or path-like, optional
        Where to write ``compare.html`` (and ``compare.pdf``); default ``dir_b/report``.
    formats : iterable of {"html", "pdf"}

    Returns
    -------
    paths : dict of str to pathlib.Path
    diff : pandas.DataFrame
        Output of :func:`compare_rows`.

    Raises
    ------
    EmptyResultsError
        Either directory is missing or holds no finished cell.
    UnknownNameError
        A format other than "html" or "pdf".
    InputFileError
        ``out_dir`` lies inside the package sources.
    """
    from parambench.datasets_gen.errors import UnknownNameError

    formats = tuple(formats)
    unknown = [f for f in formats if f not in ("html", "pdf")]
    if unknown:
        raise UnknownNameError(f"Unknown report format(s) {unknown}; choose from ['html', 'pdf'].")
    a, b = load_results(dir_a), load_results(dir_b)
    diff = compare_rows(a.rows, b.rows)
    counts = diff["change"].value_counts()
    summary = ", ".join(f"{int(counts.get(k, 0))} {k}" for k in ("regression", "improvement", "unchanged",
                                                                 "only in A", "only in B") if counts.get(k, 0))
    intro = f"A = {a.root}, B = {b.root}: {summary}."
    blocks = [comparison_table(diff)]
    if not counts.get("regression", 0):
        blocks.insert(0, Note("No regression.", "muted"))
    page = render_report("parambench comparison", f"A: {a.run.get('git_commit', '?')!s:.10} · B: "
                         f"{b.run.get('git_commit', '?')!s:.10}", [Section("Per-cell differences", blocks, intro)])
    out = Path(out_dir) if out_dir is not None else b.root / "report"
    check_out_dir(out)
    out.mkdir(parents=True, exist_ok=True)
    paths = {}
    if "html" in formats:
        path = out / "compare.html"
        atomic_write_bytes(path, page.encode("utf-8"))
        paths["html"] = path
    if "pdf" in formats:
        from .pdf import write_pdf

        paths["pdf"] = write_pdf(page, out / "compare.pdf")
    return paths, diff
