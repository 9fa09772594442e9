"""Wavefront OBJ: ``v``, ``vn`` and ``f`` records; everything else is skipped.

``v x y z [w | r g b]``: the first three values are the position, the rest are parsed and
ignored. ``f`` takes ``v``, ``v/vt``, ``v//vn`` or ``v/vt/vn`` corners with 1-based or
negative (relative: -1 is the latest ``v``) vertex indices; polygons are split into
triangles (a fan when convex, else ear clipping: :func:`._common.polygons_to_triangles`).
Index 0, an index past the vertex list, a non-numeric value or a repeated corner is an
error with its line number. ``vn`` rows count as per-vertex normals only when there is
exactly one per ``v`` (they are then taken in order). A backslash at the end of a line
of a data statement (``v``, ``f``, ...) joins the next line to it (the OBJ specification
allows it; ``#`` comments end at their line, backslash included; names such as ``g C:\\temp\\``
are never continued); a leading UTF-8 byte-order mark and classic Mac OS (CR only)
line breaks are accepted.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ._common import RawMesh, Tokens, file_error, polygons_to_triangles, strip_comments, text_of

__all__ = ["read_obj"]

#: A data statement (``v``, ``vt``, ``vn``, ``vp``, ``f``, ``l``, ``p``) continued over several
#: lines: lines ending in a backslash, and the line after them. Names are never continued: a
#: group named after a Windows folder (``g C:\\temp\\``) swallowed the next line's vertex.
_CONTINUED = re.compile(rb"(?m)^[ \t]*(?:vt|vn|vp|v|f|l|p)[ \t](?:[^\n]*\\[ \t\r]*\n)+[^\n]*")
_BREAK = re.compile(rb"\\[ \t\r]*\n")


def read_obj(path: Path, data: bytes) -> RawMesh:
    """Parse an OBJ file.

    Parameters
    ----------
    path : pathlib.Path
        For messages.
    data : bytes
        The file's contents.

    Returns
    -------
    RawMesh
        Points in ``v`` order, triangulated faces (None without ``f`` records),
        normals when there is one ``vn`` per ``v``.

    Raises
    ------
    InputFileError
        No vertices, short records, non-numeric or non-finite coordinates, index 0,
        out-of-range or non-integer face indices, a corner repeated in a face, a polygon
        without area or that crosses itself.
    """
    data = strip_comments(text_of(data))
    if b"\\" in data and _BREAK.search(data):  # only files that continue lines pay for the rewrite
        data = _CONTINUED.sub(_join, data)
    t = Tokens(path, data)
    kind = t.keywords()
    v_lines = np.flatnonzero(kind == b"v")
    if v_lines.size == 0:
        raise file_error(path, None, "no vertices ('v x y z' lines)", "pass an OBJ file with vertices")
    points = _rows(t, v_lines, "vertex coordinate", finite=True)
    vn_lines = np.flatnonzero(kind == b"vn")
    normals = _rows(t, vn_lines, "normal value", finite=False) if vn_lines.size else None
    if normals is not None and len(normals) != len(points):
        normals = None
    f_lines = np.flatnonzero(kind == b"f")
    faces = _faces(t, f_lines, v_lines, points) if f_lines.size else None
    return RawMesh(points=points, faces=faces, normals=normals)


def _join(match: re.Match) -> bytes:
    """One continued statement on one line, then as many empty lines as it lost (line numbers stay right)."""
    text, breaks = _BREAK.subn(b" ", match.group())
    return text + b"\n" * breaks


def _rows(t: Tokens, lines: np.ndarray, what: str, finite: bool) -> np.ndarray:
    """The first three values of each record (all values of the record must be numbers)."""
    short = np.flatnonzero(t.count[lines] < 4)
    if short.size:
        i = int(lines[short[0]])
        raise t.line_error(i, f"{t.tok[t.first[i]].decode()} record with {int(t.count[i]) - 1} value(s)",
                           "it needs three: x y z")
    everything = t.spans(lines, 1, t.count[lines] - 1)
    t.numbers(everything, what, finite=False)  # extra values (w, colour) must still be numbers
    first3 = t.spans(lines, 1, 3)
    values = t.numbers(first3, what, finite=False)
    if finite:
        t.check_finite(values, first3, what)
    return values.reshape(-1, 3)


def _faces(t: Tokens, lines: np.ndarray, v_lines: np.ndarray, points: np.ndarray) -> np.ndarray:
    sizes = t.count[lines] - 1
    corners = t.spans(lines, 1, sizes)
    # only the vertex part of "v/vt/vn" matters; texture and normal references are ignored
    heads = [tok.split(b"/", 1)[0] for tok in (t.tok[i] for i in corners.tolist())]
    raw = Tokens.of(t.path, heads, t.line[corners]).numbers(np.arange(len(heads)), "face vertex index", integer=True)
    zero = np.flatnonzero(raw == 0)
    if zero.size:
        raise t.error(int(corners[zero[0]]), "face vertex index 0 (OBJ indices start at 1)",
                      "renumber the face from 1, or use negative indices relative to the last vertex")
    # a negative index counts back from the vertices defined before its face line
    defined = np.repeat(np.searchsorted(v_lines, lines), sizes)
    indices = np.where(raw > 0, raw - 1, defined + raw)
    return polygons_to_triangles(indices, sizes, points, lambda f: f"line {int(t.line_no[lines[f]])}", t.path,
                                 written=raw)
