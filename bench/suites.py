"""Named suites: which datasets, sizes, samplings, seeds and methods a sweep covers."""

from __future__ import annotations

import itertools
import math
import numbers
from dataclasses import dataclass, replace

from parambench.datasets_gen.build import MIN_GENERATED_POINTS, check_noise
from parambench.datasets_gen.errors import InvalidInputError, TooFewPointsError, UnknownNameError
from parambench.datasets_gen.registry import REAL_SAMPLINGS
from parambench.datasets_gen.sampling import SAMPLINGS
from parambench.methods.registry import all_methods

from .cells import REAL_PREFIX, Cell

__all__ = ["Suite", "SUITES", "get_suite", "expand_cells", "validate_suite", "check_workers", "real_dataset_note"]


@dataclass(frozen=True)
class Suite:
    """A sweep specification.

    Attributes
    ----------
    name : str
    datasets, samplings, methods : tuple of str
        ``methods=()`` means every registered method.
    sizes : tuple of int
        Requested point counts for procedural datasets (real datasets run once at their own size).
    seeds : tuple of int
    noise : tuple of float
    param_grids : bool
        False: each method once with its defaults. True: the product of each method's
        ``param_grid``.
    variants : tuple of (method, params) pairs
        Extra non-default runs added to every surface (``params`` a tuple of (key, value)),
        e.g. the paper-literal variant of a method whose default improves on the paper.
    """

    name: str
    datasets: tuple
    sizes: tuple
    samplings: tuple
    seeds: tuple
    methods: tuple = ()
    noise: tuple = (0.0,)
    param_grids: bool = False
    variants: tuple = ()

    def with_overrides(self, **overrides) -> "Suite":
        """A copy with the given non-empty fields replaced (command-line options)."""
        given = {k: tuple(v) for k, v in overrides.items() if v}
        return replace(self, **given)


SUITES = {
    "quick": Suite(
        name="quick",
        # real/spot-top: a real mesh with protrusions (ears, horns) on which the methods disagree;
        # about 9 s of compute for all its cells (2089 vertices).
        datasets=("saddle", "bump", "holes", "cap", "cylinder", "real/lilium", "real/spot-top"),
        sizes=(2000,),
        samplings=("jittered",),
        seeds=(0,),
        # The paper's literal OCP and SDP beside the improved defaults; ocp refined by
        # cotangent SCP on its own uv mesh (what ``refine="auto"`` does only where the
        # point-set energies fail); fbcp-pc also on the true boundary, to separate the cost
        # of boundary detection from that of the map.
        variants=(("ocp", (("energy", "paper"),)), ("ocp", (("refine", "mesh"),)), ("sdp", (("b_orthonormal", False),)),
                  ("fbcp-pc", (("boundary", "given"),))),
    ),
    "full": Suite(
        name="full",
        datasets=("plane", "saddle", "bump", "holes", "holes-bumped", "cap", "cylinder", "protrusions",
                  "gnome-strip", "slit", "fold", "real/camelhead", "real/lilium", "real/bump-domain", "real/meg-helmet",
                  "real/spot-top", "real/cortex-lh", "real/bunny10k", "real/chameleon", "real/lidar-ground"),
        sizes=(2000, 10000, 50000),
        samplings=("grid", "jittered", "random", "graded"),
        seeds=(0, 1, 2),
        param_grids=True,
    ),
    # Issue "scale": time and peak memory against size, fitted exponents in the report.
    "scale": Suite(
        name="scale",
        datasets=("bump", "holes"),
        sizes=(10_000, 100_000, 1_000_000),
        samplings=("jittered",),
        seeds=(0,),
        # bff-mouette is left out: mouette assembles in Python (73 s at 100k points, measured).
        methods=("scp-igl", "scp", "sdp", "ocp", "fbcp-pc"),
    ),
}


def get_suite(name: str) -> Suite:
    """The named suite.

    Raises
    ------
    UnknownNameError
        With the list of suite names.
    """
    try:
        return SUITES[name]
    except KeyError:
        raise UnknownNameError(f"--suite: unknown suite {name!r}; available: {', '.join(SUITES)}.") from None


