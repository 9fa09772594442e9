"""``ltsa-sklearn``: scikit-learn's local tangent space alignment (a peer row, paper Fig. 1)."""

from __future__ import annotations

from ..registry import register
from ._sklearn import SklearnLLE


@register
class Ltsa(SklearnLLE):
    """LTSA (Zhang & Zha 2004) through ``sklearn.manifold.LocallyLinearEmbedding(method="ltsa")``."""

    name = "ltsa-sklearn"
    description = "scikit-learn local tangent space alignment (peer, Fig. 1)"
    lle_method = "ltsa"
