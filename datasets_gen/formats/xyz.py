"""XYZ and text PTS point clouds: one point per line, ``x y z`` or ``x y z nx ny nz``.

Values are separated by spaces, tabs or commas; ``#`` starts a comment; blank lines are
skipped. Every row must have the same number of columns (at least 3); columns 4-6 are
normals when there are at least 6, further columns are parsed and ignored. A text header
line is an error, not a point (it used to become one).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ._common import RawMesh, Tokens, file_error, strip_comments

__all__ = ["read_xyz"]


def read_xyz(path: Path, data: bytes) -> RawMesh:
    """Parse an XYZ / text PTS file.

    Parameters
    ----------
    path : pathlib.Path
        For messages.
    data : bytes
        The file's contents.

    Returns
    -------
    RawMesh
        Points (row i = i-th non-comment line), normals when there are >= 6 columns.

    Raises
    ------
    InputFileError
        Fewer than 3 columns, rows of different lengths, a token that is not a number, a
        NaN or infinite coordinate.
    """
    t = Tokens(path, strip_comments(data), separators=b",")
    if t.n_lines == 0:
        raise file_error(path, None, "no points (only comments or blank lines)", "pass a file with x y z rows")
    cols = int(t.count[0])
    if cols < 3:
        raise t.line_error(0, f"a row with {cols} value(s)", "every row needs x y z (optionally nx ny nz)")
    ragged = np.flatnonzero(t.count != cols)
    if ragged.size:
        i = int(ragged[0])
        raise t.line_error(i, f"{int(t.count[i])} value(s) where line {int(t.line_no[0])} has {cols}",
                           "give every row the same columns (x y z, or x y z nx ny nz)")
    n = t.n_lines
    values = t.numbers(np.arange(n * cols), "value", finite=False).reshape(n, cols)
    t.check_finite(values[:, :3], t.spans(np.arange(n), 0, 3), "coordinate")
    normals = values[:, 3:6].copy() if cols >= 6 else None
    return RawMesh(points=np.ascontiguousarray(values[:, :3]), normals=normals)
