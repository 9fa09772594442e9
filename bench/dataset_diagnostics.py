"""Per-surface diagnostics for the report: weight histograms and the detected boundary.

Computed once per surface of a sweep (not per method), in the process that writes the
results, for surfaces up to ``MAX_POINTS`` points. The paper's Fig. 5 compares W^tan with
cotangent weights at interior and boundary points; both are row-normalised here so the
two are on the same scale.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from parambench.datasets_gen.errors import InvalidInputError, ParambenchError
from parambench.datasets_gen.surface import Surface
from parambench.methods.mesh.weights import mesh_weights
from parambench.methods.pointset.frontend import build_frontend

from .cells import Cell
from .run_cell import _method_input, surface_for
from .schema import encode_loops
from .storage import ResultStore

__all__ = ["surface_diagnostics", "store_missing_diagnostics", "MAX_POINTS"]

MAX_POINTS = 200_000


def _split_rows(W: sp.csr_matrix, interior: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    W = W.tocsr()
    counts = np.diff(W.indptr)
    row_is_interior = np.repeat(interior, counts)
    return W.data[row_is_interior], W.data[~row_is_interior]


def surface_diagnostics(surface: Surface) -> dict:
    """Arrays for the report's weight histograms and boundary pictures.

    Returns
    -------
    dict of numpy arrays
        ``points``; ``w_tan_interior``/``w_tan_boundary`` (W^tan entries of interior and
        boundary rows); ``w_cot_*`` likewise for row-normalised cotangent weights when the
        surface has faces; ``det_boundary_mask`` and ``det_loops_*`` (angle criterion);
        ``gt_loops_*`` when the ground truth is known. ``w_cot_*`` are left out when a
        cotangent row sums to <= 0 (it cannot be normalised).

    Raises
    ------
    ParambenchError
        When the front end refuses the points (e.g. a closed surface).
    """
    # The front end as the point-set methods of the sweep run it: no generator normals.
    front = build_frontend(surface.points, _method_input(surface, needs_faces=False).normals)
    truth = surface.boundary_mask if surface.boundary_mask is not None else front.boundary_mask
    arrays = {"points": surface.points.astype(np.float32), "det_boundary_mask": front.boundary_mask}
    arrays["w_tan_interior"], arrays["w_tan_boundary"] = _split_rows(front.W, ~truth)
    if surface.faces is not None:
        try:
            cot = mesh_weights(surface.points, surface.faces, "cotangent", normalized=True)
        except InvalidInputError:
            cot = None  # a row summing to <= 0: no cotangent histogram, the W^tan one stays
        if cot is not None:
            arrays["w_cot_interior"], arrays["w_cot_boundary"] = _split_rows(cot, ~truth)
    arrays.update(encode_loops("det", front.boundary_loops))
    arrays.update(encode_loops("gt", surface.boundary_loops))
    return arrays


def store_missing_diagnostics(store: ResultStore, cells: list[Cell]) -> list[str]:
    """Compute and store diagnostics for each surface of ``cells`` that has none yet.

    Failures are not fatal (the report simply has no histogram for that surface); their
    messages are returned.
    """
    problems = []
    seen = set()
    for cell in cells:
        key = cell.dataset_key
        if key in seen or store.has_arrays(key):
            continue
        seen.add(key)
        try:
            surface = surface_for(cell.dataset, cell.size, cell.sampling, cell.noise, cell.seed)
            if surface.n_points > MAX_POINTS:
                continue
            store.write_arrays(key, surface_diagnostics(surface), folder="datasets")
        except (ParambenchError, ArithmeticError, MemoryError, ValueError) as exc:
            # Optional pictures: a surface that cannot be rebuilt (its cells already say why)
            # must not stop the sweep before its table and report are written.
            problems.append(f"{key}: {type(exc).__name__}: {exc}")
    return problems
