"""``isomap-sklearn``: scikit-learn's Isomap (a peer row, paper Fig. 1)."""

from __future__ import annotations

from parambench.datasets_gen.errors import ResourceLimitError
from parambench.datasets_gen.surface import MethodInput

from ..base import Method, MethodOutput, StageTimer
from ..registry import register
from ._sklearn import embed


@register
class IsomapPeer(Method):
    """Isomap: geodesic distances on the kNN graph, then classical MDS (dense: O(N^2) memory)."""

    name = "isomap-sklearn"
    description = "scikit-learn Isomap (peer, Fig. 1; O(N^2) memory, limited to 20k points)"
    defaults = {"n_neighbors": 10}
    max_points = 20_000

    def solve(self, surface: MethodInput, params: dict, timer: StageTimer) -> MethodOutput:
        from sklearn.manifold import Isomap

        n_neighbors = params["n_neighbors"]
        if surface.n_points > self.max_points:
            need_gb = 8 * 3 * surface.n_points**2 / 2**30
            raise ResourceLimitError(f"isomap-sklearn needs about {need_gb:.0f} GB for {surface.n_points} points "
                                     f"(dense geodesic distances); subsample to at most {self.max_points} points.")
        with timer("solve"):
            uv = embed(Isomap(n_neighbors=n_neighbors, n_components=2), surface.points, self.name)
        return MethodOutput(uv)