#: Largest requested size: the scale suite's largest is a million points, which takes about
#: 3 GB in ``ocp``; far larger sizes ran out of memory while the surface was generated.
MAX_SIZE = 20_000_000
#: Largest seed: the results table stores seeds as 64-bit integers (a 20-digit seed ran
#: every cell, then failed to write results.parquet).
MAX_SEED = 2**63 - 1
#: Largest normal noise, in mean spacings: past a few spacings no surface is left to flatten.
MAX_NOISE = 10.0


def _is_whole(value) -> bool:
    return (isinstance(value, numbers.Real) and not isinstance(value, bool) and math.isfinite(float(value))
            and float(value).is_integer())


def _require(option: str, values: tuple) -> None:
    if not values:
        raise InvalidInputError(f"--{option}: no values given; give at least one.")


def _check_names(option: str, given: tuple, available, what: str) -> None:
    unknown = [str(v) for v in given if v not in available]
    if unknown:
        raise UnknownNameError(f"--{option}: unknown {what}(s) {', '.join(unknown)}; "
                               f"available: {', '.join(available)}.")


def validate_suite(suite: Suite) -> Suite:
    """Check every field of a suite before any work, naming the option and the allowed values.

    Parameters
    ----------
    suite : Suite

    Returns
    -------
    Suite
        ``suite`` unchanged (for chaining).

    Raises
    ------
    UnknownNameError
        Unknown method, dataset or sampling names (the message lists the available ones).
    TooFewPointsError
        A size below the generators' minimum (:data:`parambench.datasets_gen.build.MIN_GENERATED_POINTS`).
    InvalidInputError
        An empty list, a size or seed that is not a whole number, a size above
        ``MAX_SIZE``, a seed outside 0 to ``MAX_SEED``, or noise outside 0 to ``MAX_NOISE``
        (or NaN).
    """
    from parambench.datasets_gen.registry import dataset_names

    registered = all_methods()
    _check_names("methods", suite.methods, list(registered), "method")
    _require("datasets", suite.datasets)
    _check_names("datasets", suite.datasets, dataset_names(), "dataset")
    for option, values in (("sizes", suite.sizes), ("samplings", suite.samplings), ("seeds", suite.seeds),
                           ("noise", suite.noise)):
        _require(option, values)
    for size in suite.sizes:
        if _is_whole(size) and size > MAX_SIZE:
            raise InvalidInputError(f"--sizes: {size!r} is too large; at most {MAX_SIZE:,} points (a million-point "
                                    "surface takes about 3 GB in ocp).")
        if not _is_whole(size):
            raise InvalidInputError(f"--sizes: {size!r} is not a whole number; sizes are point counts, "
                                    f"at least {MIN_GENERATED_POINTS}.")
        if size < MIN_GENERATED_POINTS:
            raise TooFewPointsError(f"--sizes: {size!r} is too small; sizes are point counts, "
                                    f"at least {MIN_GENERATED_POINTS}.")
    _check_names("samplings", suite.samplings, SAMPLINGS + REAL_SAMPLINGS, "sampling")
    for seed in suite.seeds:
        if not _is_whole(seed) or seed < 0 or seed > MAX_SEED:
            raise InvalidInputError(f"--seeds: {seed!r} is not allowed; seeds are whole numbers >= 0 and at most "
                                    f"{MAX_SEED} (the results table stores them as 64-bit integers).")
    for noise in suite.noise:
        try:
            check_noise(noise)
            if noise > MAX_NOISE:
                raise InvalidInputError("too noisy")
        except InvalidInputError:
            raise InvalidInputError(f"--noise: {noise!r} is not allowed; noise is a finite fraction of the mean "
                                    f"spacing, >= 0 and at most {MAX_NOISE:g} (e.g. 0 or 0.05).") from None
    return suite


def check_workers(workers) -> None:
    """Refuse a local cluster size that is not a whole number >= 1 (None means in-process).

    Raises
    ------
    InvalidInputError
    """
    if workers is not None and (not _is_whole(workers) or workers < 1):
        raise InvalidInputError(f"--workers: {workers!r} is not allowed; give a whole number of worker "
                                f"processes >= 1 (or leave it out to run in-process).")


def _param_combinations(method_cls, use_grid: bool) -> list[tuple]:
    if not use_grid or not method_cls.param_grid:
        return [()]
    keys = sorted(method_cls.param_grid)
    return [tuple(zip(keys, values)) for values in itertools.product(*(method_cls.param_grid[k] for k in keys))]


