"""Virtual hole filling: every inner boundary loop closed by a patch of triangles.

The conformal energy ``k E_W(u) - A(u)`` counts a hole's enclosed area with a minus sign,
so turning a hole inside out *lowers* ``-A``. With cotangent weights every folded
triangle costs at least twice its area (``E_D >= |area|`` per triangle), which keeps
holes open; with other weights nothing does, and on ``real/bunny10k`` (5 small holes)
uniform, authalic, mean-value and every normalized kind turned holes inside out at
every k (SCP with uniform weights: turning numbers ``[1, 1, -1, 1, -1]`` from k = 1.02
to 1.3, and ``k_search="direct"`` found no regular map either). Filling each hole makes
the mesh a disk: the hole's image is then the image of its patch, whose triangles carry
weights like any others, and the map is solved for one boundary loop. The patch's
vertices are dropped from the output. The methods' ``holes="auto"`` fills only where the
free holes fail (:func:`solve_with_holes`): filling changes the map (uniform DNCP on the
planar ``holes`` surface: k_opt 1.19 filled, 1.00 free).

The patch is pymeshlab's hole closing with refinement (``meshing_close_holes``): triangles
of about the rim's edge length that follow the rim's shape. A fan round the rim's centroid,
the earlier fill and now the fallback where pymeshlab leaves a hole open, has long thin
triangles, and where the rim is not convex seen from its centroid they overlap: ``scp`` with
``holes="filled"`` (forty-third session, fan -> patch, QC mean on the mesh): the ``slit``
plane 1.0070 -> 1.0000 (6.3e-3 -> 2.5e-6 of the diameter from its exact map),
``holes-bumped`` 1.0103 -> 1.0076, pymeshlab's bunny cut into bands by two planes 1.0878
with 1 foldover -> 1.0241 with 0, and with two small holes too 1.0876 with 32 foldovers ->
1.0332 with 0; ``holes`` and bunny10k the same to 3e-4. It costs 0.4-0.9 s more (pymeshlab's
import and mesh set-up), only where a hole is filled.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from parambench.datasets_gen.errors import ConvergenceError, InvalidInputError, SolverError, TopologyError, released
from parambench.datasets_gen.surface import MethodInput, degenerate_faces

from ..geometry2d import flipped_triangles
from ..spectral.turning import is_regular_turning
from .map_check import boundary_crossings
from .topology import require_connected_disk_like

__all__ = ["HOLES_MODES", "fill_holes", "solve_with_holes"]

#: ``holes`` parameter of the mesh methods.
HOLES_MODES = ("auto", "free", "filled")


def fill_holes(surface: MethodInput) -> tuple[MethodInput, int]:
    """``surface`` with every boundary loop but the longest closed by a patch of triangles.

    Parameters
    ----------
    surface : MethodInput
        With faces; connected and disk-like (one outer loop, any number of holes).

    Returns
    -------
    filled : MethodInput
        The original vertices first (same indices and positions), then the patches'
        vertices; its faces are consistently oriented with the original ones and it has
        one boundary loop, the longest. A surface with one boundary loop is returned
        unchanged.
    n_holes : int

    Raises
    ------
    DisconnectedError, NotADiskError
        From :func:`parambench.methods.mesh.topology.require_connected_disk_like`.
    """
    pts, faces = surface.points, surface.faces
    loops = require_connected_disk_like(pts, faces)
    if len(loops) < 2:
        return surface, 0
    outer = int(np.argmax([loop.size for loop in loops]))
    work_pts, work_faces, open_loops = pts, faces, [loop for i, loop in enumerate(loops) if i != outer]
    patched = _closed_by_pymeshlab(pts, faces, max(loop.size for loop in loops) - 1)
    if patched is not None:
        try:
            left = require_connected_disk_like(*patched)
        except TopologyError:  # a patch that is not a disk's: the fans instead
            left = None
        # A hole whose rim passes a vertex twice (two copies where a pinch was split) got
        # a patch triangle joining the copies: no area, refused. The fans join no two
        # rim vertices.
        if left is not None and degenerate_faces(*patched).any():
            left = None
        if left is not None:
            keep = int(np.argmax([loop.size for loop in left]))
            work_pts, work_faces = patched
            open_loops = [loop for i, loop in enumerate(left) if i != keep]
    work_pts, work_faces = _fans(work_pts, work_faces, open_loops)
    filled = MethodInput(work_pts, work_faces.astype(np.int64), name=f"{surface.name} (holes filled)")
    return filled, len(loops) - 1


def _closed_by_pymeshlab(pts: np.ndarray, faces: np.ndarray, max_edges: int
                         ) -> tuple[np.ndarray, np.ndarray] | None:
    """Holes of at most ``max_edges`` edges closed by pymeshlab (refined patches), the input's
    vertices first and unchanged; None where pymeshlab fails or moves them."""
    import pymeshlab  # imported only where a hole is filled

    n = pts.shape[0]
    try:
        ms = pymeshlab.MeshSet()
        ms.add_mesh(pymeshlab.Mesh(np.asarray(pts, dtype=np.float64), np.asarray(faces, dtype=np.int32)))
        ms.meshing_close_holes(maxholesize=int(max_edges), refinehole=True)
        mesh = ms.current_mesh()
        out_pts, out_faces = mesh.vertex_matrix(), mesh.face_matrix()
    except pymeshlab.PyMeshLabException:
        return None
    if out_pts.shape[0] < n or not np.allclose(out_pts[:n], pts, rtol=0.0, atol=1e-6 * float(np.ptp(pts))):
        return None
    out_pts = np.array(out_pts, dtype=np.float64)
    out_pts[:n] = pts  # pymeshlab may round the originals; the map is theirs
    return out_pts, np.asarray(out_faces, dtype=np.int64)


def _fans(pts: np.ndarray, faces: np.ndarray, holes: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Each of ``holes`` closed by a fan round a new vertex at its centroid."""
    if not holes:
        return pts, faces
    n = pts.shape[0]
    centres = np.array([pts[loop].mean(axis=0) for loop in holes])
    fans = []
    for h, loop in enumerate(holes):
        # The loop runs along its boundary edges in the faces' direction (a -> b), so the
        # fan triangle on that edge has it reversed: (b, a, centre).
        a, b = loop, np.roll(loop, -1)
        fans.append(np.column_stack([b, a, np.full(loop.size, n + h)]))
    return np.vstack([pts, centres]), np.vstack([faces, *fans])


