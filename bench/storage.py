"""Result storage: one JSON row (plus an optional npz of arrays) per finished cell.

Each cell is written the moment it finishes, atomically (temporary file, then rename), so
a run killed half-way loses no finished cell and a second run skips them. The consolidated
``results.parquet`` / ``results.csv`` are rebuilt from the cell files alone.

A cell file that cannot be read back (truncated by a full disk, edited by hand, written by
a tool that did not rename atomically) is never fatal: :meth:`ResultStore.scan` lists it
as unreadable, :meth:`ResultStore.quarantine` moves it aside (kept as evidence) and the
sweep recomputes the cell.
"""

from __future__ import annotations

import json
import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from parambench.datasets_gen.errors import InputFileError

from .schema import NUMERIC_COLUMNS, STATUS_FAILED, STATUS_OK, STATUS_SUSPECT

__all__ = ["ResultStore", "StoredCells", "check_output_dir", "atomic_write_bytes", "FAILED", "UNREADABLE_SUFFIX"]

#: The one status that does not count as finished: a rerun retries such cells by default.
FAILED = STATUS_FAILED
#: Suffix given to a cell file that could not be read back (see ``ResultStore.quarantine``).
UNREADABLE_SUFFIX = ".unreadable"


def _process_umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


#: Mode of the files written here: what ``open`` would give under the process's umask.
#: ``tempfile.mkstemp`` makes its files owner-only (0600), and the rename kept that: reports,
#: ``run.json`` and the cell files came out unreadable to the group where ``results.csv``
#: (written by pandas) did not.
FILE_MODE = 0o666 & ~_process_umask()


def _temporary_beside(path: Path, suffix: str) -> tuple[int, str]:
    """A new, uniquely named file beside ``path`` with :data:`FILE_MODE`: (descriptor, name)."""
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=suffix)
    os.fchmod(fd, FILE_MODE)
    return fd, tmp


