"""Peer rows from scikit-learn's manifold module: LTSA, Hessian LLE and Isomap (paper Fig. 1).

They run on the same points as the paper's methods so the comparison is like for like.
They know no boundary and no conformal energy; they are here to show how dimensionality
reduction methods that assume isometry or local linearity fare on curved patches.
"""

from __future__ import annotations

import warnings

import numpy as np

from parambench.datasets_gen.errors import ConvergenceError, ResourceLimitError, SolverError
from parambench.datasets_gen.surface import Surface

from ..base import Method, Parameterization, StageTimer
from ..hints import Hint, hinted
from ..pointset.plugin_support import require_neighbours
from ..registry import register


def _embed(estimator, points: np.ndarray, name: str) -> np.ndarray:
    require_neighbours(points.shape[0], estimator.n_neighbors, "n_neighbors")
    more = Hint("try a larger n_neighbors", "n_neighbors")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            uv = estimator.fit_transform(points)
    except (ValueError, np.linalg.LinAlgError, RuntimeError) as exc:
        message = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        if "converge" in message.lower() or "arpack" in message.lower():
            raise hinted(ConvergenceError, f"{name}: the eigen-solver did not converge ({message})", more,
                         Hint("use eigen_solver='dense' on small inputs", "eigen_solver", "dense")) from None
        raise hinted(SolverError, f"{name} failed: {message}", more) from None
    if not np.all(np.isfinite(uv)):
        raise hinted(SolverError, f"{name} returned non-finite coordinates", more)
    return np.ascontiguousarray(uv, dtype=np.float64)


class _SklearnLLE(Method):
    lle_method = ""
    defaults = {"n_neighbors": 12, "eigen_solver": "auto", "seed": 0}
    max_points = 200_000

    def run(self, surface: Surface, n_neighbors: int, eigen_solver: str, seed: int) -> Parameterization:
        from sklearn.manifold import LocallyLinearEmbedding

        if surface.n_points > self.max_points:
            raise ResourceLimitError(f"{self.name} is limited to {self.max_points} points here "
                                     f"(got {surface.n_points}); subsample the point set.")
        solver = eigen_solver
        if solver == "auto":
            solver = "dense" if surface.n_points <= 1500 else "arpack"
        timer = StageTimer()
        est = LocallyLinearEmbedding(n_neighbors=n_neighbors, n_components=2, method=self.lle_method,
                                     eigen_solver=solver, random_state=seed)
        with timer("solve"):
            uv = _embed(est, surface.points, self.name)
        return Parameterization(uv=uv, method=self.name, timings=timer.timings,
                                diagnostics={"reconstruction_error": float(est.reconstruction_error_),
                                             "eigen_solver": solver})


@register
class Ltsa(_SklearnLLE):
    name = "ltsa-sklearn"
    description = "scikit-learn local tangent space alignment (peer, Fig. 1)"
    lle_method = "ltsa"


@register
class HessianLle(_SklearnLLE):
    name = "hlle-sklearn"
    description = "scikit-learn Hessian LLE (peer, Fig. 1)"
    lle_method = "hessian"


@register
class IsomapPeer(Method):
    """Isomap: geodesic distances on the kNN graph, then classical MDS (dense: O(N^2) memory)."""

    name = "isomap-sklearn"
    description = "scikit-learn Isomap (peer, Fig. 1; O(N^2) memory, limited to 20k points)"
    defaults = {"n_neighbors": 10}
    max_points = 20_000

    def run(self, surface: Surface, n_neighbors: int) -> Parameterization:
        from sklearn.manifold import Isomap

        if surface.n_points > self.max_points:
            need_gb = 8 * 3 * surface.n_points**2 / 2**30
            raise ResourceLimitError(f"isomap-sklearn needs about {need_gb:.0f} GB for {surface.n_points} points "
                                     f"(dense geodesic distances); subsample to at most {self.max_points} points.")
        timer = StageTimer()
        with timer("solve"):
            uv = _embed(Isomap(n_neighbors=n_neighbors, n_components=2), surface.points, self.name)
        return Parameterization(uv=uv, method=self.name, timings=timer.timings)
