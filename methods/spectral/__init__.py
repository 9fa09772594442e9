"""Spectral conformal core shared by mesh and point-set methods.

Works on a V x V Laplacian-like matrix L (any weights, possibly non-symmetric), ordered
oriented boundary loops and a choice of B; it knows nothing of meshes. Coordinates are
complex, z = u + i v, so the 2V x 2V real conformal matrix of Mullen et al. becomes the
V x V operator ``k L / 2 - M`` (Hermitian when L is symmetric) and the rotation by 90
degrees is multiplication by i: eigenvalues no longer come in pairs.

Modules: :mod:`.operators` (area matrix M, B, the conformal operator), :mod:`.turning`
(turning numbers of the boundary image), :mod:`.ordering` (fill-reducing order),
:mod:`.sparse_eigen` (shift-invert eigen-solve), :mod:`.reduction` (exact reduction to
the boundary), :mod:`.ksearch` (the k line search of Eq. 16), :mod:`.problem` (SCP and
DNCP at a given k, the direct k, and the searches).
"""

from .ksearch import KPoint, KSearchResult, line_search
from .operators import area_matrix, boundary_indicator, conformal_operator, is_symmetric
from .problem import ConformalProblem, ConformalSolution
from .turning import is_regular_turning, loop_turning_numbers, turning_penalty

__all__ = [
    "ConformalProblem",
    "ConformalSolution",
    "KPoint",
    "KSearchResult",
    "area_matrix",
    "boundary_indicator",
    "conformal_operator",
    "is_regular_turning",
    "is_symmetric",
    "line_search",
    "loop_turning_numbers",
    "turning_penalty",
]
