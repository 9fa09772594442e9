"""A checkerboard texture drawn on the 3D surface through each method's uv.

Conformal maps keep the checks square (sizes may vary); shear, stretch and foldovers show
as lozenges, smears and torn checks. Each triangle is split into a few sub-triangles (by
linear interpolation of position and uv) when the mesh is coarse, so checks have crisp
edges; each (sub-)triangle takes the colour of the check under its centroid, shaded by a
headlight so the relief reads. Faces are painted back to front (orthographic view).
"""

from __future__ import annotations

import math

import numpy as np
from matplotlib.collections import PolyCollection

from ..load import CellArrays
from ._common import (MAX_FACES_PER_PANEL, Picture, face_normals, figure_to_picture, new_figure, splat,
                      subsample_faces, view_projection, wrap_label)

__all__ = ["subdivision_barycentrics", "checker_parity", "checks_for_size", "checkerboard_figure", "CHECK_COLORS",
           "CHECKS_ACROSS"]

#: The two check colours (RGB in [0, 1]).
CHECK_COLORS = np.array([[0.96, 0.94, 0.88], [0.16, 0.35, 0.62]])
_NCOLS = 8
_PANEL_IN = 1.75
_TITLE_PT = 7.5
#: Lower than the default: eight panels across are printed about 9 inches wide.
_DPI = 90
#: Checks across the longer side of the uv bounding box on a large surface (the issue asks ~20).
CHECKS_ACROSS = 20
_MAX_LEVEL = 4
#: Sub-triangles a coarse mesh is split into, about, per panel: enough for crisp check edges.
_TARGET_PIECES = 12_000


def subdivision_barycentrics(level: int) -> np.ndarray:
    """Barycentric corners of the ``level**2`` sub-triangles of a regular triangle split.

    Parameters
    ----------
    level : int
        Splits per edge (1 = the triangle itself).

    Returns
    -------
    (level**2, 3, 3) numpy.ndarray of float64
        ``out[s, c]`` are the barycentric weights of corner ``c`` of sub-triangle ``s``.
    """
    tris = []
    for i in range(level):
        for j in range(level - i):
            up = [(i, j), (i + 1, j), (i, j + 1)]
            tris.append(up)
            if j < level - i - 1:
                tris.append([(i + 1, j), (i + 1, j + 1), (i, j + 1)])
    ij = np.asarray(tris, dtype=np.float64) / level  # (S, 3, 2): weights of corners 1 and 2
    return np.concatenate([1.0 - ij.sum(axis=2, keepdims=True), ij], axis=2)


def checker_parity(uv: np.ndarray, n_checks: int = 8) -> np.ndarray:
    """Which check each uv point falls in: 0 or 1, alternating.

    The longer side of the uv bounding box holds ``n_checks`` checks; the checks are square.

    Parameters
    ----------
    uv : (K, 2) numpy.ndarray of float64
    n_checks : int

    Returns
    -------
    (K,) numpy.ndarray of int64
    """
    lo = uv.min(axis=0)
    extent = float((uv.max(axis=0) - lo).max())
    scaled = (uv - lo) * (n_checks / extent if extent > 0 else 1.0)
    cells = np.floor(scaled).astype(np.int64)
    return (cells[:, 0] + cells[:, 1]) % 2


def checks_for_size(n_points: int) -> int:
    """Checks across a surface of ``n_points`` vertices: about :data:`CHECKS_ACROSS`.

    A check should span a couple of mesh edges at least, or it shows the triangulation
    rather than the map: about sqrt(N) / 2 checks across, capped at :data:`CHECKS_ACROSS`
    and at least 6.

    Parameters
    ----------
    n_points : int

    Returns
    -------
    int
    """
    return int(min(CHECKS_ACROSS, max(6, round(0.5 * math.sqrt(max(n_points, 1))))))


