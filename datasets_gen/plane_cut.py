"""Open a closed mesh by a plane: the real-data cases whose rim runs across triangles.

A scan trimmed by a plane (or a closed model cut open, as ``real/spot-top`` is) has a
boundary that zigzags through the triangles the plane crossed: every other rim vertex is
a notch, with an open angle under the boundary detector's 120 degrees. Generated surfaces
never have such a rim, so the detector and ``ocp`` are also measured on cuts of meshes
nobody here made (pymeshlab's Stanford bunny, ``tests/methods/test_ocp_cut_scan.py`` and
``bench/benchmarks/bench_realdata.py``).
"""

from __future__ import annotations

import numpy as np

from .errors import InvalidInputError
from .mesh_loops import mesh_boundary
from .repair import largest_piece, repair_surface
from .surface import Surface

__all__ = ["cut_by_plane"]


def cut_by_plane(surface: Surface, axis: int, quantile: float, *, keep_above: bool = True,
                 name: str | None = None) -> Surface:
    """The largest piece of a mesh on one side of an axis-aligned plane.

    Faces with all three vertices strictly on the kept side of the plane
    ``x[axis] = quantile of x[axis] over the vertices`` are kept; the largest connected
    piece of them is returned (:func:`~parambench.datasets_gen.repair.repair_surface`),
    with the mesh's boundary loops as ground truth.

    Parameters
    ----------
    surface : Surface
        A mesh (``faces`` set).
    axis : int
        0, 1 or 2: the coordinate the plane is normal to.
    quantile : float
        In (0, 1): where the plane lies, as a quantile of the vertices' coordinate.
    keep_above : bool
        Keep the faces above the plane (larger coordinate) or below it.
    name : str, optional
        Name of the result; default ``"{surface.name}-cut{axis}{'>' or '<'}{quantile:g}"``.

    Returns
    -------
    Surface
        Renumbered vertices and faces, ``boundary_loops`` (longest first) and
        ``boundary_mask`` from the faces; ``params["cut"]`` holds the arguments.

    Raises
    ------
    InvalidInputError
        No faces, an axis other than 0-2, a quantile outside (0, 1), no face kept, or a
        cut with no boundary loop.
    """
    if surface.faces is None:
        raise InvalidInputError(f"{surface.name}: a plane cut needs a mesh; this is a point set.")
    if axis not in (0, 1, 2):
        raise InvalidInputError(f"axis must be 0, 1 or 2, got {axis!r}.")
    if not 0.0 < quantile < 1.0:
        raise InvalidInputError(f"quantile must lie in (0, 1), got {quantile!r}.")
    coordinate = surface.points[:, axis]
    level = np.quantile(coordinate, quantile)
    side = coordinate[surface.faces]
    kept = (side > level).all(axis=1) if keep_above else (side < level).all(axis=1)
    if not kept.any():
        raise InvalidInputError(f"{surface.name}: no face lies on the kept side of the plane.")
    label = name or f"{surface.name}-cut{axis}{'>' if keep_above else '<'}{quantile:g}"
    # The cut's largest piece by construction, even beside pieces of comparable size (two ear
    # tips), which repair_surface refuses to choose between for a user's file.
    faces, _ = largest_piece(surface.faces[kept], len(surface.points))
    piece, facts = repair_surface(Surface(points=surface.points, faces=faces, name=label,
                                          params={"cut": {"axis": axis, "quantile": quantile,
                                                          "keep_above": keep_above}}))
    loops, mask = mesh_boundary(piece.faces, len(piece.points))
    if not loops:
        raise InvalidInputError(f"{label}: the cut piece has no boundary loop.")
    return Surface(points=piece.points, faces=piece.faces, name=label, params=piece.params,
                   boundary_mask=mask, boundary_loops=loops)
