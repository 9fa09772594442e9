"""XYZ and text PTS point clouds: one point per line, ``x y z`` then optional columns.

Values are separated by spaces, tabs or commas; ``#`` starts a comment, and so does ``//``
at the start of a line (CloudCompare's ASCII header, ``//X,Y,Z,R,G,B``); blank lines are
skipped. A first line holding one whole number is Leica's PTS point count, checked
against the rows that follow. Every row must have the same number of columns (at least
3). Normals are three columns after x y z that hold unit vectors on most rows, or a group
of three in step with x y z that looks like unnormalised normals (:func:`_normal_columns`:
``x y z nx ny nz``, ``x y z r g b nx ny nz``); other columns (colours, intensities,
scalar fields) are parsed and ignored: an ``x y z r g b`` file once had its colours read
as normals. A text header line is an
error, not a point (it used to become one).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ._common import RawMesh, Tokens, file_error, strip_comments

__all__ = ["read_xyz", "NORMAL_SHARE", "NORMAL_TOLERANCE"]

#: Share of the rows on which three columns must be unit vectors to be read as normals: a
#: file's normals may hold some zero, missing or unnormalised ones (normalised or refused
#: downstream, with a warning, as before), while colours are almost never unit vectors
#: (integers 0-255 only at pure red, green or blue; random floats in [0, 1] on about 6 %
#: of rows).
NORMAL_SHARE = 0.5

#: How far from 1 a unit vector's length may be (normals written with 3 decimals are within 2e-3).
NORMAL_TOLERANCE = 0.02

_SLASH_COMMENT = re.compile(rb"(?m)^[ \t]*//[^\n]*")


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
        Points (row i = i-th non-comment line after a point count), normals when three
        columns after x y z hold unit vectors (see the module's notes).

    Raises
    ------
    InputFileError
        Fewer than 3 columns, rows of different lengths, a token that is not a number, a
        NaN or infinite coordinate, a point count that disagrees with the rows.
    """
    data = strip_comments(data)
    if b"//" in data:
        data = _SLASH_COMMENT.sub(b"", data)
    t = Tokens(path, data, separators=b",")
    if t.n_lines == 0:
        raise file_error(path, None, "no points (only comments or blank lines)", "pass a file with x y z rows")
    skip = _point_count_line(t)
    if skip and t.n_lines == 1:
        raise file_error(path, None, "no points after the point count", "pass a file with x y z rows")
    cols = int(t.count[skip])
    if cols < 3:
        raise t.line_error(skip, f"a row with {cols} value(s)", "every row needs x y z (optionally nx ny nz)")
    ragged = skip + np.flatnonzero(t.count[skip:] != cols)
    if ragged.size:
        i = int(ragged[0])
        raise t.line_error(i, f"{int(t.count[i])} value(s) where line {int(t.line_no[skip])} has {cols}",
                           "give every row the same columns (x y z, or x y z nx ny nz)")
    n = t.n_lines - skip
    if skip and int(t.tok[0]) != n:
        raise t.line_error(0, f"a point count of {int(t.tok[0])} but {n} rows follow",
                           "fix the count, or remove the line")
    values = t.numbers(skip + np.arange(n * cols), "value", finite=False).reshape(n, cols)
    t.check_finite(values[:, :3], t.spans(np.arange(skip, t.n_lines), 0, 3), "coordinate")
    start = _normal_columns(values)
    normals = None if start is None else values[:, start:start + 3].copy()
    return RawMesh(points=np.ascontiguousarray(values[:, :3]), normals=normals)


def _point_count_line(t: Tokens) -> int:
    """1 when the first line is a lone whole number followed by rows of 3 values or more (Leica PTS), else 0."""
    if t.count[0] != 1 or t.n_lines < 2 or t.count[1] < 3 or not t.tok[0].isdigit():
        return 0
    return 1


def _normal_columns(values: np.ndarray) -> int | None:
    """The column after x y z where three columns of normals start, or None.

    First, any three consecutive columns holding unit vectors on ``NORMAL_SHARE`` of the
    rows. Else the first group of three in step with x y z (columns 4-6, 7-9, ...) that
    looks like unnormalised normals (pymeshlab writes area-weighted ones): no column of
    whole numbers (colours 0-255, intensities) and a column taking both signs (colours in
    [0, 1] never do).
    """
    cols = values.shape[1]
    for start in range(3, cols - 2):
        with np.errstate(invalid="ignore"):
            unit = np.abs(np.linalg.norm(values[:, start:start + 3], axis=1) - 1.0) <= NORMAL_TOLERANCE
        if unit.mean() >= NORMAL_SHARE:
            return start
    for start in range(3, cols - 2, 3):
        group = values[:, start:start + 3]
        whole = np.all(group == np.round(group), axis=0)
        both_signs = (np.any(group < 0, axis=0) & np.any(group > 0, axis=0))
        if not whole.any() and both_signs.any():
            return start
    return None
