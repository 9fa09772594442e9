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
The centre vertices are dropped from the output.
"""

from __future__ import annotations

import numpy as np

from parambench.datasets_gen.surface import Surface

from .topology import require_connected_disk_like

__all__ = ["HOLES_MODES", "fill_holes", "holes_filled_by_default"]

#: ``holes`` parameter of the mesh methods.
HOLES_MODES = ("auto", "free", "filled")


def holes_filled_by_default(weights: str, normalized: bool) -> bool:
    """Whether ``holes="auto"`` fills the holes for these weights.

    Only the exact Dirichlet energy (cotangent weights, not normalized) and the hybrid
    weights built on it keep holes open by themselves; those are left free so that their
    maps are unchanged (free holes are the natural boundary condition of the conformal map).
    """
    return not (weights in ("cotangent", "hybrid") and not normalized)


def fill_holes(surface: Surface) -> tuple[Surface, int]:
    """``surface`` with every boundary loop but the longest closed by a fan around its centroid.

    Parameters
    ----------
    surface : Surface
        With faces; connected and disk-like (one outer loop, any number of holes).

    Returns
    -------
    filled : Surface
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
    filled = Surface(np.vstack([pts, centres]), np.vstack([faces, *fans]).astype(np.int64),
                     name=f"{surface.name} (holes filled)")
    return filled, len(holes)


def surface_for_solve(surface: Surface, holes: str, weights: str, normalized: bool) -> tuple[Surface, int]:
    """The surface a mesh method solves on: ``surface``, or it with its holes filled.

    Parameters
    ----------
    surface : Surface
    holes : {"auto", "free", "filled"}
        ``"auto"``: filled where :func:`holes_filled_by_default` says so.
    weights, normalized
        The method's weights.

    Returns
    -------
    work : Surface
        Its first ``surface.n_points`` vertices are the surface's; crop the map to them.
    n_filled : int
        Holes filled (0 when left free or when there are none).
    """
    if holes == "free" or (holes == "auto" and not holes_filled_by_default(weights, normalized)):
        return surface, 0
    return fill_holes(surface)
