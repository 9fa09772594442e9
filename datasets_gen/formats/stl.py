"""STL, binary and ASCII: triangles given by their corner coordinates.

STL has no vertex list: the vertices are the distinct corners in order of first
appearance. Equal corners are merged, and so are corners closer than :data:`MERGE_TOL`
times the median length of the file's triangle edges (but never half its shortest
non-zero triangle edge, so no triangle loses a corner): exporters write every triangle's
corners on their own, and a corner computed once per triangle (after a transform, or
printed in ASCII) differs between its triangles by rounding error, which made every
triangle a connected component of its own. The tolerance follows the triangles rather
than the bounding box: one stray triangle far away would make a box-relative tolerance as
large as the real edges. Exact matches are merged first (``numpy.unique``), the near ones
then with a k-d tree (``scipy.spatial.cKDTree``); each merged vertex keeps the coordinates
of its first corner.

A file is binary when its size is 84 + 50 * (the triangle count at byte 80), or up to 49
bytes more (padding some exporters add: less than one more triangle, so nothing is lost; a
warning says how many bytes were ignored); otherwise it must be ASCII (``solid`` ...
``endsolid``, keywords in any case, with or without a UTF-8 byte-order mark and CR line
breaks), and a binary-looking file shorter than its count says, or longer by a triangle or
more, is refused (that file used to keep the native reader busy forever).
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from ._common import RawMesh, Tokens, file_error, show, text_of

__all__ = ["read_stl", "MERGE_TOL"]

#: Corners closer than this times the median triangle edge length are one vertex: far above
#: the rounding of float32 (6e-8) or of a 9-digit ASCII print, far below any real edge.
MERGE_TOL = 1e-6

_BINARY = np.dtype([("normal", "<f4", (3,)), ("corners", "<f4", (3, 3)), ("attribute", "<u2")])
_FACET = [b"facet", b"outer", b"vertex", b"vertex", b"vertex", b"endloop", b"endfacet"]
_FACET_TOKENS = np.array([5, 2, 4, 4, 4, 1, 1])


def read_stl(path: Path, data: bytes) -> RawMesh:
    """Parse a binary or ASCII STL file.

    Parameters
    ----------
    path : pathlib.Path
        For messages.
    data : bytes
        The file's contents.

    Returns
    -------
    RawMesh
        Distinct corners (merged within the tolerance of the module's notes) in order of
        first appearance, one face per triangle, no normals (STL's facet normals are per
        face).

    Raises
    ------
    InputFileError
        Triangle count that disagrees with the file size, ASCII records out of order,
        non-numeric or non-finite coordinates, a triangle with two equal corners.

    Warns
    -----
    UserWarning
        A binary file with fewer than 50 bytes after its triangles (they are ignored).
    """
    if len(data) >= 84:
        n = int(np.frombuffer(data, "<u4", count=1, offset=80)[0])
        extra = len(data) - (84 + 50 * n)
        if extra == 0:
            return _binary(path, data, n)
        # Text never gives a small count (4 printable bytes are >= 0x09090909 as uint32), so
        # a size just above the count's is binary with padding, however its header starts.
        if 0 < extra < 50:
            warnings.warn(f"{path}: {extra} byte(s) after the {n} triangles the header counts are ignored; a "
                          "triangle needs 50, so no triangle is lost.", stacklevel=4)
            return _binary(path, data, n)
    text = text_of(data)
    if text.lstrip()[:5].lower() == b"solid":
        return _ascii(path, text)
    if len(data) < 84:
        raise file_error(path, None, f"{len(data)} bytes: too short for binary STL and not ASCII STL",
                         "pass a complete STL file")
    n = int(np.frombuffer(data, "<u4", count=1, offset=80)[0])
    more = (len(data) - 84 - 50 * n) // 50
    beyond = f", room for {more} more triangle(s)" if more > 0 else ""
    raise file_error(path, "byte 80", f"the header claims {n} triangles ({84 + 50 * n} bytes) but the file has "
                     f"{len(data)} bytes{beyond}", "the file is truncated or corrupt: export it again")


def _binary(path: Path, data: bytes, n: int) -> RawMesh:
    corners = np.frombuffer(data, _BINARY, count=n, offset=84)["corners"].reshape(-1, 3).astype(np.float64)
    bad = np.flatnonzero(~np.isfinite(corners).all(axis=1))
    if bad.size:
        raise file_error(path, f"byte {84 + 50 * (int(bad[0]) // 3)}", f"triangle {int(bad[0]) // 3} has a "
                         "NaN or infinite coordinate", "repair or remove that triangle")
    return _merge(path, corners, lambda f: f"byte {84 + 50 * f}")


def _ascii(path: Path, data: bytes) -> RawMesh:
    t = Tokens(path, data)
    kind = np.char.lower(t.keywords())  # some exporters write SOLID, FACET NORMAL, VERTEX, ...
    body = np.flatnonzero((kind != b"solid") & (kind != b"endsolid"))
    if kind[-1] != b"endsolid":
        raise t.line_error(t.n_lines - 1, f"the file ends with {show(kind[-1])}, not 'endsolid'",
                           "the file is truncated: export it again")
    n_tri = len(body) // len(_FACET)
    expected = np.resize(np.array(_FACET, dtype="S16"), len(body))
    wrong = np.flatnonzero((kind[body] != expected) | (t.count[body] != np.resize(_FACET_TOKENS, len(body))))
    if wrong.size or len(body) % len(_FACET):
        i = int(body[wrong[0]]) if wrong.size else int(body[n_tri * len(_FACET)])
        want = expected[wrong[0]].decode() if wrong.size else "endsolid"
        raise t.line_error(i, f"found {show(t.tok[t.first[i]])} with {int(t.count[i]) - 1} value(s) where "
                           f"'{want}' was expected", "each facet is 'facet normal nx ny nz / outer loop / "
                           "vertex x y z (3 times) / endloop / endfacet'")
    facets = body[0::len(_FACET)]
    t.numbers(t.spans(facets, 2, 3), "facet normal value", finite=False)
    vertex_lines = body[np.isin(np.arange(len(body)) % len(_FACET), [2, 3, 4])]
    index = t.spans(vertex_lines, 1, 3)
    corners = t.numbers(index, "vertex coordinate").reshape(-1, 3)
    return _merge(path, corners, lambda f: f"line {int(t.line_no[facets[f]])}")


def _merge(path: Path, corners: np.ndarray, where) -> RawMesh:
    if len(corners) == 0:
        raise file_error(path, None, "no triangles", "pass an STL file with at least one triangle")
    corners = corners + 0.0  # -0.0 and 0.0 are one corner
    unique, first, inverse = np.unique(corners, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.ravel()
    group = _near_groups(unique, corners.reshape(-1, 3, 3))
    if group is not None:
        # a merged vertex appears where the earliest of its corners does
        earliest = np.full(int(group.max()) + 1, len(corners), dtype=np.int64)
        np.minimum.at(earliest, group, first)
        first, inverse = earliest, group[inverse]
    rank = np.empty(len(first), dtype=np.int64)
    rank[np.argsort(first)] = np.arange(len(first))  # number vertices by first appearance
    faces = rank[inverse.ravel()].reshape(-1, 3)
    points = corners[np.sort(first)]
    a, b, c = faces.T
    repeated = np.flatnonzero((a == b) | (b == c) | (a == c))
    if repeated.size:
        raise file_error(path, where(int(repeated[0])), f"triangle {int(repeated[0])} has two equal corners",
                         "remove that degenerate triangle (e.g. pymeshlab meshing_remove_null_faces)")
    return RawMesh(points=points, faces=faces.astype(np.int64))


def _near_groups(unique: np.ndarray, triangles: np.ndarray) -> np.ndarray | None:
    """Groups of distinct corners that lie within the merge tolerance of each other.

    Parameters
    ----------
    unique : (U, 3) numpy.ndarray of float64
        The distinct corners.
    triangles : (M, 3, 3) numpy.ndarray of float64
        The file's triangles, for the tolerance (see the module's notes).

    Returns
    -------
    (U,) numpy.ndarray of int or None
        Group number of each distinct corner (chains of near pairs form one group); None
        when no two corners are that close.
    """
    edges = np.linalg.norm(triangles - np.roll(triangles, -1, axis=1), axis=2).ravel()
    edges = edges[edges > 0]
    if edges.size == 0 or len(unique) < 2:
        return None
    tol = min(MERGE_TOL * float(np.median(edges)), 0.5 * float(edges.min()))
    pairs = cKDTree(unique).query_pairs(tol, output_type="ndarray")
    if len(pairs) == 0:
        return None
    graph = coo_matrix((np.ones(len(pairs), dtype=np.int8), (pairs[:, 0], pairs[:, 1])),
                       shape=(len(unique), len(unique)))
    return connected_components(graph, directed=False)[1]
