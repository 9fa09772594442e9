"""Writing a flattening to disk: OBJ (v, vt, f) or CSV (u,v), one row per input point."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from datasets_gen.errors import InputFileError

__all__ = ["write_uv", "UV_FORMATS"]

UV_FORMATS = (".obj", ".csv")


def _write_obj(path: Path, points: np.ndarray, uv: np.ndarray, faces: np.ndarray | None) -> None:
    with open(path, "w") as fh:
        fh.write("# parambench flattening: one vt per v, in input order\n")
        np.savetxt(fh, points, fmt="v %.17g %.17g %.17g")
        np.savetxt(fh, uv, fmt="vt %.17g %.17g")
        if faces is not None:
            one = faces + 1
            np.savetxt(fh, np.repeat(one, 2, axis=1), fmt="f %d/%d %d/%d %d/%d")


def _write_csv(path: Path, uv: np.ndarray) -> None:
    np.savetxt(path, uv, fmt="%.17g", delimiter=",", header="u,v", comments="")


def write_uv(path: str | Path, points: np.ndarray, uv: np.ndarray, faces: np.ndarray | None = None) -> Path:
    """Write uv coordinates.

    Parameters
    ----------
    path : str or Path
        ``.obj``: ``v`` and ``vt`` lines (one per input point, input order) and ``f v/vt``
        lines when ``faces`` is given. ``.csv``: header ``u,v`` and one row per point.
    points : (N, 3) numpy.ndarray of float64
    uv : (N, 2) numpy.ndarray of float64
    faces : (M, 3) numpy.ndarray of int64, optional

    Raises
    ------
    InputFileError
        Unsupported extension, or the directory does not exist / is not writable.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in UV_FORMATS:
        raise InputFileError(f"cannot write {path.name!r}: output must end in {' or '.join(UV_FORMATS)}.")
    if not path.parent.exists():
        raise InputFileError(f"output directory {str(path.parent)!r} does not exist; create it first.")
    try:
        if suffix == ".obj":
            _write_obj(path, points, uv, faces)
        else:
            _write_csv(path, uv)
    except OSError as exc:
        raise InputFileError(f"cannot write {str(path)!r}: {exc.strerror}.") from None
    return path
