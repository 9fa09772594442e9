"""OFF meshes: ``[ST][C][N]OFF``, counts, one vertex per line, one polygon per line.

Vertex lines hold ``x y z`` then, when the keyword says so, ``nx ny nz`` (``N``) and any
colour or texture values (``C``, ``ST``: parsed, ignored); ``NCOFF`` (VCG's writer) puts the
colour before the normal. Face lines hold ``n i_1 .. i_n``
(0-based) optionally followed by a colour; polygons are split into triangles (a fan when
convex, else ear clipping). ``#`` starts a comment. A leading UTF-8 byte-order mark and
classic Mac OS (CR only) line breaks are accepted. The 4-D, n-D and binary variants are
refused with a message.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ._common import RawMesh, Tokens, file_error, polygons_to_triangles, show, strip_comments, text_of

__all__ = ["read_off"]

_KEYWORD = re.compile(rb"(ST)?(C|N|CN|NC)?(4)?(n)?OFF")


def read_off(path: Path, data: bytes) -> RawMesh:
    """Parse an OFF file.

    Parameters
    ----------
    path : pathlib.Path
        For messages.
    data : bytes
        The file's contents.

    Returns
    -------
    RawMesh
        Points in file order, triangulated faces (None when the file declares 0
        faces), normals for ``NOFF``.

    Raises
    ------
    InputFileError
        Missing or unsupported keyword, counts that are missing, negative or disagree with
        the lines that follow, short vertex or face lines, non-numeric or non-finite
        values, face indices out of range or repeated in a face, a polygon without area or
        that crosses itself.
    """
    t = Tokens(path, strip_comments(text_of(data)))
    if t.n_lines == 0:
        raise file_error(path, None, "only comments or blank lines", "pass an OFF file with a mesh")
    keyword = t.tok[0]
    m = _KEYWORD.fullmatch(keyword)
    if m is None:
        raise t.line_error(0, f"the file starts with {show(keyword)}, not an OFF keyword",
                           "the first line must be OFF, COFF, NOFF or CNOFF")
    if m.group(3) or m.group(4):
        raise t.line_error(0, f"{show(keyword)} (4-D or n-D OFF) is not supported", "save the mesh as 3-D OFF")
    letters = m.group(2) or b""
    has_normals = b"N" in letters
    # Geomview's order is x y z [normal] [colour]; VCG (MeshLab, pymeshlab) writes "NCOFF"
    # with the colour first, so for that keyword the normal is the last three values.
    normals_last = letters == b"NC"
    if t.count[0] > 1:  # counts on the keyword's line
        if t.tok[1] == b"BINARY":
            raise t.line_error(0, "binary OFF is not supported", "save the mesh as text OFF, PLY or OBJ")
        count_line, counts_index, body = 0, np.arange(1, int(t.count[0])), 1
    else:
        if t.n_lines < 2:
            raise file_error(path, None, "the vertex and face counts are missing after the keyword",
                             "add a line 'n_vertices n_faces n_edges'")
        count_line, counts_index, body = 1, t.spans(np.array([1]), 0, t.count[1]), 2
    if len(counts_index) not in (2, 3):
        raise t.line_error(count_line, f"{len(counts_index)} count(s) where 'n_vertices n_faces n_edges' is expected",
                           "fix the counts line")
    nv, nf = (int(c) for c in t.numbers(counts_index[:2], "count", integer=True))
    if nv < 0 or nf < 0:
        raise t.line_error(count_line, f"negative count ({nv} vertices, {nf} faces)", "fix the counts line")
    available = t.n_lines - body
    if available < nv + nf:
        raise t.line_error(count_line, f"the file declares {nv} vertices and {nf} faces but only {available} "
                           "data line(s) follow", "fix the counts or restore the missing lines")
    if available > nv + nf:
        raise t.line_error(body + nv + nf, f"more lines than the {nv} vertices and {nf} faces declared",
                           "fix the counts or remove the extra lines")
    points, normals = _vertices(t, np.arange(body, body + nv), has_normals, normals_last)
    faces = _faces(t, np.arange(body + nv, body + nv + nf), points) if nf else None
    return RawMesh(points=points, faces=faces, normals=normals)


def _vertices(t: Tokens, lines: np.ndarray, has_normals: bool, normals_last: bool):
    width = 6 if has_normals else 3
    short = np.flatnonzero(t.count[lines] < width)
    if short.size:
        i = int(lines[short[0]])
        raise t.line_error(i, f"a vertex line with {int(t.count[i])} value(s)",
                           f"each vertex needs x y z{' nx ny nz' if has_normals else ''}")
    if lines.size == 0:
        return np.zeros((0, 3)), None
    lo = int(t.first[lines[0]])
    hi = int(t.first[lines[-1]] + t.count[lines[-1]])
    values = t.numbers(np.arange(lo, hi), "vertex value", finite=False)
    coords = t.spans(lines, 0, 3)
    points = values[coords - lo].reshape(-1, 3)
    t.check_finite(points, coords, "vertex coordinate")
    normals = None
    if has_normals:
        offset = t.count[lines] - 3 if normals_last else 3
        normals = values[t.spans(lines, offset, 3) - lo].reshape(-1, 3)
    return points, normals


def _faces(t: Tokens, lines: np.ndarray, points: np.ndarray) -> np.ndarray:
    sizes = t.numbers(t.first[lines], "face size", integer=True)
    bad = np.flatnonzero((sizes < 3) | (t.count[lines] < sizes + 1))
    if bad.size:
        i = int(lines[bad[0]])
        raise t.line_error(i, f"a face declares {int(sizes[bad[0]])} corner(s) and the line holds "
                           f"{int(t.count[i]) - 1} value(s) after it", "each face line is 'n i_1 .. i_n' with n >= 3")
    indices = t.numbers(t.spans(lines, 1, sizes), "face index", integer=True)
    t.numbers(t.spans(lines, 1 + sizes, t.count[lines] - 1 - sizes), "face colour value", finite=False)
    return polygons_to_triangles(indices, sizes, points, lambda f: f"line {int(t.line_no[lines[f]])}", t.path)
