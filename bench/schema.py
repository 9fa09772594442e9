"""The results format: one definition that the sweep writes with and the report reads with.

A results folder holds one JSON row per cell (``cells/<cell_id>.json``), an optional npz
of arrays per cell and one npz of diagnostics per surface (``datasets/<key>.npz``).
This module fixes the row's columns and their kinds, the fields that address a cell and
a surface, the file-name-safe keys built from them, the JSON encoding of the columns
that hold a JSON document, and the flat encoding of boundary loops in the npz files.

Imports nothing of parambench but the error types, so :mod:`reports` may import it
without importing the sweep or the methods.
"""

from __future__ import annotations

import hashlib
import json
import math
import re

import numpy as np

from parambench.datasets_gen.errors import InputFileError

__all__ = [
    "STATUS_OK", "STATUS_SUSPECT", "STATUS_FAILED",
    "CELL_KEY_FIELDS", "SURFACE_KEY_FIELDS",
    "METRIC_KEYS", "SELFMESH_KEYS", "METRIC_COLUMNS", "ROW_COLUMNS", "NUMERIC_COLUMNS", "TEXT_COLUMNS",
    "JSON_COLUMNS", "ANGLE_HIST_EDGES_DEG",
    "slug", "dataset_key", "cell_id", "encode_json", "decode_json",
    "encode_loops", "decode_loops", "loops_from_flat",
]

#: Row ``status`` values: a map that passed, a map that failed its self-check (metrics kept),
#: a cell that produced no map. Only ``failed`` cells are recomputed by a rerun.
STATUS_OK, STATUS_SUSPECT, STATUS_FAILED = "ok", "suspect", "failed"

#: The fields that address a surface (its diagnostics file), in key order.
SURFACE_KEY_FIELDS = ("dataset", "size", "sampling", "noise", "seed")
#: The fields that address a cell: the surface, the method and its parameters (JSON).
CELL_KEY_FIELDS = SURFACE_KEY_FIELDS + ("method", "params")

#: The keys of :func:`parambench.bench.metrics.evaluate`'s dict, in order; each is a row column.
METRIC_KEYS = (
    "qc_mean", "qc_p95", "qc_max", "foldovers", "foldover_fraction", "collapsed",
    "area_distortion", "turning_numbers", "exact_error", "n_eval_faces",
    "mu_mean", "mu_sd", "mu_p95", "area_distortion_normalized", "sigma_ratio_max", "angle_error_mean",
    "flipped_share", "angle_hist",
)
#: The keys of :func:`parambench.bench.metrics.self_scored` (stored with the prefix ``selfmesh_``).
SELFMESH_KEYS = ("qc_mean", "qc_p95", "mu_mean", "mu_p95", "angle_error_mean", "area_distortion_normalized",
                 "n_eval_faces")
#: Metric columns of a row.
METRIC_COLUMNS = METRIC_KEYS + tuple(f"selfmesh_{k}" for k in SELFMESH_KEYS)

#: Columns that hold a JSON document as text, with the text of an empty one.
JSON_COLUMNS = {"params": "{}", "timings": "{}", "diagnostics": "{}", "turning_numbers": "[]",
                "stage_memory_mb": "{}", "angle_hist": "null"}

#: Every column of a result row (``peak_rss_mb`` only in isolated sweeps).
ROW_COLUMNS = (
    ("cell_id",) + CELL_KEY_FIELDS + ("n_points", "n_faces", "status", "error_type", "error")
    + METRIC_COLUMNS
    + ("eval_mesh", "time_total", "timings", "diagnostics", "k_opt", "peak_memory_mb", "stage_memory_mb",
       "peak_rss_mb", "artifact")
)

#: Columns of plain text.
TEXT_COLUMNS = ("cell_id", "dataset", "sampling", "method", "status", "error_type", "error", "eval_mesh",
                "artifact")
#: Columns of numbers (null for a failed cell).
NUMERIC_COLUMNS = tuple(c for c in ROW_COLUMNS if c not in TEXT_COLUMNS and c not in JSON_COLUMNS)

#: Bin edges (degrees) of the ``angle_hist`` column, a JSON list of counts: 1-degree bins over
#: [-30, 30]. Fixed so that histograms of different cells can be summed and compared;
#: differences beyond +-30 degrees are counted in the end bins.
ANGLE_HIST_EDGES_DEG = np.linspace(-30.0, 30.0, 61)


def slug(text: str) -> str:
    """``text`` made file-name safe: every run of other characters than ``A-Za-z0-9_.-`` becomes ``_``."""
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", text)


def _whole(value) -> int:
    # Tables read back store sizes and seeds as floats (NaN for a missing value).
    value = float(value)
    return 0 if math.isnan(value) else int(value)


