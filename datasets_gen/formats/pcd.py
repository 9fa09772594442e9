"""PCD point clouds (the Point Cloud Library's format, v0.7; v0.5 / v0.6 headers too).

A text header of ``KEYWORD values`` lines (``#`` comments allowed): ``VERSION``,
``FIELDS`` (``COLUMNS`` in v0.5), ``SIZE``, ``TYPE``, ``COUNT`` (default 1 each),
``WIDTH``, ``HEIGHT``, ``VIEWPOINT``, ``POINTS`` (default ``WIDTH * HEIGHT``) and, last,
``DATA ascii | binary | binary_compressed``; the points follow the DATA line's line break:

- ``ascii``: one row of whitespace-separated values per point, fields in header order;
- ``binary``: little-endian records of ``sum(SIZE * COUNT)`` bytes, point after point;
- ``binary_compressed``: two little-endian uint32 (compressed and decompressed sizes), then
  an LZF stream (:mod:`._lzf`) decoding to the fields one after the other, each holding
  all points' values of that field.

``x y z`` are the points (any numeric TYPE), ``normal_x normal_y normal_z`` the normals when
all three are present; other fields (colour, intensity, curvature, labels, ``_`` padding,
fields of COUNT > 1) are skipped. VIEWPOINT (the sensor's pose) is not applied: PCL leaves
points in the frame they are stored in too.

Organized clouds of depth cameras mark pixels without a return with x, y, z all NaN: such
points are dropped, with a warning that counts them; a point with some but not all of its
coordinates NaN, or an infinite one, is an error. Every disagreement between header and
payload is an error, including bytes after the last point (or after the compressed
stream) other than zeros (PCL's files may end in zero padding): a file whose header is
wrong is never read shifted or cut. A compressed header whose decompressed
size is more than :data:`MAX_LZF_RATIO` times the compressed one is refused before any
memory is allocated for it.
"""

from __future__ import annotations

import struct
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ._common import UTF8_BOM, RawMesh, Tokens, file_error, show, text_of

__all__ = ["read_pcd", "MAX_LZF_RATIO", "HEADER_LIMIT"]

#: LZF codes at best 264 bytes in 2 (a ratio of about 100): a header announcing more than
#: this times its compressed size (plus 1 KiB) is damaged, and is refused unallocated.
MAX_LZF_RATIO = 150

#: The DATA line must come within this many bytes of the start (PCL headers are a few hundred).
HEADER_LIMIT = 1 << 20

#: numpy dtype of each (TYPE, SIZE) pair the format allows.
_DTYPES = {(b"F", 4): "<f4", (b"F", 8): "<f8", **{(b"I", s): f"<i{s}" for s in (1, 2, 4, 8)},
           **{(b"U", s): f"<u{s}" for s in (1, 2, 4, 8)}}

_KINDS = (b"ascii", b"binary", b"binary_compressed")
_KEYWORDS = (b"VERSION", b"FIELDS", b"COLUMNS", b"SIZE", b"TYPE", b"COUNT", b"WIDTH", b"HEIGHT",
             b"VIEWPOINT", b"POINTS", b"DATA")
_NORMALS = ("normal_x", "normal_y", "normal_z")
_REEXPORT = "the file is truncated or corrupt: export it again"


@dataclass(frozen=True)
class _Header:
    """A checked header: per-field name, numpy dtype and count; the point count; where the data starts."""

    names: list
    dtypes: list
    counts: list
    n_points: int
    width: int
    height: int
    kind: bytes
    start: int  # byte offset of the payload
    lines: int  # lines of the header (an ascii payload's first row is line ``lines + 1``)

    @property
    def record(self) -> int:
        """Bytes per point in the binary layouts."""
        return sum(np.dtype(d).itemsize * c for d, c in zip(self.dtypes, self.counts))

    def offset(self, k: int) -> int:
        """Byte offset of field ``k`` within a record (times the point count: in the compressed layout)."""
        return sum(np.dtype(d).itemsize * c for d, c in zip(self.dtypes[:k], self.counts[:k]))


