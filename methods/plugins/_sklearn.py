"""What the scikit-learn peer plugins share (``ltsa-sklearn``, ``hlle-sklearn``, ``isomap-sklearn``).

The peers come from scikit-learn's manifold module (paper Fig. 1). They run on the same
points as the paper's methods so the comparison is like for like. They know no boundary
and no conformal energy; they are here to show how dimensionality reduction methods that
assume isometry or local linearity fare on curved patches.

Not a plugin module (the leading underscore): it registers nothing.
"""

from __future__ import annotations

import warnings

import numpy as np

from parambench.datasets_gen.errors import ConvergenceError, ResourceLimitError, SolverError
from parambench.datasets_gen.surface import MethodInput

from ..base import Method, MethodOutput, StageTimer
from ..hints import Hint, hinted
from ..pointset.plugin_support import require_neighbours

__all__ = ["embed", "SklearnLLE"]


def embed(estimator, points: np.ndarray, name: str) -> np.ndarray:
    """``estimator.fit_transform(points)`` with scikit-learn's failures turned into parambench errors.

    Parameters
    ----------
    estimator : sklearn.manifold estimator
        With ``n_neighbors`` and ``n_components=2``.
    points : (N, 3) numpy.ndarray of float64
    name : str
        The method's name, for the messages.

    Returns
    -------
    (N, 2) numpy.ndarray of float64

    Raises
    ------
    TooFewPointsError
        ``n_neighbors`` is not below the number of points.
    ConvergenceError
        The eigen-solver did not converge.
    SolverError
        Any other failure, or non-finite coordinates.
    """
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


class SklearnLLE(Method):
    """Base of the peers on ``sklearn.manifold.LocallyLinearEmbedding``; subclasses set ``lle_method``."""

    lle_method = ""
    defaults = {"n_neighbors": 12, "eigen_solver": "auto", "seed": 0}
    max_points = 200_000

    def solve(self, surface: MethodInput, params: dict, timer: StageTimer) -> MethodOutput:
        from sklearn.manifold import LocallyLinearEmbedding

        n_neighbors, eigen_solver, seed = params["n_neighbors"], params["eigen_solver"], params["seed"]
        if surface.n_points > self.max_points:
            raise ResourceLimitError(f"{self.name} is limited to {self.max_points} points here "
                                     f"(got {surface.n_points}); subsample the point set.")
        solver = eigen_solver
        if solver == "auto":
            solver = "dense" if surface.n_points <= 1500 else "arpack"
        est = LocallyLinearEmbedding(n_neighbors=n_neighbors, n_components=2, method=self.lle_method,
                                     eigen_solver=solver, random_state=seed)
        with timer("solve"):
            uv = embed(est, surface.points, self.name)
        return MethodOutput(uv, {"reconstruction_error": float(est.reconstruction_error_), "eigen_solver": solver})
