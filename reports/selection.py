"""Which cells the pictures show.

Sweeps repeat each surface over sizes and seeds; pictures of every repeat would bury the
reader. Per surface family (dataset, sampling, noise) the pictures show one size and one
seed: the size at which most method variants stored arrays (ties: the larger size, whose
pictures are the more telling), and at it the seed with most arrays (ties: the smallest).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from parambench.bench.schema import dataset_key

from .labels import config_label

__all__ = ["PictureView", "picture_views", "dataset_npz_candidates"]


@dataclass
class PictureView:
    """One surface (configuration and seed) chosen for pictures.

    Attributes
    ----------
    dataset, sampling : str
    size, noise, seed : float
    config : str
        The configuration's label (as in the summary tables).
    rows : pandas.DataFrame
        All rows of this configuration and seed, one per variant, sorted by variant.
    family_rows : pandas.DataFrame
        All rows of the family (every size and seed), to find the surface's dataset npz.
    """

    dataset: str
    size: float
    sampling: str
    noise: float
    seed: float
    config: str
    rows: pd.DataFrame
    family_rows: pd.DataFrame

    @property
    def title(self) -> str:
        return f"{self.config} (seed {int(self.seed)})"


def _has_arrays(root: Path, artifact: str) -> bool:
    return bool(artifact) and (root / artifact).is_file()


def picture_views(rows: pd.DataFrame, root: Path) -> list[PictureView]:
    """Pick one configuration and seed per surface family.

    Parameters
    ----------
    rows : pandas.DataFrame
        Labelled rows (see :func:`parambench.reports.labels.add_labels`).
    root : pathlib.Path
        The results directory (to see which npz files exist).

    Returns
    -------
    list of PictureView
        Sorted by dataset, sampling, noise.
    """
    views = []
    measured = ("ok", "suspect")  # suspect maps are drawn: the picture shows what the self-check found
    rows = rows.assign(_arrays=[r.status in measured and _has_arrays(root, r.artifact) for r in rows.itertuples()])
    for (dataset, sampling, noise), family in rows.groupby(["dataset", "sampling", "noise"], sort=True):
        with_arrays = family[family["_arrays"]]
        if len(with_arrays):
            per_size = with_arrays.groupby("size")["variant"].nunique()
            size = max(per_size.index, key=lambda s: (per_size[s], s))
            at_size = with_arrays[with_arrays["size"] == size]
            per_seed = at_size.groupby("seed")["variant"].nunique()
            seed = min(per_seed.index, key=lambda s: (-per_seed[s], s))
        else:
            size = family["size"].max()
            seed = family.loc[family["size"] == size, "seed"].min()
        chosen = family[(family["size"] == size) & (family["seed"] == seed)].sort_values("variant", kind="stable")
        views.append(PictureView(dataset, size, sampling, noise, seed, config_label(dataset, size, sampling, noise),
                                 chosen.drop(columns="_arrays"), family.drop(columns="_arrays")))
    return views


def dataset_npz_candidates(view: PictureView) -> list[str]:
    """File stems under ``datasets/`` to try for a view's surface diagnostics, best first.

    The view's own size and seed first, then the same size with other seeds, then other
    sizes (largest first), each keyed by :func:`parambench.bench.schema.dataset_key`.
    """
    pairs = [(view.size, view.seed)]
    family = view.family_rows
    same_size = sorted(set(family.loc[family["size"] == view.size, "seed"]) - {view.seed})
    pairs += [(view.size, s) for s in same_size]
    others = family[family["size"] != view.size][["size", "seed"]].drop_duplicates()
    pairs += sorted(map(tuple, others.to_numpy()), key=lambda p: (-p[0], p[1]))
    out: list[str] = []
    for size, seed in pairs:
        key = dataset_key(view.dataset, size, view.sampling, view.noise, seed)
        if key not in out:
            out.append(key)
    return out