def read_pcd(path: Path, data: bytes) -> RawMesh:
    """Parse a PCD file (ascii, binary or binary_compressed).

    Parameters
    ----------
    path : pathlib.Path
        For messages.
    data : bytes
        The file's contents.

    Returns
    -------
    RawMesh
        ``points`` (N, 3) float64: the x y z of every point that is not all NaN, in file
        order (row-major for an organized cloud); ``normals`` (N, 3) float64 as stored, when
        the file has ``normal_x normal_y normal_z``; where points were dropped, ``rows``
        (their file rows) and ``n_rows``.

    Raises
    ------
    InputFileError
        A header without a DATA line or with an unknown line, DATA kind, TYPE / SIZE pair
        or count; FIELDS, SIZE, TYPE, COUNT of different lengths; no x, y or z field (or one
        of COUNT > 1); POINTS that disagrees with WIDTH * HEIGHT; a payload of a different
        size than the header announces; a compressed block with inconsistent sizes or a
        malformed LZF stream; an ascii row with the wrong number of values or a value that
        is not a number; a point with some but not all coordinates NaN, or an infinite
        one; no point with coordinates.

    Warns
    -----
    UserWarning
        When points with x, y, z all NaN (no return) are dropped: how many of how many.
    """
    head = _header(path, data)
    wanted = _wanted(path, head)
    if head.kind == b"ascii":
        columns, where = _ascii(path, data, head, wanted)
    elif head.kind == b"binary":
        columns, where = _binary(path, data, head, wanted)
    else:
        columns, where = _compressed(path, data, head, wanted)
    points = np.column_stack([columns["x"], columns["y"], columns["z"]])
    normals = np.column_stack([columns[k] for k in _NORMALS]) if _NORMALS[0] in columns else None
    keep = _returns(path, points, where)
    if keep.all():
        return RawMesh(points=np.ascontiguousarray(points), normals=normals)
    # The file rows of the points kept, so that output per row (a .csv) lines up with the
    # file's points (an organized cloud's pixels) instead of shifting past each dropped one.
    return RawMesh(points=np.ascontiguousarray(points[keep]), normals=None if normals is None else normals[keep],
                   rows=np.flatnonzero(keep), n_rows=int(keep.size))


def _header(path: Path, data: bytes) -> _Header:
    """Parse and check the header lines up to DATA."""
    values: dict = {}
    pos = len(UTF8_BOM) if data.startswith(UTF8_BOM) else 0
    line_no = 0
    while True:
        line_no += 1
        end = data.find(b"\n", pos, HEADER_LIMIT)
        if end < 0 and pos < len(data) and len(data) <= HEADER_LIMIT:
            end = len(data)  # a last line without a line break (an ascii file of no points)
        if end < 0 or pos >= len(data):
            raise file_error(path, None, "no DATA line ends the header (not a PCD file, or its header is cut short)",
                             "pass a PCD file whose header ends with 'DATA ascii', 'DATA binary' or "
                             "'DATA binary_compressed'")
        raw = data[pos:end].split(b"#", 1)[0]
        pos = end + 1
        words = raw.split()
        if not words:
            continue
        key = words[0].upper()
        if key not in _KEYWORDS:
            raise file_error(path, f"line {line_no}", f"unexpected header line {show(raw.strip())} (not a PCD file?)",
                             "a PCD header holds VERSION, FIELDS, SIZE, TYPE, COUNT, WIDTH, HEIGHT, VIEWPOINT, "
                             "POINTS and DATA lines")
        key = b"FIELDS" if key == b"COLUMNS" else key
        if key in values:
            raise file_error(path, f"line {line_no}", f"a second {key.decode()} line", "keep one, and repair the file")
        values[key] = (words[1:], line_no)
        if key == b"DATA":
            return _checked(path, values, min(pos, len(data)), line_no)


def _checked(path: Path, values: dict, start: int, lines: int) -> _Header:
    """The header's values checked against each other."""
    kind = b" ".join(values[b"DATA"][0])
    if kind.lower() not in _KINDS:
        raise file_error(path, f"line {lines}", f"unknown DATA kind {show(kind)}",
                         "PCD data is 'ascii', 'binary' or 'binary_compressed'; export the file again")
    if b"FIELDS" not in values:
        raise file_error(path, None, "the header has no FIELDS line", "add 'FIELDS x y z ...' naming the columns")
    names = [w.decode("utf-8", "replace") for w in values[b"FIELDS"][0]]
    old = _version(values) < 0.7  # v0.5 / v0.6 files may leave out SIZE and TYPE: 4-byte floats
    sizes = _list(path, values, b"SIZE", len(names), [b"4"] * len(names) if old else None)
    types = _list(path, values, b"TYPE", len(names), [b"F"] * len(names) if old else None)
    counts = _list(path, values, b"COUNT", len(names), [b"1"] * len(names))
    dtypes = []
    for k, (name, size, kind_of, count) in enumerate(zip(names, sizes, types, counts)):
        dtype = _DTYPES.get((kind_of.upper(), int(size) if _is_whole(size) else -1))
        if dtype is None:
            raise file_error(path, f"line {values[b'TYPE'][1] if b'TYPE' in values else lines}",
                             f"field {show(name.encode())} has TYPE {show(kind_of)} with SIZE {show(size)}",
                             "TYPE F takes SIZE 4 or 8, TYPE I and U take 1, 2, 4 or 8")
        if not (_is_whole(count) and int(count) > 0):
            raise file_error(path, f"line {values[b'COUNT'][1]}",
                             f"field {show(name.encode())} has COUNT {show(count)}",
                             "a COUNT is a whole number of at least 1")
        dtypes.append(dtype)
    width = _whole(path, values, b"WIDTH")
    height = _whole(path, values, b"HEIGHT")
    n_points = _whole(path, values, b"POINTS")
    if n_points is None and width is None:
        raise file_error(path, None, "the header has neither POINTS nor WIDTH", "add 'POINTS n' (the number of points)")
    height = 1 if height is None else height
    width = n_points if width is None else width
    n_points = width * height if n_points is None else n_points
    if n_points != width * height:
        raise file_error(path, f"line {values[b'POINTS'][1]}", f"POINTS {n_points} is not WIDTH * HEIGHT "
                         f"({width} * {height} = {width * height})", _REEXPORT)
    if n_points == 0:
        raise file_error(path, None, "the file holds no points (POINTS 0)", "pass a file with points")
    return _Header(names=names, dtypes=dtypes, counts=[int(c) for c in counts], n_points=n_points, width=width,
                   height=height, kind=kind.lower(), start=start, lines=lines)


