"""One cell of a sweep: (dataset, size, sampling, noise, seed, method, parameters).

A :class:`Cell` is a small frozen record that pickles cleanly (no arrays, no closures):
workers regenerate the surface from its seed, so a cell can run in another process or on
a Dask worker and give the same row.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from .schema import CELL_KEY_FIELDS, cell_id, dataset_key, encode_json

__all__ = ["Cell", "REAL_PREFIX"]

#: Dataset names starting with this are real files; size and sampling do not apply.
REAL_PREFIX = "real/"


@dataclass(frozen=True)
class Cell:
    """Address of one result row.

    Parameters
    ----------
    dataset : str
        Dataset name from ``parambench.datasets_gen.registry``.
    size : int
        Requested number of points (0 for real datasets: their own size).
    sampling : str
        Sampling name ("" for real datasets).
    noise : float
        Normal noise as a fraction of the mean spacing.
    seed : int
        Seed of the generator and of any random choice in the method.
    method : str
        Registered method name.
    params : tuple of (str, value) pairs
        Method parameters, sorted by name (a tuple so the cell is hashable).
    """

    dataset: str
    size: int
    sampling: str
    noise: float
    seed: int
    method: str
    params: tuple = field(default_factory=tuple)

    @property
    def is_real(self) -> bool:
        return self.dataset.startswith(REAL_PREFIX)

    @property
    def params_dict(self) -> dict:
        return dict(self.params)

    @property
    def params_json(self) -> str:
        return encode_json(self.params_dict)

    @property
    def dataset_key(self) -> str:
        """Identifies the surface (everything but the method): :func:`parambench.bench.schema.dataset_key`."""
        return dataset_key(self.dataset, self.size, self.sampling, self.noise, self.seed)

    @property
    def cell_id(self) -> str:
        """Stable, file-name-safe identifier: :func:`parambench.bench.schema.cell_id`."""
        return cell_id(self.dataset, self.size, self.sampling, self.noise, self.seed, self.method, self.params_dict)

    def address(self) -> dict:
        """The row columns that identify the cell (:data:`parambench.bench.schema.CELL_KEY_FIELDS`)."""
        d = {name: getattr(self, name) for name in CELL_KEY_FIELDS}
        d["params"] = self.params_json
        return d
