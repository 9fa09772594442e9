"""``hlle-sklearn``: scikit-learn's Hessian LLE (a peer row, paper Fig. 1)."""

from __future__ import annotations

from ..registry import register
from ._sklearn import SklearnLLE


@register
class HessianLle(SklearnLLE):
    """Hessian eigenmaps (Donoho & Grimes 2003) through ``LocallyLinearEmbedding(method="hessian")``."""

    name = "hlle-sklearn"
    description = "scikit-learn Hessian LLE (peer, Fig. 1)"
    lle_method = "hessian"
