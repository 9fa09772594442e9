"""``bff-mouette``: Boundary First Flattening (Sawhney & Crane 2017) through the ``mouette`` package.

BFF finds the boundary curve first (from target scale factors or curvatures along the
boundary), then extends it conformally inside. Run here with zero boundary scale factors
(boundary lengths kept), the free-boundary conformal map of the paper's default, and
mouette's defaults otherwise (cotangent Laplacian, Hilbert-transform extension).

Two things about ``mouette.processing.parametrization.BoundaryFirstFlattening`` (1.2.8):

* Left without boundary data it builds its zero scale factors with one entry per
  *boundary* vertex and then indexes them by *vertex* id, which fails (IndexError) on
  any mesh whose boundary vertices are not numbered first; a zero factor for every
  vertex is passed instead.
* It renumbers the vertices, boundary loop first (``_vertex_permutation``: new index ->
  input index); the uv rows are put back in input order, after checking that the
  renumbered positions are the input's.

mouette maps topological disks only (one boundary loop). As the reference BFF
application does (its ``HoleFiller``: every hole but the longest loop filled), holes are
closed by patches (:func:`~parambench.methods.mesh.holes.fill_holes`, the fill of the
mesh methods' ``holes="filled"``) and the patches' vertices dropped from the output;
``holes="refuse"`` raises NotADiskError instead, as every mesh with holes did before (the
quick sweep's one failed cell, ``holes``). mouette assembles its matrices in Python loops: about 11 s at
20k vertices on one core (measured), so it is the slowest mesh baseline.
"""

from __future__ import annotations

import numpy as np

from parambench.datasets_gen.errors import NotADiskError, SolverError
from parambench.datasets_gen.surface import MethodInput

from ..base import Method, MethodOutput, StageTimer
from ..mesh.holes import fill_holes
from ..mesh.topology import require_connected_disk_like
from ..registry import register

__all__ = ["BffMouette", "bff_uv"]


def bff_uv(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """BFF with zero boundary scale factors, uv in input vertex order.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    faces : (M, 3) numpy.ndarray of int64
        A triangulated topological disk (checked by the caller).

    Returns
    -------
    (N, 2) numpy.ndarray of float64
        Row i is the image of ``points[i]``; boundary lengths are those of the surface.

    Raises
    ------
    SolverError
        mouette failed, renumbered the vertices in a way that cannot be undone, or
        returned non-finite uv.
    """
    # Imported here: mouette takes over a second to import, and only this method needs it.
    import mouette
    from mouette.processing.parametrization import BoundaryFirstFlattening

    n = points.shape[0]
    mesh = mouette.mesh.from_arrays(np.asarray(points, dtype=np.float64), F=np.asarray(faces, dtype=np.int64))
    bff = BoundaryFirstFlattening(mesh, bnd_scale_fctr=np.zeros(n), save_on_corners=False)
    try:
        bff.run()
    except Exception as exc:  # mouette raises bare Exception / numpy errors
        raise SolverError(f"mouette's BFF failed ({type(exc).__name__}: {exc}); try 'scp-igl'.") from exc
    perm = getattr(bff, "_vertex_permutation", None)
    perm = np.asarray([] if perm is None else perm, dtype=np.int64)
    if perm.shape != (n,) or not np.array_equal(np.sort(perm), np.arange(n)) \
            or not np.array_equal(np.asarray(bff.mesh.vertices, dtype=np.float64), points[perm]):
        raise SolverError("mouette's BFF renumbered the vertices in a way parambench cannot undo "
                          "(an unsupported mouette version?); pin mouette 1.2.x or use 'scp-igl'.")
    uv_new = np.asarray(bff.uvs.as_array(), dtype=np.float64).reshape(n, -1)[:, :2]
    uv = np.empty((n, 2))
    uv[perm] = uv_new  # new vertex i is input vertex perm[i]
    if not np.all(np.isfinite(uv)):
        raise SolverError("mouette's BFF returned non-finite uv; check the mesh for degenerate faces or use 'scp-igl'.")
    return uv


@register
class BffMouette(Method):
    """Baseline: Boundary First Flattening (``mouette``), zero boundary scale factors.

    Free boundary, no pins; uv in input vertex order, centred, at the surface's own scale
    (boundary lengths kept). Holes filled by default (``holes="filled"``), or refused.
    """

    name = "bff-mouette"
    description = "Boundary First Flattening, zero boundary scale factors (Sawhney & Crane 2017; mouette; baseline)"
    needs_faces = True
    defaults = {"holes": "filled"}
    choices = {"holes": ("filled", "refuse")}

    def solve(self, surface: MethodInput, params: dict, timer: StageTimer) -> MethodOutput:
        with timer("topology"):
            loops = require_connected_disk_like(surface.points, surface.faces)
            if len(loops) != 1 and params["holes"] == "refuse":
                raise NotADiskError(f"{surface.name!r} has {len(loops)} boundary loops; BFF (bff-mouette) maps "
                                    "topological disks only: leave holes='filled' (the default) to fill them, or use "
                                    "'scp-igl' or 'scp'.")
            work, n_filled = fill_holes(surface) if len(loops) > 1 else (surface, 0)
        with timer("solve"):
            uv = bff_uv(work.points, work.faces)[: surface.n_points]
        uv -= uv.mean(axis=0)
        return MethodOutput(uv, {"n_boundary_loops": len(loops), "boundary_scale_factor": 0.0,
                                 "holes_filled": n_filled})