def _version(values: dict) -> float:
    """The header's VERSION as a number (``.7``, ``0.7``, ``0.6``), 0.7 when absent or unreadable."""
    words = values.get(b"VERSION", ([b".7"], 0))[0]
    try:
        return float(words[0]) if words else 0.7
    except ValueError:
        return 0.7


def _list(path: Path, values: dict, key: bytes, n: int, default) -> list:
    """The ``n`` words of header line ``key`` (``default`` when absent), one per field."""
    if key not in values:
        if default is None:
            raise file_error(path, None, f"the header has no {key.decode()} line",
                             f"add one giving each of the {n} fields its {key.decode().lower()}")
        return default
    words, line_no = values[key]
    if len(words) != n:
        raise file_error(path, f"line {line_no}", f"{key.decode()} gives {len(words)} value(s) for {n} field(s) "
                         "of FIELDS", "give every field one value on each of FIELDS, SIZE, TYPE and COUNT")
    return words


def _whole(path: Path, values: dict, key: bytes) -> int | None:
    """Header line ``key``'s one whole number, None when absent."""
    if key not in values:
        return None
    words, line_no = values[key]
    if len(words) != 1 or not _is_whole(words[0]):
        raise file_error(path, f"line {line_no}", f"{key.decode()} {show(b' '.join(words))} is not a whole number "
                         "of 0 or more", _REEXPORT)
    return int(words[0])


def _is_whole(word: bytes) -> bool:
    """A whole number of at most 18 digits (``int()`` refuses more than 4,300, and no count needs 19)."""
    return word.isdigit() and len(word) <= 18


def _wanted(path: Path, head: _Header) -> dict:
    """``{name: field index}`` for x, y, z and (when all three are there) the normals."""
    index: dict = {}
    for k, name in enumerate(head.names):
        if name.lower() in ("x", "y", "z") + _NORMALS and head.counts[k] == 1:
            if name.lower() in index:
                raise file_error(path, None, f"two fields named {name.lower()!r}", "rename or remove one of them")
            index[name.lower()] = k
    for axis in ("x", "y", "z"):
        if axis not in index:
            several = any(name.lower() == axis for name in head.names)
            raise file_error(path, None, f"no field {axis!r} of COUNT 1 (FIELDS: {' '.join(head.names)[:80]})"
                             if several else f"no field {axis!r} (FIELDS: {' '.join(head.names)[:80]})",
                             "the points need fields x, y and z, one value each")
    if not all(k in index for k in _NORMALS):
        for k in _NORMALS:
            index.pop(k, None)
    return index


def _ascii(path: Path, data: bytes, head: _Header, wanted: dict) -> tuple[dict, callable]:
    """The wanted columns (float64) of an ascii payload, and where point i is (its line)."""
    t = Tokens(path, text_of(data[head.start:]), first_line=head.lines + 1)
    cols = sum(head.counts)
    if t.n_lines != head.n_points:
        raise file_error(path, None, f"the header counts {head.n_points} points but {t.n_lines} rows follow",
                         "fix POINTS (and WIDTH, HEIGHT), or export the file again")
    ragged = np.flatnonzero(t.count != cols)
    if ragged.size:
        i = int(ragged[0])
        raise t.line_error(i, f"{int(t.count[i])} value(s) where the header's fields take {cols}", _REEXPORT)
    values = t.numbers(np.arange(head.n_points * cols), "value", finite=False).reshape(head.n_points, cols)
    starts = np.cumsum([0] + head.counts)
    columns = {name: values[:, starts[k]] for name, k in wanted.items()}
    return columns, lambda i: f"line {int(t.line_no[i])}"


