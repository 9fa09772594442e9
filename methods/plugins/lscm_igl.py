"""``lscm-igl``: libigl's least-squares conformal map with two pinned boundary vertices."""

from __future__ import annotations

import igl
import numpy as np

from parambench.datasets_gen.errors import SolverError
from parambench.datasets_gen.surface import MethodInput

from ..base import Method, MethodOutput, StageTimer
from ..mesh.pins import farthest_pair
from ..mesh.topology import require_connected_disk_like
from ..registry import register


@register
class LscmIgl(Method):
    """Baseline: ``igl.lscm`` pinning the two boundary vertices farthest apart.

    The pins go to (0, 0) and (d, 0), d their 3D distance, so the map keeps the
    surface's scale roughly.
    """

    name = "lscm-igl"
    description = "libigl LSCM, the two boundary vertices farthest apart pinned (baseline)"
    needs_faces = True

    def solve(self, surface: MethodInput, params: dict, timer: StageTimer) -> MethodOutput:
        with timer("topology"):
            loops = require_connected_disk_like(surface.points, surface.faces)
            i, j = farthest_pair(surface.points, np.concatenate(loops))
        d = float(np.linalg.norm(surface.points[i] - surface.points[j]))
        with timer("solve"):
            try:
                uv, _ = igl.lscm(surface.points, surface.faces, np.array([i, j], dtype=np.int64),
                                 np.array([[0.0, 0.0], [d, 0.0]]))
            except RuntimeError as exc:  # libigl's own "igl::lscm failed": its sparse solve broke down
                raise SolverError(f"libigl's LSCM failed on {surface.name!r} ({exc}); check the mesh for "
                                  "degenerate or overlapping faces, or try --method scp.") from None
        uv = np.asarray(uv, dtype=np.float64)
        if not np.all(np.isfinite(uv)):
            raise SolverError(f"libigl's LSCM returned a non-finite map on {surface.name!r}; check the mesh for "
                              "degenerate or overlapping faces, or try --method scp.")
        return MethodOutput(uv, {"pins": [i, j], "n_boundary_loops": len(loops)})
