"""Run one sweep cell: make the surface, run the method, measure, store the row.

:func:`run_cell` is a plain top-level function of picklable arguments, so the same code
runs in-process, in a process pool or on a Dask worker.
"""

from __future__ import annotations

import traceback
from dataclasses import replace
from functools import lru_cache

import numpy as np

from parambench.datasets_gen.errors import ParambenchError
from parambench.datasets_gen.registry import REAL_SAMPLINGS, make_surface
from parambench.datasets_gen.surface import MethodInput, Surface
from parambench.methods import get_method

from .cells import Cell
from .memory import PeakMemory
from .metrics import evaluate, flipped_mask, per_face_qc, self_scored, triangle_signed_areas, uv_delaunay_faces
from .schema import METRIC_COLUMNS, STATUS_FAILED, STATUS_OK, STATUS_SUSPECT, encode_json, encode_loops
from .storage import ResultStore

__all__ = ["compute_cell", "failed_row", "run_cell", "store_cell", "surface_for", "warm_up", "METRIC_COLUMNS",
           "ARTIFACT_MAX_POINTS", "WARM_UP_POINTS"]

#: Cells on larger surfaces store no arrays: pictures of a million triangles are not drawn.
ARTIFACT_MAX_POINTS = 200_000


@lru_cache(maxsize=4)
def surface_for(dataset: str, size: int, sampling: str, noise: float, seed: int) -> Surface:
    """The surface of a cell, regenerated from its seed (cached per process)."""
    if dataset.startswith("real/") and sampling not in REAL_SAMPLINGS:
        return make_surface(dataset, seed=seed)
    return make_surface(dataset, size, sampling=sampling, seed=seed, noise=noise)


def _method_input(surface: Surface, needs_faces: bool, wants_loops: bool = False) -> MethodInput:
    """What a cell's method is given: a :class:`MethodInput`, no ground truth (see :meth:`Surface.method_input`).

    A file's own normals are data (``flatten`` passes them too), kept for point-set methods
    while the positions are the file's; a generator's normals, or a file's once noise has
    moved the points, are ground truth and withheld. ``wants_loops``: the cell asked for
    the true boundary (e.g. ``fbcp-pc boundary=given``), so ``boundary_loops`` is kept.
    """
    file_normals = surface.params.get("normals") == "file" and not surface.params.get("noise")
    given = surface.method_input(needs_faces, keep_normals=file_normals)
    return replace(given, boundary_loops=surface.boundary_loops) if wants_loops else given


#: Points of the surface :func:`warm_up` runs a method on.
WARM_UP_POINTS = 300

#: (method, parameters) already warmed up in this process.
_WARMED: set[tuple[str, str]] = set()


def warm_up(name: str, params: dict | None = None) -> float:
    """Run method ``name`` once, untimed, on a small surface, the first time in this process.

    Its compiled kernels (numba) are built or loaded from the on-disk cache on first use:
    without this the first cell of each method in a process was timed with them. A fresh
    checkout's first ``real/lilium`` benchmark took 26.4 s in the front end against 0.43 s
    warm (time ratio to ``scp-igl`` 87.7 against 8.4), and a sweep's first ``ocp`` cell spent
    0.27-0.43 s in its kNN stage against 0.02-0.05 s (a comparison of two sweeps then read it
    as a 1.5x regression). Failures are ignored: the cell itself reports its own. Only the
    built-in methods (modules of ``parambench.methods``) are warmed: a plugin's kernels, cost
    and side effects are its own.

    Parameters
    ----------
    name : str
        A registered method.
    params : dict, optional
        Its parameters (variants take other code paths).

    Returns
    -------
    float
        Seconds spent (0.0 when this process had already run it).
    """
    import json
    import time
    import warnings

    params = dict(params or {})
    key = (name, json.dumps(params, sort_keys=True, default=str))
    if key in _WARMED:
        return 0.0
    _WARMED.add(key)
    start = time.perf_counter()
    method = get_method(name)
    if not type(method).__module__.startswith("parambench.methods."):
        return 0.0
    surface = make_surface("bump", WARM_UP_POINTS, sampling="jittered", seed=0)
    wants_loops = getattr(method, "wants_given_boundary", None)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            method(_method_input(surface, method.needs_faces, bool(wants_loops and wants_loops(params))), **params)
    except Exception:  # noqa: BLE001 - the warm-up's own result does not matter
        pass
    return time.perf_counter() - start


def _empty_row(cell: Cell) -> dict:
    row = cell.address()
    row.update(cell_id=cell.cell_id, n_points=None, n_faces=None, status=STATUS_FAILED, error_type="", error="",
               eval_mesh="", time_total=None, timings="{}", diagnostics="{}", k_opt=None,
               peak_memory_mb=None, stage_memory_mb="{}", artifact="")
    row.update({c: None for c in METRIC_COLUMNS})
    return row


def failed_row(cell: Cell, error_type: str, message: str) -> dict:
    """The row of a cell that failed outside the method (e.g. its process died)."""
    row = _empty_row(cell)
    row.update(status=STATUS_FAILED, error_type=error_type, error=message)
    return row


def _evaluation_mesh(surface: Surface, result) -> tuple[np.ndarray, str]:
    if surface.faces is not None:
        return surface.faces, "ground-truth"
    if result.faces is not None:
        return result.faces, "method"
    return uv_delaunay_faces(surface.points, result.uv), "uv-delaunay"