def _surfaces_of(dataset: str, suite: Suite) -> list[tuple]:
    """(size, sampling, noise, seed) of every surface of ``dataset`` in the suite.

    Real datasets are loaded as they are (size 0, no sampling, no noise) unless the suite
    names a sampling of real meshes ("scattered"): then they are sampled at every size and
    noise. Generated ones take every other sampling.
    """
    if dataset.startswith(REAL_PREFIX):
        real = tuple(s for s in suite.samplings if s in REAL_SAMPLINGS)
        if not real:
            return [(0, "", 0.0, seed) for seed in suite.seeds]
        return list(itertools.product(suite.sizes, real, suite.noise, suite.seeds))
    generated = tuple(s for s in suite.samplings if s not in REAL_SAMPLINGS)
    return list(itertools.product(suite.sizes, generated, suite.noise, suite.seeds))


def real_dataset_note(suite: Suite) -> str | None:
    """A line saying that real datasets ignore the suite's noise and samplings, when they do; else None.

    Without a sampling of real meshes ("scattered") a real dataset is its file's own points:
    ``--datasets real/lilium --noise 0.5 --samplings random`` ran the clean file, stored with
    noise 0, and said nothing.
    """
    real = [d for d in suite.datasets if d.startswith(REAL_PREFIX)]
    if not real or any(s in REAL_SAMPLINGS for s in suite.samplings):
        return None
    noisy = sorted({float(n) for n in suite.noise if n})
    if not noisy:
        return None
    shown = ", ".join(real[:3]) + (f" and {len(real) - 3} more" if len(real) > 3 else "")
    return (f"note: {shown} run on the file's own points, without noise ({', '.join(f'{n:g}' for n in noisy)}) "
            "or resampling: those apply to generated surfaces; add --samplings scattered to sample the real "
            "meshes at the given sizes and noise.")


def _points_only(dataset: str) -> bool:
    """A real dataset of points with no faces at all (``real/chameleon``; not one given a reference mesh)."""
    from parambench.datasets_gen.real import REAL_DATASETS

    entry = REAL_DATASETS.get(dataset)
    return entry is not None and entry.points_only and entry.reference is None


def expand_cells(suite: Suite) -> list[Cell]:
    """Every cell of a suite, in a deterministic order (dataset, size, sampling, seed, method).

    Mesh methods get no cell on a real dataset stored as points without faces.

    Raises
    ------
    UnknownNameError, TooFewPointsError, InvalidInputError
        From :func:`validate_suite`; InvalidInputError also when no cell is left (only
        samplings of real meshes, and no real mesh).
    """
    validate_suite(suite)
    registered = all_methods()
    methods = suite.methods or tuple(registered)
    cells = []
    for dataset in suite.datasets:
        for size, sampling, noise, seed in _surfaces_of(dataset, suite):
            for method in methods:
                if registered[method].needs_faces and _points_only(dataset):
                    continue  # a mesh method on a point set: no cell (5 "MissingFacesError" rows per seed before)
                combos = _param_combinations(registered[method], suite.param_grids)
                combos += [tuple(sorted(p)) for m, p in suite.variants if m == method and tuple(sorted(p)) not in combos]
                for params in combos:
                    # + 0.0: "--noise -0" is the noise-free surface, not a cell of its own (n-0)
                    cells.append(Cell(dataset, int(size), sampling, float(noise) + 0.0, int(seed), method, params))
    # A value given twice ("--seeds 0 0", "--methods ocp ocp") names the same cell twice: run it once.
    cells = list(dict.fromkeys(cells))
    if not cells and all(_points_only(d) for d in suite.datasets):
        raise InvalidInputError(f"the suite has no cell: {', '.join(suite.datasets)} hold(s) points without faces, "
                                "and mesh methods need faces; add a point-set method (e.g. --methods ocp).")
    if not cells:  # only samplings of real meshes, and no real mesh to sample
        raise InvalidInputError(f"the suite has no cell: sampling {', '.join(suite.samplings)} applies to real "
                                f"meshes only (e.g. --datasets real/lilium); generated surfaces take "
                                f"{', '.join(SAMPLINGS)}.")
    return cells