def dataset_key(dataset: str, size, sampling: str, noise, seed) -> str:
    """The file stem of a surface's diagnostics, ``datasets/<key>.npz``.

    Parameters
    ----------
    dataset : str
    size, seed : int or float
        Whole numbers (floats as read back from a table are accepted; NaN counts as 0).
    sampling : str
    noise : float
        NaN counts as 0.

    Returns
    -------
    str
        ``slug(f"{dataset}-{size}-{sampling}-n{noise:g}-s{seed}")``, e.g. ``"bump-2000-jittered-n0-s0"``.
    """
    noise = float(noise)
    noise = 0.0 if math.isnan(noise) else noise
    return slug(f"{dataset}-{_whole(size)}-{sampling}-n{noise:g}-s{_whole(seed)}")


def cell_id(dataset: str, size: int, sampling: str, noise: float, seed: int, method: str, params: dict) -> str:
    """Stable, file-name-safe identifier of a cell: a readable prefix plus a hash of its full address.

    Parameters
    ----------
    dataset, size, sampling, noise, seed, method
        See :data:`CELL_KEY_FIELDS`.
    params : dict
        Method parameters.

    Returns
    -------
    str
        E.g. ``"bump-2000-jittered-s0-ocp-1a2b3c4d5e"``.
    """
    address = json.dumps([dataset, size, sampling, noise, seed, method, params], sort_keys=True)
    digest = hashlib.sha1(address.encode()).hexdigest()[:10]
    return slug(f"{dataset}-{size}-{sampling}-s{seed}-{method}") + f"-{digest}"


def _plain(value):
    if isinstance(value, np.generic):
        return value.item()
    if hasattr(value, "tolist"):
        return value.tolist()
    return str(value)


def encode_json(value) -> str:
    """The text stored in a :data:`JSON_COLUMNS` column (keys sorted; numpy values as plain ones)."""
    return json.dumps(value, default=_plain, sort_keys=True)


def decode_json(value, default=None):
    """Decode a JSON column's value; dicts and lists pass through.

    Parameters
    ----------
    value : str, dict, list, None or float NaN
    default : object
        Returned for null, empty or undecodable values.
    """
    if isinstance(value, (dict, list)):
        return value
    if value is None or (isinstance(value, float) and math.isnan(value)) or value == "":
        return default
    try:
        return json.loads(value)
    except (TypeError, ValueError):
        return default


def encode_loops(prefix: str, loops) -> dict:
    """Boundary loops as two npz arrays: ``<prefix>_loops_flat`` and ``<prefix>_loops_offsets``.

    Parameters
    ----------
    prefix : str
        ``"gt"`` (ground truth) or ``"det"`` (detected by the method or the front end).
    loops : list of (L_i,) array_like of int, or None

    Returns
    -------
    dict of str to numpy.ndarray
        ``flat`` (S,) int32, all loops one after the other; ``offsets`` (L+1,) int32,
        loop ``i`` is ``flat[offsets[i]:offsets[i+1]]``. Empty when there are no loops.
    """
    if not loops:
        return {}
    flat = np.concatenate([np.asarray(lp, dtype=np.int32).ravel() for lp in loops])
    offsets = np.cumsum([0] + [len(lp) for lp in loops]).astype(np.int32)
    return {f"{prefix}_loops_flat": flat, f"{prefix}_loops_offsets": offsets}


def loops_from_flat(flat: np.ndarray, offsets: np.ndarray, n_points: int | None = None) -> list[np.ndarray]:
    """Split concatenated loops back into a list (the inverse of :func:`encode_loops`).

    Parameters
    ----------
    flat : (S,) integer numpy.ndarray
        Vertex indices of all loops, one after the other.
    offsets : (L+1,) integer numpy.ndarray
        ``flat[offsets[i]:offsets[i+1]]`` is loop ``i``; starts at 0, ends at ``S``.
    n_points : int, optional
        When given, indices must be below it.

    Returns
    -------
    list of (L_i,) numpy.ndarray of int64

    Raises
    ------
    InputFileError
        Offsets not increasing from 0 to ``len(flat)``, or indices out of range.
    """
    flat = np.asarray(flat, dtype=np.int64).ravel()
    offsets = np.asarray(offsets, dtype=np.int64).ravel()
    if (len(offsets) < 1 or offsets[0] != 0 or offsets[-1] != len(flat) or np.any(np.diff(offsets) < 0)):
        raise InputFileError("loop offsets must rise from 0 to the length of the flat loop array.")
    if n_points is not None and len(flat) and (flat.min() < 0 or flat.max() >= n_points):
        raise InputFileError(f"loop vertex indices must lie in [0, {n_points}).")
    return [flat[a:b] for a, b in zip(offsets[:-1], offsets[1:]) if b > a]


def decode_loops(arrays, prefix: str, n_points: int | None = None) -> list[np.ndarray] | None:
    """The loops :func:`encode_loops` stored under ``prefix`` in ``arrays``, or None if absent.

    Parameters
    ----------
    arrays : mapping of str to numpy.ndarray
        An open npz or a dict.
    prefix : str
    n_points : int, optional
        When given, indices must be below it.

    Raises
    ------
    InputFileError
        See :func:`loops_from_flat`.
    """
    flat, offsets = f"{prefix}_loops_flat", f"{prefix}_loops_offsets"
    if flat not in arrays or offsets not in arrays:
        return None
    return loops_from_flat(arrays[flat], arrays[offsets], n_points)