def _draw_panel(ax, label: str, arrays: CellArrays, n_checks: int, max_faces: int, seed: int) -> None:
    ax.set_title(wrap_label(label, _PANEL_IN, _TITLE_PT, 3), fontsize=_TITLE_PT)
    ax.set_aspect("equal")
    ax.set_axis_off()
    if not np.isfinite(arrays.uv).all():
        ax.text(0.5, 0.5, "uv has NaN or inf", ha="center", va="center", transform=ax.transAxes, fontsize=9)
        return
    shown = subsample_faces(len(arrays.faces), max_faces, seed=seed)
    faces = arrays.faces[shown]
    target = min(max_faces, _TARGET_PIECES)
    level = int(min(_MAX_LEVEL, max(1, math.isqrt(max(1, target // max(1, len(faces)))))))
    bary = subdivision_barycentrics(level)  # (S, 3, 3)
    xy, depth, view = view_projection(arrays.points, arrays.faces)
    # Sub-triangle corners: (M, S, 3, k) = sum over the face's corners of weight * value.
    corner_xy = splat(np.einsum("scd,mdk->msck", bary, xy[faces]).reshape(-1, 3, 2),
                      len(arrays.faces) * len(bary))
    corner_uv = np.einsum("scd,mdk->msck", bary, arrays.uv[faces]).reshape(-1, 3, 2)
    corner_depth = np.einsum("scd,md->msc", bary, depth[faces]).reshape(-1, 3)
    parity = checker_parity(corner_uv.mean(axis=1), n_checks) if len(corner_uv) else np.zeros(0, int)
    cosine = np.abs(face_normals(arrays.points, faces) @ view)
    shade = np.repeat(0.45 + 0.55 * cosine, len(bary))[:, None]
    colors = CHECK_COLORS[parity] * shade
    order = np.argsort(corner_depth.mean(axis=1), kind="stable")  # far first: painter's algorithm
    # Edges in the face colour close the hairline gaps between pieces; no anti-aliasing
    # keeps tens of thousands of polygons per panel affordable.
    ax.add_collection(PolyCollection(corner_xy[order], facecolors=colors[order], edgecolors="face",
                                     linewidths=0.15, antialiased=False))
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    pad = 0.03 * max(float((hi - lo).max()), 1e-12)
    ax.set_xlim(lo[0] - pad, hi[0] + pad)
    ax.set_ylim(lo[1] - pad, hi[1] + pad)


def checkerboard_figure(panels: list[tuple[str, CellArrays]], title: str, *, n_checks: int | None = None,
                        max_faces: int = MAX_FACES_PER_PANEL, seed: int = 0) -> Picture:
    """Texture each method's map with a checkerboard and draw it on the surface.

    Parameters
    ----------
    panels : list of (label, CellArrays)
        At least one.
    title : str
        The surface's name.
    n_checks : int, optional
        Checks along the longer side of each uv bounding box; default from the surface's
        size (:func:`checks_for_size`).
    max_faces : int
        Triangles (after subdivision) drawn per panel, about.
    seed : int
        Seed of the subsampling of large meshes.

    Returns
    -------
    Picture
    """
    if not panels:
        raise ValueError("checkerboard_figure needs at least one panel.")
    if n_checks is None:
        n_checks = checks_for_size(max(len(a.points) for _, a in panels))
    ncols = min(_NCOLS, len(panels))
    nrows = math.ceil(len(panels) / ncols)
    fig = new_figure(_PANEL_IN * ncols, (_PANEL_IN + 0.35) * nrows)
    axes = np.atleast_1d(fig.subplots(nrows, ncols, squeeze=False)).ravel()
    for ax, (label, arrays) in zip(axes, panels):
        _draw_panel(ax, label, arrays, n_checks, max_faces, seed)
    where = {label: ax for (label, _), ax in zip(panels, axes)}
    for ax in axes[len(panels):]:
        ax.set_axis_off()
    caption = (f"A {n_checks}-check checkerboard mapped onto {title} through each method's uv. Square checks "
               f"mean an angle-preserving map; lozenges show shear, smeared or torn checks show foldovers.")
    return figure_to_picture(fig, f"Checkerboard texture — {title}", caption, rows=nrows, panel_axes=where,
                             dpi=_DPI)