def _artifact(surface: Surface, result, faces, eval_kind: str) -> dict:
    qc = per_face_qc(surface.points, faces, result.uv)
    arrays = {
        "points": surface.points.astype(np.float32),
        "faces": faces.astype(np.int32),
        "uv": result.uv,
        "qc": qc,
        # the faces the row counts as foldovers, so the picture and the number agree
        "flipped": flipped_mask(triangle_signed_areas(result.uv, faces)),
    }
    if eval_kind == "ground-truth":
        arrays.update(encode_loops("gt", surface.boundary_loops))
    diag = result.diagnostics
    arrays.update(encode_loops("det", diag.get("boundary_loops")))
    landscape = diag.get("landscape")
    if landscape:
        for key in ("k", "E", "t"):
            arrays[f"landscape_{key}"] = np.asarray(landscape[key], dtype=np.float64)
    return arrays


def _jsonable_diagnostics(diag: dict) -> str:
    # Loops and landscapes go to the npz; the row keeps scalars and short lists.
    slim = {k: v for k, v in diag.items() if k not in ("boundary_loops", "landscape")}
    if "boundary_loops" in diag:
        slim["n_detected_loops"] = len(diag["boundary_loops"])
    return encode_json(slim)


def _status(result) -> str:
    """``"suspect"`` for a map that failed its self-check (metrics still computed), else ``"ok"``."""
    check = result.diagnostics.get("selfcheck")
    return STATUS_SUSPECT if check is not None and not check.get("passed", False) else STATUS_OK


def compute_cell(cell: Cell) -> tuple[dict, dict | None]:
    """Run one cell and return its row and arrays, writing nothing.

    Never raises for a failure of the method or the data: the row records
    ``status="failed"`` with the error type and text, and the sweep goes on. A point-set
    map that fails its self-check (``diagnostics["selfcheck"]``) gets ``status="suspect"``
    and its ``error`` holds the check's one-line reason; its metrics are stored as usual.

    Parameters
    ----------
    cell : Cell

    Returns
    -------
    row : dict
        Flat, JSON-serialisable; ``artifact`` is filled in by :func:`store_cell`.
    arrays : dict of numpy arrays, or None
        Pictures' data for ok and suspect cells on surfaces up to ``ARTIFACT_MAX_POINTS`` points.
    """
    row = _empty_row(cell)
    arrays = None
    try:
        surface = surface_for(cell.dataset, cell.size, cell.sampling, cell.noise, cell.seed)
        row.update(n_points=surface.n_points, n_faces=0 if surface.faces is None else int(len(surface.faces)))
        method = get_method(cell.method)
        params = cell.params_dict
        wants_loops = getattr(method, "wants_given_boundary", None)
        given = _method_input(surface, method.needs_faces, bool(wants_loops and wants_loops(params)))
        if "seed" in method.defaults:
            params.setdefault("seed", cell.seed)
        warm_up(cell.method, cell.params_dict)
        peak = PeakMemory()
        with peak.measure():
            result = method(given, **params)
        faces, eval_kind = _evaluation_mesh(surface, result)
        use_gt_loops = eval_kind == "ground-truth" and surface.boundary_loops is not None
        metrics = evaluate(surface.points, faces, result.uv, exact_uv=surface.exact_uv,
                           boundary_loops=surface.boundary_loops if use_gt_loops else None,
                           diameter=surface.diameter)
        loops = result.diagnostics.get("boundary_loops")
        if not method.needs_faces and loops:
            # Point-set maps are also scored without ground truth, on their own uv triangulation.
            # Loops that bound nothing in uv leave these columns empty rather than failing a
            # cell whose ground-truth metrics are valid.
            try:
                metrics.update(self_scored(surface.points, result.uv, loops))
            except ParambenchError:
                pass
        row.update({c: metrics.get(c) for c in METRIC_COLUMNS})
        row["turning_numbers"] = encode_json(metrics.get("turning_numbers", []))
        # Counts over parambench.bench.schema.ANGLE_HIST_EDGES_DEG, as JSON like the turning numbers.
        row["angle_hist"] = encode_json(metrics.get("angle_hist"))
        row.update(status=_status(result), eval_mesh=eval_kind, time_total=result.timings.get("total"),
                   timings=encode_json(result.timings),
                   diagnostics=_jsonable_diagnostics(result.diagnostics),
                   k_opt=result.diagnostics.get("k_opt"), peak_memory_mb=peak.delta_mb,
                   stage_memory_mb=encode_json({k: round(v, 1) for k, v in peak.stage_peak_mb.items()}))
        if row["status"] == STATUS_SUSPECT:
            row.update(error_type="SelfCheck", error=result.diagnostics["selfcheck"].get("reason", ""))
        if surface.n_points <= ARTIFACT_MAX_POINTS:
            arrays = _artifact(surface, result, faces, eval_kind)
    except ParambenchError as exc:
        row.update(status=STATUS_FAILED, error_type=type(exc).__name__, error=str(exc))
    except Exception as exc:  # a bug or a library failure: keep the sweep alive, keep the evidence
        where = traceback.extract_tb(exc.__traceback__)[-1]
        row.update(status=STATUS_FAILED, error_type=type(exc).__name__,
                   error=f"{exc} (at {where.filename.rsplit('/', 1)[-1]}:{where.lineno})")
    return row, arrays


def store_cell(store: ResultStore, row: dict, arrays: dict | None) -> dict:
    """Write a computed cell: arrays first, then the row that points to them."""
    if arrays is not None:
        row["artifact"] = store.write_arrays(row["cell_id"], arrays)
    store.write_row(row)
    return row


def run_cell(cell: Cell, results_dir: str) -> dict:
    """Compute one cell and store it in ``results_dir``; returns the row."""
    row, arrays = compute_cell(cell)
    return store_cell(ResultStore(results_dir), row, arrays)
