"""Point sets from files: their given normals screened, their stray points dropped (``flatten`` / ``inspect``).

A file's normal columns are data the methods trust, so wrong ones must not reach them:
columns only guessed to be normals (an XYZ file with no header naming them) that do not
fit the points are ignored with a warning, always; given normals that point to the other
side of the surface than their neighbours', or far off it, are flipped or dropped only
under ``--repair``, as are stray points (a scan's outliers), since that changes the data.
"""

from __future__ import annotations

import warnings
from dataclasses import replace

import numpy as np

from parambench.datasets_gen.surface import Surface
from parambench.methods.pointset.neighbourhoods import knn_graph
from parambench.methods.pointset.normals import MIN_NORMAL_ALIGNMENT, misoriented_normals, normal_alignment, pca_normals
from parambench.methods.pointset.stray_points import find_stray_points

__all__ = ["with_usable_normals", "without_stray_points", "screened_guessed_normals", "GUESSED_NORMAL_ALIGNMENT"]

#: Median |cos| between guessed normal columns and the normals fitted to the points (the
#: better of fits on ``k_nn`` and on ``3 k_nn`` neighbours) below which the columns are no
#: normals. Measured, true normals against the better fit: the generated surfaces' exact
#: normals (6 surfaces, random / graded / jittered, 3000 points) 0.977 or more clean and
#: 0.923 or more at normal noise of 0.5 spacings (8 neighbours alone: 0.797, as the noise
#: tilts small fits); area-weighted vertex normals of the shipped real meshes 0.919 or more
#: (cortex-lh; at 24 neighbours alone 0.843, its folds). Columns the test took for normals:
#: colours written as floats ((1, 0, 0), (0, 1, 0), (0, 0, 1)) 0.36, three signed scalar
#: fields 0.68.
GUESSED_NORMAL_ALIGNMENT = 0.8


def screened_guessed_normals(surface: Surface, k_nn: int) -> Surface:
    """``surface``, without normals that were only guessed from its file's columns and do not fit its points.

    Parameters
    ----------
    surface : Surface
        As :func:`~parambench.datasets_gen.io.load_surface` read it; ``params["normals_guessed"]``
        says whether its normals were guessed.
    k_nn : int
        Neighbours of the fit the normals are compared with.

    Returns
    -------
    Surface
        The same surface, or a copy without normals (``params["normals_dropped"]`` holding
        the median |cos|); a warning says so.
    """
    if surface.normals is None or not surface.params.get("normals_guessed") or surface.n_points <= k_nn:
        return surface
    # One graph of the larger neighbourhood; its rows are sorted by distance, so the first
    # k_nn columns are the smaller one.
    indices = knn_graph(surface.points, min(3 * k_nn, surface.n_points - 1)).indices
    align = max(normal_alignment(surface.normals, pca_normals(surface.points, indices[:, :k])) for k in
                (k_nn, indices.shape[1]))
    if align >= GUESSED_NORMAL_ALIGNMENT:
        return surface
    warnings.warn(f"{surface.name}: the columns after x y z were taken for normals but do not fit the points (median "
                  f"|cos| to the fitted normals {align:.2f}): ignored, normals are estimated; a header line naming "
                  "the columns (x y z nx ny nz) says which are normals.", stacklevel=2)
    return replace(surface, normals=None, params={**surface.params, "normals_dropped": round(float(align), 3)})


def _fit(surface: Surface, k_nn: int) -> tuple[float, np.ndarray]:
    """Median |cos| between the surface's normals and normals fitted on ``k_nn`` neighbours, and those neighbours."""
    # The graph the front end checks the normals on is near this one: its duplicates are
    # merged, and its gap-aware edges differ only across narrow gaps.
    indices = knn_graph(surface.points, k_nn).indices
    return normal_alignment(surface.normals, pca_normals(surface.points, indices)), indices


def with_usable_normals(surface: Surface, k_nn: int) -> tuple[Surface, str]:
    """A point set's given normals with the misoriented ones flipped, or dropped when far off the surface, and a
    note."""
    if surface.normals is None:
        return surface, ""
    align, indices = _fit(surface, k_nn)
    if align < MIN_NORMAL_ALIGNMENT:
        return (replace(surface, normals=None),
                f"; dropped the given normals (median |cos| to the fitted ones {align:.2f}): estimated instead")
    odd = misoriented_normals(surface.points, surface.normals, indices)
    if not odd.any():
        return surface, ""
    normals = surface.normals.copy()
    normals[odd] *= -1.0
    note = f"; flipped {int(odd.sum())} given normal(s) to agree with their neighbours"
    return replace(surface, normals=normals), note


def without_stray_points(surface: Surface, k_nn: int) -> tuple[Surface, int]:
    """A point set without its stray points (a scan's outliers), and how many there were.

    ``params["input_rows"]`` follows: the input row of each point kept.
    """
    stray = find_stray_points(surface.points, k_nn)
    if not stray.any():
        return surface, 0
    keep = ~stray
    normals = None if surface.normals is None else surface.normals[keep]
    rows = surface.params.get("input_rows")
    kept_rows = np.flatnonzero(keep) if rows is None else np.asarray(rows)[keep]
    params = {**surface.params, "stray_points_dropped": int(stray.sum()), "input_rows": kept_rows}
    return Surface(points=surface.points[keep], normals=normals, name=surface.name, params=params), int(stray.sum())
