"""Read a results directory (the sweep's storage contract) into a DataFrame and arrays.

The report never runs a method: everything it shows comes from here. Rows come from
``cells/*.json`` (one per finished cell, written atomically, so always current); rows found
only in ``results.parquet`` (or ``results.csv`` when there is no parquet) are added, so a
consolidated file from an older run and newer cell files give their union.
"""

from __future__ import annotations

import json
import math
import os
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

# The results format is the sweep's: read with the same definitions it writes with.
from parambench.bench.schema import JSON_COLUMNS, NUMERIC_COLUMNS, ROW_COLUMNS, STATUS_FAILED, TEXT_COLUMNS
from parambench.bench.schema import decode_json as parse_json_field
from parambench.bench.schema import dataset_key, decode_loops, encode_json, loops_from_flat
from parambench.datasets_gen.errors import InputFileError

from .errors import EmptyResultsError

__all__ = [
    "ROW_COLUMNS",
    "NUMERIC_COLUMNS",
    "Results",
    "CellArrays",
    "load_results",
    "gather_rows",
    "normalise_rows",
    "parse_json_field",
    "loops_from_flat",
    "load_cell_arrays",
    "load_dataset_arrays",
    "dataset_key_candidates",
]

#: What numpy raises on a damaged ``.npz``: a truncated zip is a BadZipFile or EOFError
#: (it stopped the report, and every run after it, as the cell's JSON said "finished").
NPZ_READ_ERRORS = (OSError, KeyError, ValueError, EOFError, zipfile.BadZipFile)


@dataclass
class Results:
    """Everything read from one results directory.

    Attributes
    ----------
    root : pathlib.Path
        The results directory.
    run : dict
        ``run.json`` (empty when the file is missing or unreadable).
    rows : pandas.DataFrame
        One row per cell with every column of :data:`ROW_COLUMNS`, normalised by
        :func:`normalise_rows`, sorted by ``cell_id``.
    warnings : list of str
        Files that were skipped and why; the report lists them.
    """

    root: Path
    run: dict
    rows: pd.DataFrame
    warnings: list = field(default_factory=list)


@dataclass
class CellArrays:
    """The pictures' data of one ok cell (``cells/<cell_id>.npz``).

    Attributes
    ----------
    points : (N, 3) numpy.ndarray of float64
    faces : (M, 3) numpy.ndarray of int64
        The evaluation mesh.
    uv : (N, 2) numpy.ndarray of float64
    qc : (M,) numpy.ndarray of float64
        Per-face quasi-conformal distortion (1 = conformal).
    flipped : (M,) numpy.ndarray of bool
        Foldover mask.
    gt_loops, det_loops : list of (L,) int64 arrays, or None
        Ground-truth boundary loops and the loops the method detected.
    landscape : dict with keys "k", "E", "t" of (K,) float64 arrays, or None
        OCP line-search samples. When the file holds one turning number per boundary loop
        (``landscape_t`` of shape (K, L)), ``t`` is the outer loop's (the first).
    problems : list of str
        Parts of the file that were left out and why (the rest is usable).
    """

    points: np.ndarray
    faces: np.ndarray
    uv: np.ndarray
    qc: np.ndarray
    flipped: np.ndarray
    gt_loops: list | None = None
    det_loops: list | None = None
    landscape: dict | None = None
    problems: list = field(default_factory=list)


def _read_json(path: Path) -> dict:
    try:
        data = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise InputFileError(f"{path}: not readable JSON ({exc}).") from exc
    if not isinstance(data, dict):
        raise InputFileError(f"{path}: expected a JSON object, got {type(data).__name__}.")
    return data


def _canonical_json(value, default: str) -> str:
    # Rows from JSON cells may carry objects, rows from parquet carry strings: one form for both.
    parsed = parse_json_field(value, None)
    if parsed is None:
        return default if not isinstance(value, str) or not value else value
    return encode_json(parsed)


def normalise_rows(rows: pd.DataFrame) -> pd.DataFrame:
    """Give raw rows every contract column with one dtype per column.

    Missing columns are added as null; :data:`NUMERIC_COLUMNS` become float64 (NaN for
    null); text columns become str ("" for null); JSON columns become canonical JSON
    strings; ``status`` is lower-cased.

    Parameters
    ----------
    rows : pandas.DataFrame
        Raw rows, any subset of :data:`ROW_COLUMNS` plus extra columns (kept).

    Returns
    -------
    pandas.DataFrame
        A new frame sorted by ``cell_id`` with a fresh index.
    """
    df = rows.copy()
    for col in ROW_COLUMNS:
        if col not in df.columns:
            df[col] = None
    for col in NUMERIC_COLUMNS:
        df[col] = pd.to_numeric(df[col], errors="coerce").astype("float64")
    for col in TEXT_COLUMNS:
        df[col] = df[col].map(lambda v: "" if v is None or (isinstance(v, float) and math.isnan(v)) else str(v))
    for col, default in JSON_COLUMNS.items():
        df[col] = df[col].map(lambda v, d=default: _canonical_json(v, d))
    df["status"] = df["status"].str.strip().str.lower().replace("", STATUS_FAILED)
    return df.sort_values("cell_id", kind="stable").reset_index(drop=True)


