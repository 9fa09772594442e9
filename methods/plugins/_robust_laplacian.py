"""What the robust-laplacian peer plugins share (``scp-rl``, ``sdp-rl``).

The peers run on robust-laplacian's point-cloud Laplacian (Sharp & Crane 2020) with the
same points and the same detected boundary as ``ocp`` and ``sdp``; only the Laplacian
differs, so their rows isolate what W^tan contributes.

Not a plugin module (the leading underscore): it registers nothing.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..base import StageTimer

__all__ = ["robust_point_cloud_laplacian"]


def robust_point_cloud_laplacian(points: np.ndarray, n_neighbors: int, timer: StageTimer) -> sp.csr_matrix:
    """robust-laplacian's point-cloud Laplacian (its mass matrix dropped), timed as stage ``laplacian``.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    n_neighbors : int
        Neighbours of robust-laplacian's tufted cover.
    timer : StageTimer

    Returns
    -------
    (N, N) scipy.sparse.csr_matrix of float64
    """
    # Imported here: only these two peers need the package.
    import robust_laplacian

    with timer("laplacian"):
        lap, _mass = robust_laplacian.point_cloud_laplacian(points, n_neighbors=n_neighbors)
    return sp.csr_matrix(lap)
