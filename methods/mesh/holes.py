"""Virtual hole filling: a centre vertex and a fan of triangles per inner boundary loop.

The conformal energy ``k E_W(u) - A(u)`` counts a hole's enclosed area with a minus sign,
so turning a hole inside out *lowers* ``-A``. With cotangent weights every folded
triangle costs at least twice its area (``E_D >= |area|`` per triangle), which keeps
holes open; with other weights nothing does, and on ``real/bunny10k`` (5 small holes)
uniform, authalic, mean-value and every normalized kind turned holes inside out at
every k (SCP with uniform weights: turning numbers ``[1, 1, -1, 1, -1]`` from k = 1.02
to 1.3, and ``k_search="direct"`` found no regular map either). Filling each hole with a
fan makes the mesh a disk: the hole's image is then the image of its fan, whose
triangles carry weights like any others, and the map is solved for one boundary loop.
The centre vertices are dropped from the output. The methods' ``holes="auto"`` fills
only where the free holes fail (:func:`solve_with_holes`): filling changes the map (uniform
DNCP on the planar ``holes`` surface: k_opt 1.19 filled, 1.00 free).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from parambench.datasets_gen.errors import ConvergenceError, InvalidInputError, SolverError, TopologyError, released
from parambench.datasets_gen.surface import MethodInput

from ..spectral.turning import is_regular_turning
from .topology import require_connected_disk_like

__all__ = ["HOLES_MODES", "fill_holes", "solve_with_holes"]

#: ``holes`` parameter of the mesh methods.
HOLES_MODES = ("auto", "free", "filled")


def fill_holes(surface: MethodInput) -> tuple[MethodInput, int]:
    """``surface`` with every boundary loop but the longest closed by a fan around its centroid.

    Parameters
    ----------
    surface : MethodInput
        With faces; connected and disk-like (one outer loop, any number of holes).

    Returns
    -------
    filled : MethodInput
        The original vertices first (same indices), then one centre vertex per hole; the
        original faces first, then the fans, oriented like the faces around each hole.
        A surface with one boundary loop is returned unchanged.
    n_holes : int

    Raises
    ------
    DisconnectedError, NotADiskError
        From :func:`parambench.methods.mesh.topology.require_connected_disk_like`.
    """
    pts, faces = surface.points, surface.faces
    loops = require_connected_disk_like(pts, faces)
    holes = loops[1:]
    if not holes:
        return surface, 0
    n = pts.shape[0]
    centres = np.array([pts[loop].mean(axis=0) for loop in holes])
    fans = []
    for h, loop in enumerate(holes):
        # The loop runs along its boundary edges in the faces' direction (a -> b), so the
        # fan triangle on that edge has it reversed: (b, a, centre).
        a, b = loop, np.roll(loop, -1)
        fans.append(np.column_stack([b, a, np.full(loop.size, n + h)]))
    filled = MethodInput(np.vstack([pts, centres]), np.vstack([faces, *fans]).astype(np.int64),
                         name=f"{surface.name} (holes filled)")
    return filled, len(holes)


def solve_with_holes(surface: MethodInput, holes: str, attempt: Callable[[MethodInput], tuple],
                     fill: Callable[[MethodInput], tuple[MethodInput, int]] = fill_holes) -> tuple[tuple, MethodInput, int]:
    """Run a method's ``attempt`` with the holes free, filled, or filled where free fails.

    Parameters
    ----------
    surface : MethodInput
    holes : {"auto", "free", "filled"}
        ``"auto"``: free first (the natural boundary condition; plain cotangent weights
        keep holes open, and filling would change their map), then filled when that
        attempt raises :class:`SolverError` / :class:`ConvergenceError` or returns a map
        whose boundary is not regular. Free is also all there is for one boundary loop.
    attempt : callable
        ``attempt(surface) -> (problem, solution, ...)``: ``result[1]`` is the solution
        (its ``turning`` and ``diagnostics`` are read).
    fill : callable
        ``fill(surface) -> (filled surface, holes filled)``; :func:`fill_holes` (fans, for
        meshes) by default; point sets pass
        :func:`parambench.methods.pointset.hole_filling.fill_point_holes` through a closure.

    Returns
    -------
    result : tuple
        What the successful ``attempt`` returned.
    work : MethodInput
        The surface it ran on; its first ``surface.n_points`` vertices are the surface's.
    n_filled : int
        Holes filled (0 when free).

    Raises
    ------
    SolverError, ConvergenceError
        From the free attempt, when the filled one fails too (``"auto"``: also with a
        :class:`TopologyError` or :class:`InvalidInputError` on the filled surface), or
        from the only attempt.
    """
    if holes == "filled":
        work, n = fill(surface)
        return attempt(work), work, n
    first_error = None
    try:
        result = attempt(surface)
    except (SolverError, ConvergenceError) as err:
        if holes == "free":
            raise
        first_error = released(err)  # held through the filled attempt: not its frames
    else:
        sol = result[1]
        if holes == "free" or (sol.diagnostics.get("regular_boundary", True) and is_regular_turning(sol.turning)):
            return result, surface, 0
    work, n = fill(surface)
    if n == 0:
        if first_error is not None:
            raise first_error
        return result, surface, 0
    try:
        return attempt(work), work, n
    except (SolverError, TopologyError, InvalidInputError):
        # The filled surface is ours, not the caller's: its input errors are this
        # fallback failing (fill points that split a point set's kNN graph, scan lines
        # 10 spacings apart at k_nn=12), not advice about the input.
        if first_error is not None:
            raise first_error from None
        # the free map is irregular but exists: the benchmark measures it
        return result, surface, 0
