"""What the point-set methods' two-level solves share: the coarse level of a front end, and SDP's pair.

``ocp`` and ``sdp`` with ``solver="multilevel"`` (:mod:`parambench.methods.spectral.multilevel`,
:mod:`parambench.methods.spectral.multilevel_dirichlet`) both solve first on a Poisson-disk
subsample of the points with the boundary loops kept; ``ocp`` also takes SDP's pair on two
levels where its mesh fallback needs one at sizes where a direct solve costs minutes and
gigabytes.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..base import StageTimer

if TYPE_CHECKING:  # the spectral modules compile numba kernels on import: imported where used
    from ..spectral.multilevel import MultilevelSettings
    from .frontend import FrontEnd

__all__ = ["coarse_subsample", "two_level_sdp_pair"]


def coarse_subsample(front: "FrontEnd", settings: "MultilevelSettings") -> np.ndarray:
    """The coarse points of a two-level solve: Poisson-disk, radius ``settings.radius_factor`` l.

    Parameters
    ----------
    front : FrontEnd
        Its points, mean spacing l and boundary loops (every loop point is kept).
    settings : MultilevelSettings
        ``radius_factor`` and ``seed``.

    Returns
    -------
    (C,) numpy.ndarray of int64
        Indices of the coarse points into ``front.points``.
    """
    from .subsample import poisson_disk_subsample

    return poisson_disk_subsample(front.points, settings.radius_factor * front.mean_spacing,
                                  np.concatenate(front.boundary_loops), seed=settings.seed)


def two_level_sdp_pair(front: "FrontEnd", lap, fine_solver: str, timer: StageTimer) -> tuple[np.ndarray, dict]:
    """SDP's pair ``L f = lambda B f`` on two levels (stages ``subsample``, ``coarse``, ``solve``).

    Parameters
    ----------
    front : FrontEnd
    lap : (N, N) scipy.sparse matrix of float64
        The Laplacian (e.g. ``I - W^tan``).
    fine_solver : {"twogrid", "direct"}
        See :class:`~parambench.methods.spectral.multilevel.MultilevelSettings`.
    timer : StageTimer

    Returns
    -------
    pair : (N, 2) numpy.ndarray of float64
        Not B-orthonormalised.
    info : dict
        The two-level diagnostics of :func:`~parambench.methods.spectral.multilevel_dirichlet.multilevel_sdp`.

    Raises
    ------
    ConvergenceError, SolverError
        The two-level refinement did not converge.
    """
    from ..spectral.multilevel import MultilevelSettings
    from ..spectral.multilevel_dirichlet import multilevel_sdp

    settings = MultilevelSettings(fine_solver=fine_solver)
    with timer("subsample"):
        coarse = coarse_subsample(front, settings)
    return multilevel_sdp(lap, front.boundary_loops, front.points, coarse, normals=front.normals, settings=settings,
                          stage=lambda name: timer("solve" if name == "fine" else name))
