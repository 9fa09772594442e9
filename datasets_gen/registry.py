"""The dataset registry: every named surface the suite can generate or load.

>>> from parambench.datasets_gen.registry import make_surface
>>> s = make_surface("cap", 2000, sampling="blue-noise", seed=3)
>>> s.exact_map_kind
'conformal'
"""

from __future__ import annotations

from dataclasses import replace

from .build import build_surface, check_noise
from .errors import UnknownNameError
from .real import REAL_DATASETS, load_real
from .sampling import SAMPLINGS
from .shapes import SHAPES
from .surface import Surface

__all__ = ["make_surface", "dataset_names", "dataset_info", "SAMPLINGS", "REAL_SAMPLINGS"]

#: Samplings of a real mesh's own triangles (the real datasets are otherwise loaded as they are).
REAL_SAMPLINGS = ("scattered",)


def dataset_names() -> list[str]:
    """All dataset names: the procedural ones, then ``real/...``."""
    return list(SHAPES) + list(REAL_DATASETS)


def dataset_info() -> dict[str, str]:
    """Dataset name -> one-line description."""
    info = {name: cls.description for name, cls in SHAPES.items()}
    info.update({name: spec.description for name, spec in REAL_DATASETS.items()})
    return info


def make_surface(name: str, n_points: int = 5000, *, sampling: str = "jittered", seed: int | None = 0,
                 noise: float = 0.0, **options) -> Surface:
    """Generate (or load) a named surface.

    Parameters
    ----------
    name : str
        One of :func:`dataset_names`.
    n_points : int
        Requested number of points, at least 100 (the result is within a few percent;
        ``params["n_actual"]`` records it). Ignored by real datasets unless ``sampling="scattered"``.
    sampling : {"grid", "jittered", "random", "blue-noise", "graded"}
        How the parameter domain is sampled (see :mod:`parambench.datasets_gen.build`). Real
        datasets are loaded as they are, except with ``"scattered"`` (:data:`REAL_SAMPLINGS`):
        ``n_points`` area-uniform random points on a real mesh's triangles, none on its rim,
        as a scan leaves them, with a reference triangulation as ``faces``
        (:func:`parambench.datasets_gen.scattered.scatter_on_mesh`).
    seed : int or None
        Seeds every random choice; the same seed gives identical arrays.
    noise : float
        Standard deviation of a displacement along the exact normal, as a fraction of the
        mean spacing (mean edge length of the ground-truth mesh). Normals, faces and
        ``exact_uv`` stay those of the clean surface.
    **options
        Shape options (e.g. ``h`` and ``s`` of "bump"); unknown ones are refused.

    Returns
    -------
    Surface
        Points, ground-truth faces (counter-clockwise seen from the normals' side), exact
        normals, boundary mask and loops (outer first and counter-clockwise seen from the
        normals' side, holes clockwise), ``exact_uv`` and ``exact_map_kind`` where known.
        ``params`` = ``{"n_points", "sampling", "noise", **options, "n_actual", "spacing"}``.

    Raises
    ------
    UnknownNameError
        Unknown dataset, sampling or option (the message lists the valid ones).
    TooFewPointsError
        ``n_points`` < 100.
    InvalidInputError
        Bad noise or option values.
    InputFileError
        A real dataset's file is missing.
    """
    if name in REAL_DATASETS:
        if options:
            raise UnknownNameError(f"{name} takes no options (got {', '.join(sorted(options))}).")
        if sampling in REAL_SAMPLINGS:
            return _scattered_real(name, n_points, seed, check_noise(noise))
        return load_real(name, seed=seed, noise=check_noise(noise),
                         requested={"n_points": n_points, "sampling": sampling})
    if name not in SHAPES:
        raise UnknownNameError(f"unknown dataset {name!r}; valid datasets: {', '.join(dataset_names())}.")
    if sampling in REAL_SAMPLINGS:
        raise UnknownNameError(f"sampling {sampling!r} scatters points over a real mesh's triangles; {name} is "
                               f"generated: use 'random' (area-uniform) or one of {', '.join(SAMPLINGS)}.")
    shape = SHAPES[name](**options)
    return build_surface(shape, n_points, sampling, seed, noise)


def _scattered_real(name: str, n_points: int, seed: int | None, noise: float) -> Surface:
    """A real mesh's surface scattered with ``n_points`` random points (:func:`scatter_on_mesh`)."""
    import numpy as np

    from .build import add_normal_noise
    from .scattered import scatter_on_mesh

    surface = scatter_on_mesh(load_real(name, seed=seed), n_points, seed)
    if noise > 0:  # along the interpolated normals, in units of the points' mean spacing
        rng = np.random.default_rng(None if seed is None else [seed, 1])
        points = add_normal_noise(surface.points, surface.normals, noise * surface.params["spacing"], rng)
        surface = replace(surface, points=points, params={**surface.params, "noise": noise})
    return surface