def gather_rows(root: Path) -> tuple[pd.DataFrame, list[str]]:
    """Rows of ``cells/*.json`` plus rows only present in the consolidated table.

    Parameters
    ----------
    root : pathlib.Path
        A results directory.

    Returns
    -------
    rows : pandas.DataFrame
        Raw (not normalised) rows; empty when nothing was found.
    warnings : list of str
        Files that were skipped and why (unreadable, or a table without ``cell_id`` or rows).
    """
    warnings: list[str] = []
    records = []
    for path in sorted((root / "cells").glob("*.json")):
        try:
            record = _read_json(path)
        except InputFileError as exc:
            warnings.append(f"skipped {path.name}: {exc}")
            continue
        record.setdefault("cell_id", path.stem)
        records.append(record)
    from_cells = pd.DataFrame.from_records(records)
    table = None
    for name, reader in (("results.parquet", pd.read_parquet), ("results.csv", pd.read_csv)):
        path = root / name
        if path.exists():
            table, problem = _read_table(path, reader)
            if problem:
                warnings.append(f"skipped {name}: {problem}")
                continue
            break
    if table is None:
        return from_cells, warnings
    if from_cells.empty:
        return table, warnings
    extra = table[~table["cell_id"].astype(str).isin(set(from_cells["cell_id"].astype(str)))]
    return pd.concat([from_cells, extra], ignore_index=True), warnings


def _read_table(path: Path, reader) -> tuple[pd.DataFrame | None, str]:
    """A consolidated results table, or None and what is wrong with it (one line).

    A table that exists but cannot be used is named with its fault, so that a folder with
    only such a table is not reported as holding no table at all.
    """
    if path.is_dir():
        return None, "a folder, not a file"
    if path.stat().st_size == 0:
        return None, "empty file (0 bytes)"
    try:
        table = reader(path)
    except Exception as exc:  # pyarrow and the csv parser raise many kinds; skip the file either way
        text = " ".join(str(exc).split()) or type(exc).__name__
        hint = "; the file may be cut off or damaged" if path.suffix == ".csv" else ""
        return None, f"unreadable ({type(exc).__name__}: {text[:200]}{hint})"
    if path.suffix == ".csv" and not _ends_with_newline(path):
        # The sweep writes whole lines: a last line without its end was cut off, and the
        # parser would fill the missing fields of that row with blanks without a word.
        return None, "cut off mid-row (its last line has no line end): the file is incomplete"
    if "cell_id" not in table.columns:
        shown = ", ".join(map(str, table.columns[:8])) + (", …" if len(table.columns) > 8 else "")
        return None, f"no cell_id column (columns: {shown or 'none'}), so its rows cannot be told apart"
    if table.empty:
        return None, "no row (only a header)"
    return table, ""


def load_results(results_dir: str | os.PathLike) -> Results:
    """Read a results directory.

    Parameters
    ----------
    results_dir : str or path-like

    Returns
    -------
    Results

    Raises
    ------
    EmptyResultsError
        The path is a file or does not exist, or the directory holds no usable result row
        (the message names each file that is there but unusable, and its fault). A directory
        whose rows all failed is not empty: it gives a report of the failures.
    """
    root = Path(results_dir)
    if root.is_file():
        raise EmptyResultsError(
            f"{root} is a file; pass the sweep's results folder (the one holding cells/ and run.json, "
            f"here perhaps {root.parent}): `parambench report RESULTS_DIR`.")
    if not root.is_dir():
        raise EmptyResultsError(
            f"Results directory {root} does not exist. Run `parambench run` first (or pass the "
            f"directory it wrote), then `parambench report RESULTS_DIR`.")
    raw, warnings = gather_rows(root)
    if raw.empty:
        raise EmptyResultsError(_no_rows_message(root, warnings))
    run: dict = {}
    run_path = root / "run.json"
    if run_path.exists():
        try:
            run = _read_json(run_path)
        except InputFileError as exc:
            warnings.append(f"skipped run.json: {exc}")
    else:
        warnings.append("run.json is missing: run metadata is not shown.")
    return Results(root=root, run=run, rows=normalise_rows(raw), warnings=warnings)


def _ends_with_newline(path: Path) -> bool:
    with path.open("rb") as handle:
        handle.seek(-1, os.SEEK_END)  # not empty: _read_table says so before
        return handle.read(1) in (b"\n", b"\r")


def _no_rows_message(root: Path, warnings: list[str]) -> str:
    """Why ``root`` gave no row: the files that were there but unusable, or that there were none."""
    if not warnings:
        return (f"No finished cell in {root} (no cells/*.json, no results.parquet or results.csv). "
                f"Run `parambench run` first and wait for at least one cell to finish.")
    shown = "; ".join(" ".join(w.split()) for w in warnings[:3])  # one line: the CLI prints it as is
    shown += f"; and {len(warnings) - 3} more" if len(warnings) > 3 else ""
    return (f"No usable result in {root}: {shown}. Restore the file(s), or run `parambench run` again into this "
            f"folder (finished cells in cells/ are kept).")