def _binary(path: Path, data: bytes, head: _Header, wanted: dict) -> tuple[dict, callable]:
    """The wanted columns (float64) of a binary payload, and where point i is (its byte offset)."""
    record = head.record
    body = len(data) - head.start
    if body != head.n_points * record and not _zero_padding(data, head.start + head.n_points * record):
        more = "more" if body > head.n_points * record else "fewer"
        raise file_error(path, f"byte {head.start}", f"the header announces {head.n_points} points of {record} bytes "
                         f"({head.n_points * record} bytes) but {body} bytes follow ({more})", _REEXPORT)
    dtype = np.dtype({"names": list(wanted), "formats": [head.dtypes[k] for k in wanted.values()],
                      "offsets": [head.offset(k) for k in wanted.values()], "itemsize": record})
    records = np.frombuffer(data, dtype, count=head.n_points, offset=head.start)
    columns = {name: records[name].astype(np.float64) for name in wanted}
    return columns, lambda i: f"byte {head.start + record * i}"


def _compressed(path: Path, data: bytes, head: _Header, wanted: dict) -> tuple[dict, callable]:
    """The wanted columns (float64) of a binary_compressed payload, and where point i is (none: it is compressed)."""
    body = len(data) - head.start
    if body < 8:
        raise file_error(path, f"byte {head.start}", f"{body} bytes follow the header, too few for the compressed "
                         "block's two sizes", _REEXPORT)
    packed, unpacked = struct.unpack_from("<II", data, head.start)
    expected = head.n_points * head.record
    where = f"byte {head.start}"
    if unpacked != expected:
        raise file_error(path, where, f"the compressed block decompresses to {unpacked} bytes, but the header's "
                         f"{head.n_points} points of {head.record} bytes take {expected}", _REEXPORT)
    if packed != body - 8 and not _zero_padding(data, head.start + 8 + packed):
        raise file_error(path, where, f"the compressed block announces {packed} bytes but {body - 8} follow", _REEXPORT)
    if unpacked > MAX_LZF_RATIO * packed + 1024:
        raise file_error(path, where, f"{packed} compressed bytes cannot hold {unpacked} (LZF packs at most about "
                         "100 to 1): the file is damaged", "export it again")
    from ._lzf import LZFError, lzf_decompress  # numba is loaded only for compressed files

    try:
        raw = lzf_decompress(np.frombuffer(data, dtype=np.uint8, count=packed, offset=head.start + 8), unpacked)
    except LZFError as exc:
        raise file_error(path, f"byte {head.start + 8 + exc.position}", f"a malformed compressed stream "
                         f"({exc.problem})", _REEXPORT) from None
    columns = {name: np.frombuffer(raw, head.dtypes[k], count=head.n_points,
                                   offset=head.n_points * head.offset(k)).astype(np.float64)
               for name, k in wanted.items()}
    return columns, lambda i: None


def _zero_padding(data: bytes, end: int) -> bool:
    """Whether the bytes after the data's announced ``end`` are zeros and nothing else.

    Files written by PCL can end in zeros past their data (the test files in pypcd4's
    sources: 3,918 after a binary payload, 2,179 after a compressed one); PCL reads them by
    their header. Any other byte there means the header does not describe the file.
    """
    return end < len(data) and not np.frombuffer(data, dtype=np.uint8, offset=end).any()


def _returns(path: Path, points: np.ndarray, where) -> np.ndarray:
    """(N,) bool: the points with coordinates (not all NaN); warns when some are dropped.

    Raises
    ------
    InputFileError
        A point with an infinite coordinate or some but not all of them NaN; every point NaN.
    """
    nan = np.isnan(points)
    empty = nan.all(axis=1)
    bad = np.flatnonzero((nan.any(axis=1) & ~empty) | np.isinf(points).any(axis=1))
    if bad.size:
        i = int(bad[0])
        x, y, z = points[i]
        raise file_error(path, where(i), f"point {i} has coordinates ({x}, {y}, {z}): NaN or infinite",
                         "repair or remove that point (a point without a return has x, y and z all NaN)")
    n_empty = int(empty.sum())
    if n_empty == len(points):
        raise file_error(path, None, f"all {len(points)} points have x, y, z NaN (no returns)",
                         "pass a cloud with measured points")
    if n_empty:
        warnings.warn(f"{path}: {n_empty} of {len(points)} points have x, y, z all NaN (no return, as depth cameras "
                      f"mark them) and are dropped; the other {len(points) - n_empty} are read, in file order",
                      stacklevel=5)
    return ~empty
