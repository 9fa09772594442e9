"""The dataset registry: every named surface the suite can generate or load.

>>> from parambench.datasets_gen.registry import make_surface
>>> s = make_surface("cap", 2000, sampling="blue-noise", seed=3)
>>> s.exact_map_kind
'conformal'
"""

from __future__ import annotations

from .build import build_surface, check_noise
from .errors import UnknownNameError
from .real import REAL_DATASETS, load_real
from .sampling import SAMPLINGS
from .shapes import SHAPES
from .surface import Surface

__all__ = ["make_surface", "dataset_names", "dataset_info", "SAMPLINGS"]


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
        ``params["n_actual"]`` records it). Ignored by real datasets.
    sampling : {"grid", "jittered", "random", "blue-noise", "graded"}
        How the parameter domain is sampled (see :mod:`parambench.datasets_gen.build`). Ignored by
        real datasets.
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
        return load_real(name, seed=seed, noise=check_noise(noise),
                         requested={"n_points": n_points, "sampling": sampling})
    if name not in SHAPES:
        raise UnknownNameError(f"unknown dataset {name!r}; valid datasets: {', '.join(dataset_names())}.")
    shape = SHAPES[name](**options)
    return build_surface(shape, n_points, sampling, seed, noise)