def _overlaps(surface: MethodInput, sol) -> int:
    """Flipped triangles and crossing boundary edges of a mesh's map, on the surface's own faces; 0 for a point set.

    Each loop can turn once and the loops still overlap: pymeshfix's Stanford bunny,
    repaired (5 scan holes and 52 of 3-8 edges where faces on non-manifold edges were
    dropped), mapped by ``scp`` with every loop turning once and 26 crossings, a failed
    check with advice about helical strips; filled, 1 flipped triangle and no crossing.
    """
    z = getattr(sol, "z", None)
    if surface.faces is None or z is None:
        return 0
    z = np.asarray(z)[: surface.n_points]
    if not np.all(np.isfinite(z)):
        return surface.faces.shape[0]
    uv = np.column_stack([z.real, z.imag])
    return int(flipped_triangles(uv, surface.faces).sum()) + boundary_crossings(uv, surface.faces)


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
        whose boundary is not regular; for a mesh also when the free map overlaps itself
        (flipped triangles, boundary images that cross) and the filled one less. Free is
        also all there is for one boundary loop.
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
    first_error, regular, overlaps = None, False, 0
    try:
        result = attempt(surface)
    except (SolverError, ConvergenceError) as err:
        if holes == "free":
            raise
        first_error = released(err)  # held through the filled attempt: not its frames
    else:
        sol = result[1]
        regular = sol.diagnostics.get("regular_boundary", True) and is_regular_turning(sol.turning)
        # one loop: nothing to fill, and the method's own check counts its overlaps anyway
        holed = np.size(sol.turning) > 1
        overlaps = _overlaps(surface, sol) if regular and holed and holes != "free" else 0
        if holes == "free" or (regular and not overlaps):
            return result, surface, 0
    try:
        work, n = fill(surface)
        if n == 0:
            if first_error is not None:
                raise first_error
            return result, surface, 0
        filled = attempt(work)
        # a regular free map that overlaps is kept unless filling overlaps less (face000:
        # free 1 flip and 2 crossings, filled 2 and 3)
        if first_error is None and regular and _overlaps(surface, filled[1]) >= overlaps:
            return result, surface, 0
        return filled, work, n
    except (SolverError, TopologyError, InvalidInputError) as err:
        if err is first_error:
            raise
        # The filled surface is ours, not the caller's: its input errors are this
        # fallback failing (fill points that split a point set's kNN graph, scan lines
        # 10 spacings apart at k_nn=12), not advice about the input.
        if first_error is not None:
            raise first_error from None
        # the free map is irregular but exists: the benchmark measures it
        return result, surface, 0