def load_cell_arrays(root: Path, artifact: str) -> CellArrays | None:
    """Read a cell's npz.

    Parameters
    ----------
    root : pathlib.Path
        The results directory.
    artifact : str
        The row's ``artifact`` (path relative to ``root``); "" means none.

    Returns
    -------
    CellArrays or None
        None when the cell has no artifact or the file is gone (big cells keep none).

    Raises
    ------
    InputFileError
        The file is unreadable or its arrays disagree in shape.
    """
    if not artifact:
        return None
    path = root / artifact
    if not path.is_file():
        return None
    try:
        with np.load(path, allow_pickle=False) as data:
            points = np.asarray(data["points"], dtype=np.float64)
            faces = np.asarray(data["faces"], dtype=np.int64)
            uv = np.asarray(data["uv"], dtype=np.float64)
            qc = np.asarray(data["qc"], dtype=np.float64).ravel()
            flipped = np.asarray(data["flipped"], dtype=bool).ravel()
            n = len(points)
            gt = decode_loops(data, "gt", n)
            det = decode_loops(data, "det", n)
            landscape = None
            if all(f"landscape_{k}" in data for k in "kEt"):
                landscape = {k: np.asarray(data[f"landscape_{k}"], dtype=np.float64) for k in "kEt"}
    except InputFileError as exc:
        raise InputFileError(f"{artifact}: {exc}") from exc
    except NPZ_READ_ERRORS as exc:
        raise InputFileError(f"{artifact}: unreadable cell arrays ({exc}).") from exc
    if (points.ndim != 2 or points.shape[1] != 3 or faces.ndim != 2 or faces.shape[1] != 3
            or uv.shape != (len(points), 2) or qc.shape != (len(faces),) or flipped.shape != (len(faces),)):
        raise InputFileError(
            f"{artifact}: array shapes disagree (points {points.shape}, faces {faces.shape}, uv {uv.shape}, "
            f"qc {qc.shape}, flipped {flipped.shape}).")
    if len(faces) and (faces.min() < 0 or faces.max() >= len(points)):
        raise InputFileError(f"{artifact}: face indices out of range.")
    problems = []
    if landscape is not None:
        landscape, problem = _landscape(landscape)
        if problem:
            problems.append(f"{artifact}: {problem}")
    return CellArrays(points, faces, uv, qc, flipped, gt, det, landscape, problems)


def _landscape(raw: dict) -> tuple[dict | None, str]:
    # Turning numbers may come one per boundary loop, (K, L): the outer loop (first) is the
    # boundary polygon of the paper's Fig. 9.
    k, energy, t = raw["k"].ravel(), raw["E"].ravel(), raw["t"]
    t = t[:, 0] if t.ndim == 2 and t.shape[0] == len(k) and t.shape[1] >= 1 else t.ravel()
    if not (len(k) == len(energy) == len(t)):
        return None, (f"landscape left out: landscape_k {raw['k'].shape}, landscape_E {raw['E'].shape} and "
                      f"landscape_t {raw['t'].shape} do not match.")
    return {"k": k, "E": energy, "t": t}, ""


def dataset_key_candidates(dataset: str, size, sampling: str, noise, seed) -> list[str]:
    """File stems under ``datasets/`` that hold a surface's diagnostics.

    One: the key the sweep writes, :func:`parambench.bench.schema.dataset_key` (sizes and seeds read
    back as floats are accepted). A list, so callers can look through several surfaces.
    """
    return [dataset_key(dataset, size, sampling, noise, seed)]


def load_dataset_arrays(root: Path, candidates: list[str]) -> dict | None:
    """Read a surface's diagnostics npz (weight samples, detected boundary).

    Parameters
    ----------
    root : pathlib.Path
        The results directory.
    candidates : list of str
        File stems to try, from :func:`dataset_key_candidates`.

    Returns
    -------
    dict or None
        Arrays by name; ``gt_loops`` and ``det_loops`` are decoded to lists of index
        arrays when present. None when no candidate file exists.

    Raises
    ------
    InputFileError
        The file is unreadable or its loops are inconsistent.
    """
    for key in candidates:
        path = root / "datasets" / f"{key}.npz"
        if not path.is_file():
            continue
        try:
            with np.load(path, allow_pickle=False) as data:
                out = {name: np.asarray(data[name]) for name in data.files}
        except NPZ_READ_ERRORS as exc:
            raise InputFileError(f"datasets/{key}.npz: unreadable ({exc}).") from exc
        n = len(out["points"]) if "points" in out else None
        try:
            out["gt_loops"] = decode_loops(out, "gt", n)
            out["det_loops"] = decode_loops(out, "det", n)
        except InputFileError as exc:
            raise InputFileError(f"datasets/{key}.npz: {exc}") from exc
        return out
    return None