def atomic_write_bytes(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` through a uniquely named temporary file beside it and a rename.

    Readers never see a half-written file, and two writers of one path (a report rebuilt by a
    second sweep while the first's is still being written) never share a temporary file. The
    file gets :data:`FILE_MODE`, as a plain ``open`` would give it.
    """
    fd, tmp = _temporary_beside(path, ".tmp")
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


def check_output_dir(path: str | os.PathLike) -> Path:
    """Check, creating nothing, that a results folder can be created or written.

    Parameters
    ----------
    path : str or path-like
        The results folder (``--out``); it may not exist yet.

    Returns
    -------
    pathlib.Path

    Raises
    ------
    InputFileError
        ``path`` (or the nearest existing folder above it) is a file or is not writable.
    """
    root = Path(path)
    existing = root
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if not existing.is_dir():
        what = "" if existing == root else f" ({str(existing)!r} is a file)"
        raise InputFileError(f"--out: cannot use {str(root)!r} as a results folder{what}; give a folder path.")
    # An existing results folder must also let us replace files in its sub-folders.
    probes = [existing]
    if existing == root:
        probes += [root / sub for sub in ("cells", "datasets") if (root / sub).is_dir()]
    for folder in probes:
        if not os.access(folder, os.W_OK | os.X_OK):
            raise InputFileError(f"--out: folder {str(folder)!r} is not writable; fix its permissions or "
                                 f"choose another --out.")
    return root


@dataclass(frozen=True)
class StoredCells:
    """What a results folder holds, read without ever raising.

    Attributes
    ----------
    status : dict of str to str
        ``cell_id`` -> ``status`` of every readable row.
    unreadable : dict of str to str
        ``cell_id`` -> one-line reason, for cell files that are not a valid row
        (undecodable or truncated JSON, not an object, ``cell_id`` not matching the file
        name, no ``status``).
    """

    status: dict = field(default_factory=dict)
    unreadable: dict = field(default_factory=dict)

    def finished(self) -> set[str]:
        """Cells that need no rerun: every readable status but ``failed`` (``ok``, ``suspect``, ...)."""
        return {cid for cid, status in self.status.items() if status != FAILED}

    def failed(self) -> set[str]:
        return {cid for cid, status in self.status.items() if status == FAILED}


def _read_row(path: Path) -> tuple[dict | None, str]:
    """The row stored at ``path``, or None and why it is not usable."""
    try:
        row = json.loads(path.read_bytes())
    except OSError as exc:
        return None, f"cannot be read ({exc.strerror or exc})"
    except (UnicodeDecodeError, ValueError) as exc:  # JSONDecodeError is a ValueError
        return None, f"is not valid JSON, probably truncated ({exc})"
    if not isinstance(row, dict):
        return None, f"holds a JSON {type(row).__name__}, not a row object"
    if row.get("cell_id") != path.stem:
        return None, f"names cell {row.get('cell_id')!r}, not {path.stem!r}"
    if row.get("status") not in (STATUS_OK, STATUS_SUSPECT, STATUS_FAILED):
        # an unknown status counted as finished forever, and the report called it failed
        return None, f"has no known status ({row.get('status')!r})"
    # A value edited by hand ("qc_mean": "abc") made the results table unwritable and the
    # report count it as a failure: such a row is unreadable, and its cell is recomputed.
    bad = [c for c in NUMERIC_COLUMNS if not _is_number_or_null(row.get(c))]
    if bad:
        return None, f"holds a value that is not a number in {', '.join(bad[:3])}"
    return row, ""


def _is_number_or_null(value) -> bool:
    return value is None or (isinstance(value, (int, float)) and not isinstance(value, bool))


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

    def scan(self) -> StoredCells:
        """Status of every readable cell file and the reason for every unreadable one."""
        stored = StoredCells()
        for path in sorted(self.cells_dir.glob("*.json")):
            row, why = _read_row(path)
            if row is None:
                stored.unreadable[path.stem] = why
            else:
                stored.status[path.stem] = row["status"]
        return stored

    def finished_ids(self) -> set[str]:
        """Identifiers of cells with a readable row whose status is not ``failed``."""
        return self.scan().finished()

    def quarantine(self, cell_id: str) -> Path:
        """Move an unreadable cell file aside (``<cell_id>.json.unreadable``, then ``.unreadable.1``, ...)
        so it is recomputed.

        The bytes are kept for inspection; the report and later sweeps no longer see them.
        Returns the new path.
        """
        path = self.cells_dir / f"{cell_id}.json"
        target = path.with_name(path.name + UNREADABLE_SUFFIX)
        copies = 1
        while target.exists():  # an earlier unreadable copy of the same cell stays as evidence too
            target = path.with_name(f"{path.name}{UNREADABLE_SUFFIX}.{copies}")
            copies += 1
        os.replace(path, target)
        return target

    def remove_stale_temporaries(self) -> int:
        """Delete temporary files left by a writer that was killed mid-write; returns how many.

        Call only while holding the folder lock (:func:`parambench.bench.folder_lock.hold_folder`):
        a running writer's temporary file looks the same.
        """
        stale = [p for folder in (self.cells_dir, self.datasets_dir) for p in folder.glob(".*")
                 if p.suffix in (".tmp", ".npz") and p.is_file()]
        for p in stale:
            p.unlink(missing_ok=True)
        return len(stale)

    def write_row(self, row: dict) -> Path:
        """Write one cell's row atomically; returns its path."""
        path = self.cells_dir / f"{row['cell_id']}.json"
        atomic_write_bytes(path, json.dumps(row, default=_json_default, sort_keys=True).encode())
        return path

    def write_arrays(self, name: str, arrays: dict, *, folder: str = "cells") -> str:
        """Write a compressed npz atomically; returns its path relative to the root."""
        target_dir = self.root / folder
        target_dir.mkdir(parents=True, exist_ok=True)
        path = target_dir / f"{name}.npz"
        fd, tmp = _temporary_beside(path, ".npz")
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
        """All readable rows (any status), sorted by cell id; unreadable files are left out."""
        rows = [row for row, _ in map(_read_row, sorted(self.cells_dir.glob("*.json"))) if row is not None]
        return pd.DataFrame(rows)

    def consolidate(self) -> pd.DataFrame:
        """Rebuild ``results.parquet`` and ``results.csv`` from the cell rows."""
        table = self.rows()
        if not table.empty:
            table.to_parquet(self.root / "results.parquet", index=False)
            table.to_csv(self.root / "results.csv", index=False)
        return table

    def write_metadata(self, meta: dict) -> None:
        atomic_write_bytes(self.root / "run.json", json.dumps(meta, indent=2, default=_json_default).encode())
