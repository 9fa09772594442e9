"""XYZ and text PTS point clouds: one point per line, ``x y z`` then optional columns.

Also read for ``.txt``, ``.csv`` and ``.asc`` files. Values are separated by spaces, tabs,
commas or semicolons; in a file separated by semicolons (European CSV), commas are decimal
marks (``1,5;2,25;3`` is ``1.5 2.25 3``), and so they are in a file separated by spaces or
tabs whose numbers hold commas and no point (``1,5 2,25 3``, :func:`_decimal_commas`);
double quotes around fields are dropped. ``#`` starts a comment, and so does ``//`` at the
start of a line (CloudCompare's ASCII header, ``//X,Y,Z,R,G,B``); blank lines are skipped;
a leading UTF-8 byte-order mark and classic Mac OS (CR only) line breaks are accepted. A
first line holding one whole number is Leica's PTS point count, checked against the rows
that follow. A first line of column names (every token a name: a letter, then letters,
digits or underscores, e.g. ``x y z`` or ``X,Y,Z,R,G,B``, units in brackets after them
dropped: ``x [m]``) is a header: it must name as many
columns as the rows hold, and when it names x y z they must be the first three. Every row
must have the same number of columns (at least 3). Normals are the columns a header names
``nx ny nz`` (or ``normal_x`` ...; a header that names none means there are none); without
a header (or with a ``//`` comment that does not name the columns), three columns after
x y z that hold unit vectors on most rows, or a group of three in step with x y z that
looks like unnormalised normals (:func:`_normal_columns`: ``x y z nx ny nz``,
``x y z r g b nx ny nz``); other columns (colours, intensities, scalar fields) are parsed
and ignored: an ``x y z r g b`` file once had its colours read as normals. Any other text
line is an error, not a point (it used to become one).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ._common import RawMesh, Tokens, file_error, show, strip_comments, text_of

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
_NAME = re.compile(rb"[A-Za-z][A-Za-z0-9_]*")
_NOT_NAMES = {b"nan", b"inf", b"infinity"}  # names numpy reads as numbers
_COORDINATE = re.compile(r"(?i)(?:pos(?:ition)?_?)?([xyz])")
_NORMAL = re.compile(r"(?i)(?:n|nrm|normal|normals)_?([xyz])")


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
        Points (row i = i-th non-comment line after a point count or header), normals when
        a header names them or, without one, when three columns after x y z hold unit
        vectors (see the module's notes).

    Raises
    ------
    InputFileError
        Fewer than 3 columns, rows of different lengths, a token that is not a number, a
        NaN or infinite coordinate, a point count that disagrees with the rows, a header
        that names a different number of columns than the rows hold or puts x y z
        elsewhere than first.
    """
    data = strip_comments(text_of(data))
    slash = None
    if b"//" in data:
        first = _SLASH_COMMENT.search(data)
        if first is not None and not data[:first.start()].strip():  # a comment before any row may name the columns
            slash = first.group().strip()[2:]
        data = _SLASH_COMMENT.sub(b"", data)
    if b'"' in data:
        data = data.replace(b'"', b" ")  # quoted fields (R's write.csv quotes its header)
    data = _without_header_units(data)
    separators = b","
    if b";" in data:
        separators = b";"
        if b"," in data:
            data = data.replace(b",", b".")  # semicolons separate, so commas are decimal marks
    elif _decimal_commas(data):
        separators = b""
        data = data.replace(b",", b".")
    t = Tokens(path, data, separators=separators)
    if t.n_lines == 0:
        raise file_error(path, None, "no points (only comments or blank lines)", "pass a file with x y z rows")
    names = _header(t)
    header = names is not None
    skip = 1 if header else _point_count_line(t)
    if skip and t.n_lines == 1:
        what = "the header" if header else "the point count"
        raise file_error(path, None, f"no points after {what}", "pass a file with x y z rows")
    cols = int(t.count[skip])
    if cols < 3:
        raise t.line_error(skip, f"a row with {cols} value(s)", "every row needs x y z (optionally nx ny nz)")
    ragged = skip + np.flatnonzero(t.count[skip:] != cols)
    if ragged.size:
        i = int(ragged[0])
        raise t.line_error(i, f"{int(t.count[i])} value(s) where line {int(t.line_no[skip])} has {cols}",
                           "give every row the same columns (x y z, or x y z nx ny nz)")
    if header:
        _check_header(t, names, cols)
    elif slash is not None:
        names = _slash_names(slash, separators, cols)
    n = t.n_lines - skip
    if skip and not header and int(t.tok[0]) != n:
        raise t.line_error(0, f"a point count of {int(t.tok[0])} but {n} rows follow",
                           "fix the count, or remove the line")
    values = t.numbers(int(t.first[skip]) + np.arange(n * cols), "value", finite=False).reshape(n, cols)
    t.check_finite(values[:, :3], t.spans(np.arange(skip, t.n_lines), 0, 3), "coordinate")
    start = _normal_columns(values) if names is None else _named_normals(names)
    normals = None if start is None else values[:, start:start + 3].copy()
    return RawMesh(points=np.ascontiguousarray(values[:, :3]), normals=normals,
                   normals_guessed=normals is not None and names is None)


