"""PLY, ASCII and binary (little and big endian), any property types.

The header is parsed first and every count is checked against what the body can hold
before anything is allocated. The ``vertex`` element needs ``x y z`` and may carry
``nx ny nz`` and any other properties (parsed, ignored); the ``face`` element needs a list
``vertex_indices`` (or ``vertex_index``) of integers, its polygons split into triangles (a
fan when convex, else ear clipping). Stanford's ``tristrips`` element (a list
``vertex_indices`` of triangle strips, ``-1`` starting a new strip) is read into triangles
too; a file whose only connectivity is another element with such a list is refused rather
than read as a point cloud. Other elements are parsed and skipped. Binary elements are read
with one ``numpy.frombuffer`` call when their lists all have the first record's lengths
(triangle meshes), record by record otherwise. The header (and an ASCII body) may start
with a UTF-8 byte-order mark and use classic Mac OS (CR only) line breaks; byte offsets in
messages are always those of the file as stored.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ._common import UTF8_BOM, RawMesh, Tokens, file_error, polygons_to_triangles, show, text_of

__all__ = ["read_ply"]

_TYPES = {b"char": "i1", b"int8": "i1", b"uchar": "u1", b"uint8": "u1", b"short": "i2", b"int16": "i2",
          b"ushort": "u2", b"uint16": "u2", b"int": "i4", b"int32": "i4", b"uint": "u4", b"uint32": "u4",
          b"float": "f4", b"float32": "f4", b"double": "f8", b"float64": "f8"}
_FORMATS = {b"ascii": None, b"binary_little_endian": "<", b"binary_big_endian": ">"}
_MAGIC = re.compile(rb"ply[ \t]*(?:\r?\n|\r|\Z)")
_END_HEADER = re.compile(rb"(?m)^end_header[ \t\r]*(?:\n|\Z)")
_END_HEADER_CR = re.compile(rb"(?<=\r)end_header[ \t]*(?:\r|\Z)")  # a classic Mac OS header
#: List properties that hold a connectivity (Stanford names; other tools vary the case).
_INDEX_LIST = re.compile(r"(?i)vertex_ind(ices|ex)")


@dataclass
class _Property:
    name: str
    type: str  # numpy type code without byte order
    count_type: str | None = None  # list length type; None for a scalar


@dataclass
class _Element:
    name: str
    count: int
    line: int
    props: list = field(default_factory=list)


def read_ply(path: Path, data: bytes) -> RawMesh:
    """Parse a PLY file.

    Parameters
    ----------
    path : pathlib.Path
        For messages.
    data : bytes
        The file's contents.

    Returns
    -------
    RawMesh
        Points in vertex-element order, triangulated faces and triangle strips (None
        without either, or with 0 of them), normals when ``nx ny nz`` are stored.

    Raises
    ------
    InputFileError
        Missing magic or ``end_header``, malformed header lines (counts that are missing,
        negative or not integers, unknown property types), counts the body cannot hold,
        truncated or extra data, non-numeric or non-finite coordinates, face indices out
        of range or repeated in a face, a polygon without area or that crosses itself,
        connectivity in an element other than ``face`` or ``tristrips``.
    """
    magic = _MAGIC.match(data, len(UTF8_BOM) if data.startswith(UTF8_BOM) else 0)
    if magic is None:
        raise file_error(path, "line 1", "no 'ply' magic line", "this is not a PLY file; check its format")
    mac = magic.group().endswith(b"\r")  # lines end in a lone CR: only the header is converted
    end = (_END_HEADER_CR if mac else _END_HEADER).search(data)
    if end is None:
        raise file_error(path, None, "no 'end_header' line", "the PLY header is truncated or corrupt")
    header = text_of(data[:end.start()]).split(b"\n")
    order, elements = _parse_header(path, header)
    body_line = len(header) + 1
    if order is None:
        values = _ascii_body(path, text_of(data[end.end():]), body_line, elements)
    else:
        values = _binary_body(path, data, end.end(), order, elements)
    return _build(path, elements, values)


def _parse_header(path: Path, lines: list):
    order, elements, seen_format = None, [], False
    for no, raw in enumerate(lines[1:], start=2):
        words = raw.split()
        if not words or words[0] in (b"comment", b"obj_info"):
            continue
        where = f"line {no}"
        if words[0] == b"format":
            if len(words) != 3 or words[1] not in _FORMATS:
                raise file_error(path, where, f"unknown format line {show(raw.strip())}",
                                 "use ascii, binary_little_endian or binary_big_endian")
            order, seen_format = _FORMATS[words[1]], True
        elif words[0] == b"element":
            if len(words) != 3 or not re.fullmatch(rb"\d+", words[2]):
                raise file_error(path, where, f"{show(raw.strip())} needs a name and a non-negative integer count",
                                 "fix the header line, e.g. 'element vertex 100'")
            elements.append(_Element(words[1].decode("ascii", "replace"), int(words[2]), no))
        elif words[0] == b"property":
            if not elements:
                raise file_error(path, where, "a property before any element", "fix the PLY header")
            elements[-1].props.append(_property(path, where, words))
        else:
            raise file_error(path, where, f"unknown header line {show(raw.strip())}", "fix the PLY header")
    if not seen_format:
        raise file_error(path, "line 2", "no 'format' line", "the header needs e.g. 'format ascii 1.0'")
    return order, elements


def _property(path: Path, where: str, words: list) -> _Property:
    if len(words) == 5 and words[1] == b"list":
        count_type, item_type = _TYPES.get(words[2]), _TYPES.get(words[3])
        if count_type is None or item_type is None:
            bad = words[2] if count_type is None else words[3]
            raise file_error(path, where, f"unknown property type {show(bad)}", f"use one of {_type_names()}")
        if count_type[0] == "f":
            raise file_error(path, where, "a list length of floating-point type", "use an integer type, e.g. uchar")
        return _Property(words[4].decode("ascii", "replace"), item_type, count_type)
    if len(words) == 3:
        if words[1] not in _TYPES:
            raise file_error(path, where, f"unknown property type {show(words[1])}", f"use one of {_type_names()}")
        return _Property(words[2].decode("ascii", "replace"), _TYPES[words[1]])
    raise file_error(path, where, f"malformed property line {show(b' '.join(words))}",
                     "use 'property TYPE NAME' or 'property list COUNT_TYPE ITEM_TYPE NAME'")


def _type_names() -> str:
    return ", ".join(sorted({k.decode() for k in _TYPES}))


# -- ASCII body: one record per line ---------------------------------------------------------------

def _ascii_body(path: Path, body: bytes, first_line: int, elements: list) -> list:
    t = Tokens(path, body, first_line=first_line)
    needed = sum(e.count for e in elements)
    if t.n_lines < needed:
        raise file_error(path, None, f"the header declares {needed} records "
                         f"({', '.join(f'{e.count} {e.name}' for e in elements)}) but the body has {t.n_lines} "
                         "line(s)", "fix the counts or restore the missing lines")
    if t.n_lines > needed:
        raise t.line_error(needed, f"more lines than the {needed} records the header declares",
                           "fix the counts or remove the extra lines")
    out, cursor = [], 0
    for e in elements:
        lines = np.arange(cursor, cursor + e.count)
        cursor += e.count
        out.append(_ascii_element(t, e, lines))
    return out


def _ascii_element(t: Tokens, e: _Element, lines: np.ndarray) -> dict:
    where = (lambda i: f"line {int(t.line_no[lines[i]])}") if len(lines) else None
    if all(p.count_type is None for p in e.props):
        wrong = np.flatnonzero(t.count[lines] != len(e.props))
        if wrong.size:
            i = int(lines[wrong[0]])
            raise t.line_error(i, f"{int(t.count[i])} value(s) in a {e.name} record of {len(e.props)} properties",
                               "fix the record or the header")
        values = t.numbers(t.spans(lines, 0, len(e.props)), f"{e.name} value", finite=False)
        values = values.reshape(len(lines), len(e.props))
        return {"where": where, **{p.name: (values[:, k], None) for k, p in enumerate(e.props)}}
    if len(e.props) == 1:  # the usual face element: just the list
        p = e.props[0]
        sizes = t.numbers(t.first[lines], f"{p.name} length", integer=True)
        wrong = np.flatnonzero((sizes < 0) | (t.count[lines] != sizes + 1))
        if wrong.size:
            i = int(lines[wrong[0]])
            raise t.line_error(i, f"a list of length {int(sizes[wrong[0]])} followed by {int(t.count[i]) - 1} "
                               "value(s)", "fix the record")
        items = t.numbers(t.spans(lines, 1, sizes), f"{p.name} value", integer=p.type[0] != "f", finite=False)
        return {"where": where, p.name: (items, sizes)}
    return _ascii_general(t, e, lines, where)


def _ascii_general(t: Tokens, e: _Element, lines: np.ndarray, where) -> dict:
    """Record-by-record parse for elements that mix scalars and lists (rare, so a loop)."""
    cols = {p.name: ([], []) for p in e.props}
    for i in lines.tolist():
        k, stop = int(t.first[i]), int(t.first[i] + t.count[i])
        for p in e.props:
            n = 1
            if p.count_type is not None:
                if k >= stop:
                    raise t.line_error(i, f"the record ends before list {p.name}", "fix the record")
                n = int(t.numbers(np.array([k]), f"{p.name} length", integer=True)[0])
                if n < 0:
                    raise t.line_error(i, f"negative list length {n}", "fix the record")
                k += 1
                cols[p.name][1].append(n)
            if k + n > stop:
                raise t.line_error(i, f"the record ends inside property {p.name}", "fix the record")
            cols[p.name][0].append(t.numbers(np.arange(k, k + n), f"{p.name} value", finite=False))
            k += n
        if k != stop:
            raise t.line_error(i, f"{stop - k} value(s) after the last property", "fix the record or the header")
    out = {"where": where}
    for p in e.props:
        flat = np.concatenate(cols[p.name][0]) if cols[p.name][0] else np.zeros(0)
        if p.type[0] != "f":
            flat = flat.astype(np.int64)
        out[p.name] = (flat, np.array(cols[p.name][1], dtype=np.int64) if p.count_type else None)
    return out


# -- binary body -------------------------------------------------------------------------------------

def _binary_body(path: Path, data: bytes, offset: int, order: str, elements: list) -> list:
    out = []
    for e in elements:
        values, offset = _binary_element(path, data, offset, order, e)
        out.append(values)
    if data[offset:].strip():
        raise file_error(path, f"byte {offset}", f"{len(data) - offset} byte(s) after the last element",
                         "the header's counts or types do not match the data; export the file again")
    return out


def _binary_element(path: Path, data: bytes, offset: int, order: str, e: _Element):
    remaining = len(data) - offset
    lengths = _first_record_lengths(path, data, offset, order, e) if e.count else {}
    record = sum(np.dtype(p.type).itemsize * (lengths.get(p.name, 0) if p.count_type else 1)
                 + (np.dtype(p.count_type).itemsize if p.count_type else 0) for p in e.props)
    smallest = sum(np.dtype(p.count_type or p.type).itemsize for p in e.props)  # every list empty
    if e.count * smallest > remaining:
        raise file_error(path, f"byte {offset}", f"the header declares {e.count} {e.name} records of at least "
                         f"{smallest} bytes ({e.count * smallest} bytes) but only {remaining} remain",
                         "the file is truncated or its counts are wrong: export it again")
    if e.count * record > remaining and any(p.count_type for p in e.props):
        # lists longer than the file (or of varying length): the record-by-record read finds where
        return _binary_general(path, data, offset, order, e)
    fields = []
    for k, p in enumerate(e.props):
        if p.count_type is not None:
            fields.append((f"n{k}", order + p.count_type))
            fields.append((f"p{k}", order + p.type, (lengths.get(p.name, 0),)))
        else:
            fields.append((f"p{k}", order + p.type))
    dtype = np.dtype(fields)
    fixed = e.count * dtype.itemsize <= remaining
    if fixed:
        records = np.frombuffer(data, dtype, count=e.count, offset=offset)
        fixed = all(np.all(records[f"n{k}"] == lengths.get(p.name, 0)) for k, p in enumerate(e.props) if p.count_type)
    if not fixed:
        return _binary_general(path, data, offset, order, e)
    start = offset
    out = {"where": lambda i: f"byte {start + i * dtype.itemsize}"}
    for k, p in enumerate(e.props):
        if p.count_type is None:
            out[p.name] = (records[f"p{k}"], None)
        else:
            n = lengths.get(p.name, 0)
            out[p.name] = (records[f"p{k}"].reshape(-1), np.full(e.count, n, dtype=np.int64))
    return out, offset + e.count * dtype.itemsize


def _first_record_lengths(path: Path, data: bytes, offset: int, order: str, e: _Element) -> dict:
    lengths = {}
    for p in e.props:
        if p.count_type is not None:
            n = _unpack(path, data, offset, order + p.count_type, e)
            lengths[p.name] = max(int(n), 0)
            offset += np.dtype(p.count_type).itemsize + lengths[p.name] * np.dtype(p.type).itemsize
        else:
            offset += np.dtype(p.type).itemsize
    return lengths


def _unpack(path: Path, data: bytes, offset: int, code: str, e: _Element):
    size = np.dtype(code).itemsize
    if offset + size > len(data):
        raise file_error(path, f"byte {offset}", f"the file ends inside a {e.name} record",
                         "the file is truncated or its counts are wrong: export it again")
    return np.frombuffer(data, code, count=1, offset=offset)[0]


def _binary_general(path: Path, data: bytes, offset: int, order: str, e: _Element):
    """Record-by-record read for lists of varying length (polygon meshes)."""
    cols = {p.name: ([], []) for p in e.props}
    starts = []
    for _ in range(e.count):
        starts.append(offset)
        for p in e.props:
            n = 1
            if p.count_type is not None:
                n = int(_unpack(path, data, offset, order + p.count_type, e))
                if n < 0:
                    raise file_error(path, f"byte {offset}", f"negative list length {n} in {e.name}.{p.name}",
                                     "the file is corrupt: export it again")
                offset += np.dtype(p.count_type).itemsize
                cols[p.name][1].append(n)
            size = n * np.dtype(p.type).itemsize
            if offset + size > len(data):
                raise file_error(path, f"byte {offset}", f"the file ends inside a {e.name} record",
                                 "the file is truncated or its counts are wrong: export it again")
            cols[p.name][0].append(np.frombuffer(data, order + p.type, count=n, offset=offset))
            offset += size
    out = {"where": lambda i: f"byte {starts[i]}"}
    for p in e.props:
        flat = np.concatenate(cols[p.name][0]) if cols[p.name][0] else np.zeros(0, dtype=p.type)
        out[p.name] = (flat, np.array(cols[p.name][1], dtype=np.int64) if p.count_type else None)
    return out, offset


# -- from elements to the mesh ----------------------------------------------------------------------

def _build(path: Path, elements: list, values: list) -> RawMesh:
    by_name = {e.name: (e, v) for e, v in zip(elements, values)}
    if "vertex" not in by_name:
        raise file_error(path, None, "no 'element vertex' in the header", "pass a PLY file with vertices")
    e, v = by_name["vertex"]
    missing = [c for c in ("x", "y", "z") if c not in v or v[c][1] is not None]
    if missing:
        raise file_error(path, f"line {e.line}", f"the vertex element has no scalar {', '.join(missing)} property",
                         "vertices need properties x, y and z")
    points = np.stack([np.asarray(v[c][0], dtype=np.float64) for c in "xyz"], axis=1)
    bad = np.flatnonzero(~np.isfinite(points).all(axis=1))
    if bad.size:
        raise file_error(path, v["where"](int(bad[0])), f"vertex {int(bad[0])} has a NaN or infinite coordinate",
                         "remove or repair that vertex (rows are matched to the output by position)")
    normals = None
    if all(c in v and v[c][1] is None for c in ("nx", "ny", "nz")):
        normals = np.stack([np.asarray(v[c][0], dtype=np.float64) for c in ("nx", "ny", "nz")], axis=1)
    return RawMesh(points=points, faces=_connectivity(path, elements, by_name, points), normals=normals)


def _connectivity(path: Path, elements: list, by_name: dict, points: np.ndarray) -> np.ndarray | None:
    """Triangles of the ``face`` and ``tristrips`` elements, or None when there are none."""
    parts = []
    if "face" in by_name and by_name["face"][0].count:
        fe, fv = by_name["face"]
        flat, sizes = _index_list(path, fe, fv, "face", "uchar int")
        parts.append(polygons_to_triangles(flat.astype(np.int64), sizes, points, fv["where"], path))
    if "tristrips" in by_name and by_name["tristrips"][0].count:
        parts.append(_tristrips(path, *by_name["tristrips"], points))
    if "face" not in by_name and "tristrips" not in by_name:
        # e.g. 'element polygon' or 'element triangle': read as a point cloud, the mesh would be lost silently
        for e in elements:
            lists = [p.name for p in e.props if p.count_type is not None and _INDEX_LIST.fullmatch(p.name)]
            if e.name != "vertex" and lists:
                raise file_error(path, f"line {e.line}", f"the mesh's faces are in an element named {e.name!r} "
                                 f"(list {lists[0]!r}), which is not read as faces",
                                 "save the mesh with a 'face' element (e.g. re-export it with MeshLab)")
    return np.concatenate(parts) if parts else None


def _index_list(path: Path, e: _Element, values: dict, what: str, types: str) -> tuple[np.ndarray, np.ndarray]:
    """An element's list of vertex indices (``vertex_indices`` or ``vertex_index``, any case): (flat values, lengths).

    Raises
    ------
    InputFileError
        No such list, or indices of floating-point type.
    """
    key = next((p.name for p in e.props if p.count_type is not None and _INDEX_LIST.fullmatch(p.name)), None)
    if key is None:
        raise file_error(path, f"line {e.line}", f"the {e.name} element has no list 'vertex_indices'",
                         f"declare 'property list {types} vertex_indices'")
    flat, sizes = values[key]
    if flat.dtype.kind == "f":
        raise file_error(path, f"line {e.line}", f"{what} indices of floating-point type",
                         f"declare them as an integer type, e.g. 'property list {types} vertex_indices'")
    return flat, sizes


def _tristrips(path: Path, e: _Element, values: dict, points: np.ndarray) -> np.ndarray:
    """Triangles of Stanford's ``tristrips`` element.

    Each record is a list of vertex indices forming triangle strips; ``-1`` (or, for an
    unsigned type, its largest value) ends a strip, and so does the end of a record.
    Triangle ``k`` of a strip is ``(s_k, s_k+1, s_k+2)`` for even ``k`` and
    ``(s_k+1, s_k, s_k+2)`` for odd ``k``, so that all keep one winding. Triangles with a
    repeated index are the zero-area ones that stitch strips together: they are skipped
    (and still count for the alternation, as in every strip reader).

    Returns
    -------
    (M, 3) numpy.ndarray of int64

    Raises
    ------
    InputFileError
        No list ``vertex_indices``, indices of floating-point type, an index other than
        ``-1`` out of range, no triangle at all.
    """
    flat, sizes = _index_list(path, e, values, "strip", "int int")
    index = flat.astype(np.int64)
    if flat.dtype.kind == "u" and flat.size:
        index[flat == np.iinfo(flat.dtype).max] = -1
    record = np.repeat(np.arange(len(sizes)), sizes)
    stop = index == -1
    out = np.flatnonzero(~stop & ((index < 0) | (index >= len(points))))
    if out.size:
        raise file_error(path, values["where"](int(record[out[0]])), f"strip index {int(index[out[0]])} is out of "
                         f"range (the file has {len(points)} vertices)", "repair or remove that strip")
    new = np.zeros(len(index), dtype=bool)
    new[(np.cumsum(sizes) - sizes)[sizes > 0]] = True  # each record starts a strip
    new[1:] |= stop[:-1]  # and so does the index after a -1
    strip = np.cumsum(new)[~stop]
    index, record = index[~stop], record[~stop]
    pos = np.arange(len(index))
    head = np.ones(len(index), dtype=bool)
    head[1:] = strip[1:] != strip[:-1]
    k = pos - np.maximum.accumulate(np.where(head, pos, 0)) - 2  # triangle number within the strip
    third = np.flatnonzero(k >= 0)
    odd = (k[third] % 2).astype(bool)
    a = np.where(odd, index[third - 1], index[third - 2])
    b = np.where(odd, index[third - 2], index[third - 1])
    c = index[third]
    real = (a != b) & (b != c) & (a != c)
    if not real.any():
        raise file_error(path, f"line {e.line}", "the tristrips element holds no triangle (every strip has fewer "
                         "than 3 distinct corners)", "repair the strips, or save the mesh with a 'face' element")
    return np.stack([a[real], b[real], c[real]], axis=1)
