"""``scp-igl``: libigl's spectral conformal parameterization (Mullen et al. 2008)."""

from __future__ import annotations

import igl.spectra
import numpy as np

from parambench.datasets_gen.errors import SolverError
from parambench.datasets_gen.surface import MethodInput

from ..base import Method, MethodOutput, StageTimer
from ..memory_budget import PeakMemory
from ..mesh.topology import require_connected_disk_like
from ..registry import register


@register
class ScpIgl(Method):
    """Baseline: ``igl.spectra.lscm`` (SCP with the mass matrix as B)."""

    name = "scp-igl"
    description = "libigl spectral conformal parameterization, igl.spectra.lscm (baseline)"
    needs_faces = True
    # bump: 300k vertices 1.87 GiB at the peak (random), 1M 10.4 GB (jittered, issue #14's figure).
    peak_memory = PeakMemory(1_000_000, 10.4e9, 1.37)

    def solve(self, surface: MethodInput, params: dict, timer: StageTimer) -> MethodOutput:
        with timer("topology"):
            loops = require_connected_disk_like(surface.points, surface.faces)
        with timer("solve"):
            try:
                uv = igl.spectra.lscm(surface.points, surface.faces)
            except RuntimeError as exc:  # libigl's own solver failure
                raise SolverError(f"igl.spectra.lscm failed on {surface.name!r} ({exc}); check the mesh for "
                                  "degenerate or overlapping faces, or try --method scp.") from None
        uv = np.asarray(uv, dtype=np.float64)
        if not np.all(np.isfinite(uv)) or np.ptp(uv, axis=0).min() <= 0:
            raise SolverError(f"igl.spectra.lscm returned a degenerate map on {surface.name!r}; "
                              "check the mesh for degenerate or duplicated faces.")
        return MethodOutput(uv, {"n_boundary_loops": len(loops)})
