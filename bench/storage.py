"""Result storage: one JSON row (plus an optional npz of arrays) per finished cell.

Each cell is written the moment it finishes, atomically (temporary file, then rename), so
a run killed half-way loses no finished cell and a second run skips them. The consolidated
``results.parquet`` / ``results.csv`` are rebuilt from the cell files alone.
"""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

__all__ = ["ResultStore"]


def _atomic_write_bytes(path: Path, data: bytes) -> None:
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _json_default(value):
    if isinstance(value, (np.integer,)):
        return int(value)
    if isinstance(value, (np.floating,)):
        return float(value)
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"not JSON-serialisable: {type(value).__name__}")


class ResultStore:
    """A results directory.

    Layout::

        RESULTS_DIR/run.json              run metadata
        RESULTS_DIR/cells/<cell_id>.json  one row per finished cell
        RESULTS_DIR/cells/<cell_id>.npz   arrays for pictures (ok cells)
        RESULTS_DIR/datasets/<key>.npz    per-surface diagnostics (weights, boundary)
        RESULTS_DIR/results.parquet|csv   consolidated rows

    Parameters
    ----------
    root : str or Path
        Created if missing.
    """

    def __init__(self, root: str | os.PathLike) -> None:
        self.root = Path(root)
        self.cells_dir = self.root / "cells"
        self.datasets_dir = self.root / "datasets"
        self.cells_dir.mkdir(parents=True, exist_ok=True)
        self.datasets_dir.mkdir(parents=True, exist_ok=True)

    def finished_ids(self) -> set[str]:
        """Identifiers of cells that already have a row."""
        return {p.stem for p in self.cells_dir.glob("*.json")}

    def write_row(self, row: dict) -> Path:
        """Write one cell's row atomically; returns its path."""
        path = self.cells_dir / f"{row['cell_id']}.json"
        _atomic_write_bytes(path, json.dumps(row, default=_json_default, sort_keys=True).encode())
        return path

    def write_arrays(self, name: str, arrays: dict, *, folder: str = "cells") -> str:
        """Write a compressed npz atomically; returns its path relative to the root."""
        target_dir = self.root / folder
        target_dir.mkdir(parents=True, exist_ok=True)
        path = target_dir / f"{name}.npz"
        fd, tmp = tempfile.mkstemp(dir=target_dir, prefix=f".{name}.", suffix=".npz")
        os.close(fd)
        try:
            np.savez_compressed(tmp, **arrays)
            os.replace(tmp, path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
        return str(path.relative_to(self.root))

    def has_arrays(self, name: str, *, folder: str = "datasets") -> bool:
        return (self.root / folder / f"{name}.npz").exists()

    def rows(self) -> pd.DataFrame:
        """All finished rows, sorted by cell id."""
        rows = [json.loads(p.read_text()) for p in sorted(self.cells_dir.glob("*.json"))]
        return pd.DataFrame(rows)

    def consolidate(self) -> pd.DataFrame:
        """Rebuild ``results.parquet`` and ``results.csv`` from the cell rows."""
        table = self.rows()
        if not table.empty:
            table.to_parquet(self.root / "results.parquet", index=False)
            table.to_csv(self.root / "results.csv", index=False)
        return table

    def write_metadata(self, meta: dict) -> None:
        _atomic_write_bytes(self.root / "run.json", json.dumps(meta, indent=2, default=_json_default).encode())