#: A number written with a decimal comma: digits on both sides of the comma, no space.
_DECIMAL_COMMA = re.compile(rb"^-?\d+,\d+(?:[eE][-+]?\d+)?$")


def _decimal_commas(data: bytes) -> bool:
    """Whether commas are decimal marks in a file whose values are separated by spaces or tabs.

    ``1,5<TAB>2,25<TAB>3`` (a European export) was split at the commas into six values a
    row, silently. Read so when the file holds no decimal point and the first row with a
    comma splits at its whitespace into three values or more, each a whole number or one
    with a decimal comma; ``1,2,3`` (no whitespace) and ``1, 2, 3`` (commas before spaces)
    keep their commas as separators.
    """
    if b"," not in data or b"." in data:
        return False
    for line in data.splitlines():
        if b"," in line:
            values = line.split()
            return len(values) >= 3 and all(_DECIMAL_COMMA.match(v) or v.lstrip(b"-").isdigit() for v in values)
    return False


#: A unit after a column name in a header: ``x [m]``, ``z (mm)``.
_UNIT = re.compile(rb"[ \t]*[\[(][^\])\n]*[\])]")


def _without_header_units(data: bytes) -> bytes:
    """``data`` with the units dropped from a header row of names (``x [m],y [m],z [m]``).

    A header with units was split into names and units, twice as many values as the rows
    hold, and refused with a confusing count. Only a first line that becomes names alone
    is changed; its line number stays.
    """
    start = len(data) - len(data.lstrip())
    end = data.find(b"\n", start)
    end = len(data) if end < 0 else end
    first = data[start:end]
    if not (b"[" in first or b"(" in first):
        return data
    names = _UNIT.sub(b"", first)
    tokens = names.replace(b",", b" ").replace(b";", b" ").split()
    if not tokens or not all(_is_name(t) for t in tokens):
        return data
    return data[:start] + names + data[end:]


def _is_name(token: bytes) -> bool:
    return _NAME.fullmatch(token) is not None and token.lower() not in _NOT_NAMES


def _header(t: Tokens) -> list | None:
    """The column names when the first line is a header (every token a name), else None."""
    tokens = t.tok[int(t.first[0]):int(t.first[0] + t.count[0])]
    return [x.decode("ascii") for x in tokens] if all(_is_name(x) for x in tokens) else None


def _check_header(t: Tokens, names: list, cols: int) -> None:
    """Refuse a header that does not describe the rows: a wrong count, or x y z not first."""
    if len(names) != cols:
        raise t.line_error(0, f"a header of {len(names)} column name(s) over rows of {cols} value(s)",
                           "give the header one name per column, or remove it")
    axes = [m.group(1).lower() if (m := _COORDINATE.fullmatch(x)) else None for x in names]
    if any(axes) and axes[:3] != ["x", "y", "z"]:
        raise t.line_error(0, f"the header {show(' '.join(names).encode())} does not start with x y z",
                           "put the coordinates first, in the order x y z")


def _slash_names(text: bytes, separators: bytes, cols: int) -> list | None:
    """The column names a leading ``//`` comment gives (CloudCompare), or None if it is just a comment."""
    tokens = text.translate(bytes.maketrans(separators, b" " * len(separators))).replace(b",", b" ").split()
    if len(tokens) != cols or not all(_is_name(x) for x in tokens):
        return None
    names = [x.decode("ascii") for x in tokens]
    axes = [m.group(1).lower() if (m := _COORDINATE.fullmatch(x)) else None for x in names]
    return names if axes[:3] == ["x", "y", "z"] else None


def _named_normals(names: list) -> int | None:
    """The column where the header's ``nx ny nz`` (or ``normal_x`` ...) start, or None."""
    axes = [m.group(1).lower() if (m := _NORMAL.fullmatch(x)) else None for x in names]
    return next((k for k in range(3, len(names) - 2) if axes[k:k + 3] == ["x", "y", "z"]), None)


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
