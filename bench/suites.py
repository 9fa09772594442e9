"""Named suites: which datasets, sizes, samplings, seeds and methods a sweep covers."""

from __future__ import annotations

import itertools
from dataclasses import dataclass, replace

from datasets_gen.errors import UnknownNameError
from methods.registry import all_methods

from .cells import REAL_PREFIX, Cell

__all__ = ["Suite", "SUITES", "get_suite", "expand_cells"]


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
        datasets=("saddle", "bump", "holes", "cap", "cylinder", "real/lilium"),
        sizes=(2000,),
        samplings=("jittered",),
        seeds=(0,),
        # The paper's literal OCP and SDP beside the improved defaults.
        variants=(("ocp", (("energy", "paper"),)), ("sdp", (("b_orthonormal", False),))),
    ),
    "full": Suite(
        name="full",
        datasets=("plane", "saddle", "bump", "holes", "holes-bumped", "cap", "cylinder", "protrusions",
                  "gnome-strip", "real/camelhead", "real/lilium", "real/bump-domain", "real/bunny10k",
                  "real/chameleon"),
        sizes=(2000, 10000, 50000),
        samplings=("grid", "jittered", "random"),
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
        methods=("scp-igl", "scp", "sdp", "ocp"),
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
        raise UnknownNameError(f"unknown suite {name!r}; available: {', '.join(SUITES)}.") from None


def _param_combinations(method_cls, use_grid: bool) -> list[tuple]:
    if not use_grid or not method_cls.param_grid:
        return [()]
    keys = sorted(method_cls.param_grid)
    return [tuple(zip(keys, values)) for values in itertools.product(*(method_cls.param_grid[k] for k in keys))]


def expand_cells(suite: Suite) -> list[Cell]:
    """Every cell of a suite, in a deterministic order (dataset, size, sampling, seed, method).

    Raises
    ------
    UnknownNameError
        Unknown method or dataset names, listing the available ones.
    """
    from datasets_gen.registry import dataset_names

    registered = all_methods()
    unknown = [m for m in suite.methods if m not in registered]
    if unknown:
        raise UnknownNameError(f"unknown method(s) {', '.join(unknown)}; available: {', '.join(registered)}.")
    known_datasets = set(dataset_names())
    bad = [d for d in suite.datasets if d not in known_datasets]
    if bad:
        raise UnknownNameError(f"unknown dataset(s) {', '.join(bad)}; available: {', '.join(sorted(known_datasets))}.")
    methods = suite.methods or tuple(registered)
    cells = []
    for dataset in suite.datasets:
        real = dataset.startswith(REAL_PREFIX)
        sizes = (0,) if real else suite.sizes
        samplings = ("",) if real else suite.samplings
        noises = (0.0,) if real else suite.noise
        for size, sampling, noise, seed in itertools.product(sizes, samplings, noises, suite.seeds):
            for method in methods:
                combos = _param_combinations(registered[method], suite.param_grids)
                combos += [tuple(sorted(p)) for m, p in suite.variants if m == method and tuple(sorted(p)) not in combos]
                for params in combos:
                    cells.append(Cell(dataset, int(size), sampling, float(noise), int(seed), method, params))
    return cells
