"""STL, binary and ASCII: triangles given by their corner coordinates.

STL has no vertex list: the vertices are the distinct corners in order of first
appearance (exactly equal coordinates are merged, nothing within a tolerance). A file is
binary when its size is exactly 84 + 50 * (the triangle count at byte 80); otherwise it
must be ASCII (``solid`` ... ``endsolid``), and a binary-looking file whose count
disagrees with its size is refused (that file used to keep the native reader busy forever).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ._common import RawMesh, Tokens, file_error, show

__all__ = ["read_stl"]

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
        Distinct corners in order of first appearance, one face per triangle, no normals
        (STL's facet normals are per face).

    Raises
    ------
    InputFileError
        Triangle count that disagrees with the file size, ASCII records out of order,
        non-numeric or non-finite coordinates, a triangle with two equal corners.
    """
    if len(data) >= 84:
        n = int(np.frombuffer(data, "<u4", count=1, offset=80)[0])
        if len(data) == 84 + 50 * n:
            return _binary(path, data, n)
    if data.lstrip()[:5] == b"solid":
        return _ascii(path, data)
    if len(data) < 84:
        raise file_error(path, None, f"{len(data)} bytes: too short for binary STL and not ASCII STL",
                         "pass a complete STL file")
    n = int(np.frombuffer(data, "<u4", count=1, offset=80)[0])
    raise file_error(path, "byte 80", f"the header claims {n} triangles ({84 + 50 * n} bytes) but the file has "
                     f"{len(data)} bytes", "the file is truncated or corrupt: export it again")


def _binary(path: Path, data: bytes, n: int) -> RawMesh:
    corners = np.frombuffer(data, _BINARY, count=n, offset=84)["corners"].reshape(-1, 3).astype(np.float64)
    bad = np.flatnonzero(~np.isfinite(corners).all(axis=1))
    if bad.size:
        raise file_error(path, f"byte {84 + 50 * (int(bad[0]) // 3)}", f"triangle {int(bad[0]) // 3} has a "
                         "NaN or infinite coordinate", "repair or remove that triangle")
    return _merge(path, corners, lambda f: f"byte {84 + 50 * f}")


def _ascii(path: Path, data: bytes) -> RawMesh:
    t = Tokens(path, data)
    kind = t.keywords()
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
    _, first, inverse = np.unique(corners, axis=0, return_index=True, return_inverse=True)
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
