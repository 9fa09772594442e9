"""Shared parts of the file readers: opening, text, one-line errors, tokens, numbers, faces.

Every reader parses the whole file with numpy before anything is built from it, so no
native reader ever sees an unchecked file. Text is first made uniform (:func:`text_of`: no
byte-order mark, LF line breaks), then tokenised once (``bytes.split`` plus the line each
token starts on, found with vectorised numpy); numbers are converted in one numpy call and
the slow per-token search runs only to name the bad token in an error. Polygons are split
into triangles by :func:`polygons_to_triangles`: a fan for convex ones, ear clipping for
the others.
"""

from __future__ import annotations

import re
import stat
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputFileError

__all__ = ["RawMesh", "read_bytes", "file_error", "show", "text_of", "strip_comments", "Tokens",
           "polygons_to_triangles", "MAX_NUMBER_CHARS", "UTF8_BOM", "STRAIGHT_SINE"]

#: Longer tokens are refused before conversion: a number never needs more characters, and
#: one huge token would make numpy's fixed-width byte array as wide as itself per row.
MAX_NUMBER_CHARS = 64

#: The UTF-8 byte-order mark some Windows tools write at the start of every text file.
UTF8_BOM = b"\xef\xbb\xbf"

#: A polygon corner whose turn (the sine of the angle between its two edges) is at most
#: this counts as straight: a fan triangle or an ear at such a corner would have (almost) no
#: area, and the Surface refuses zero-area faces. Mid-edge corners written with 6
#: significant digits are off their edge's line by about 1e-6 of its length.
STRAIGHT_SINE = 1e-6


@dataclass(frozen=True)
class RawMesh:
    """What a reader found in a file, before any geometric validation.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
        Row i is vertex i of the file; every value finite.
    faces : (M, 3) numpy.ndarray of int64 or None
        Triangles (polygons fan-triangulated), indices in ``[0, N)``, no repeated index in a
        face; None when the file has no faces.
    normals : (N, 3) numpy.ndarray of float64 or None
        Per-vertex normals exactly as stored (not normalised, possibly non-finite); None
        when the file stores none.
    normals_guessed : bool
        The file does not say these columns are normals (an XYZ file without a header):
        the reader took them for normals by their values.
    rows : (N,) numpy.ndarray of int64 or None
        Where the reader dropped points the format marks as empty (a PCD point without a
        return, an E57 record flagged invalid): the file row of each point kept, increasing;
        None when every row is a point.
    n_rows : int or None
        With ``rows``: the number of point rows in the file.
    """

    points: np.ndarray
    faces: np.ndarray | None = None
    normals: np.ndarray | None = None
    normals_guessed: bool = False
    rows: np.ndarray | None = None
    n_rows: int | None = None


def file_error(path: Path, where: str | None, problem: str, todo: str) -> InputFileError:
    """Build the one-line error every reader raises.

    Parameters
    ----------
    path : pathlib.Path
        The file.
    where : str or None
        ``"line 12"``, ``"byte 84"`` or None for the file as a whole.
    problem, todo : str
        What is wrong, and what the user should do about it.

    Returns
    -------
    InputFileError
        Message ``"<path>: <where>: <problem>; <todo>."`` with any line break escaped.
    """
    text = f"{path}: {where + ': ' if where else ''}{problem}; {todo}."
    return InputFileError(text.replace("\r", "\\r").replace("\n", "\\n"))


def show(token: bytes) -> str:
    """A file token quoted for a message: at most 30 characters, no control characters."""
    text = token[:30].decode("utf-8", "replace")
    return repr(text + ("..." if len(token) > 30 else ""))


def read_bytes(path: Path) -> bytes:
    """The whole file, after checking that it is a readable, non-empty regular file.

    Raises
    ------
    InputFileError
        Missing path, directory, special file (FIFO, device, socket: opening one could
        block), unreadable or empty file.
    """
    data, _ = read_head(path, None)
    if not data.strip():
        raise file_error(path, None, "the file is empty", "pass a file that holds the mesh or points")
    return data


def read_head(path: Path, n_bytes: int | None) -> tuple[bytes, int]:
    """The first ``n_bytes`` of a readable regular file (all of it for None) and its size in bytes.

    For formats whose decoder reads the file itself (LAS/LAZ, E57): only their header is read here.

    Raises
    ------
    InputFileError
        As :func:`read_bytes`; an empty file only where ``n_bytes`` is given.
    """
    try:
        info = path.stat()
    except FileNotFoundError:
        raise file_error(path, None, "no such file", "check the path") from None
    except OSError as exc:
        raise file_error(path, None, f"cannot access the file ({exc.strerror or exc})",
                         "check the path and its permissions") from None
    if stat.S_ISDIR(info.st_mode):
        raise file_error(path, None, "is a directory, not a file", "pass the mesh or point-cloud file inside it")
    if not stat.S_ISREG(info.st_mode):
        raise file_error(path, None, "is not a regular file (a pipe, device or socket)",
                         "save the data to a regular file and pass that")
    try:
        with path.open("rb") as fh:
            data = fh.read() if n_bytes is None else fh.read(n_bytes)
    except OSError as exc:
        raise file_error(path, None, f"cannot read the file ({exc.strerror or exc})",
                         "check its permissions") from None
    if n_bytes is not None and info.st_size == 0:
        raise file_error(path, None, "the file is empty", "pass a file that holds the mesh or points")
    return data, (len(data) if n_bytes is None else int(info.st_size))


def text_of(data: bytes) -> bytes:
    """A text file's bytes as the tokeniser expects them: no byte-order mark, LF line breaks.

    Only for text: a binary payload (binary STL or PLY body, Expe PTS) must never pass here.

    Parameters
    ----------
    data : bytes
        The file's contents (or, for PLY, its header).

    Returns
    -------
    bytes
        ``data`` without a leading UTF-8 byte-order mark (it would stick to the first
        token: OBJ lost its first vertex, ``\\ufeffv`` not being the keyword ``v``) and,
        where it holds a CR not followed by LF (classic Mac OS line breaks, or those mixed
        with CRLF), every CRLF and lone CR turned into LF; CRLF files without a lone CR keep
        their CRs, which the tokeniser treats as spaces. Neither changes the number of lines,
        so messages name the lines an editor shows.
    """
    if data.startswith(UTF8_BOM):
        data = data[len(UTF8_BOM):]
    if b"\r" in data:
        lone = data.count(b"\r") - data.count(b"\r\n")
        if lone:  # a lone CR ends a line, as in Python's universal newlines
            data = data.replace(b"\r\n", b"\n").replace(b"\r", b"\n")
    return data


def strip_comments(data: bytes) -> bytes:
    """Blank out ``#`` comments to the end of their line (line numbers are kept)."""
    return re.sub(rb"#[^\n]*", b"", data) if b"#" in data else data


class Tokens:
    """Whitespace-separated tokens of a text and the line each one is on.

    Parameters
    ----------
    path : pathlib.Path
        For error messages.
    data : bytes
        The text (comments already removed if the format has them).
    first_line : int
        Line number of ``data``'s first line in the file (1-based).
    separators : bytes
        Extra bytes treated as whitespace (``b","`` for XYZ).

    Attributes
    ----------
    tok : list of bytes
        The tokens, in file order.
    line : (T,) numpy.ndarray of int64
        1-based file line of each token.
    first, count, line_no : (L,) numpy.ndarray of int64
        Per non-blank line: index of its first token, number of tokens, file line number.
    """

    def __init__(self, path: Path, data: bytes, first_line: int = 1, separators: bytes = b"") -> None:
        self.path = path
        if any(sep in data for sep in separators):
            data = data.translate(bytes.maketrans(separators, b" " * len(separators)))
        self.tok = data.split()
        buf = np.frombuffer(data, dtype=np.uint8)
        space = (buf == 32) | ((buf >= 9) & (buf <= 13))  # exactly the bytes ``bytes.split()`` splits on
        starts = ~space
        starts[1:] &= space[:-1]
        pos = np.flatnonzero(starts)
        ends = ~space
        ends[:-1] &= space[1:]
        self.length = np.flatnonzero(ends) - pos + 1
        self.line = np.searchsorted(np.flatnonzero(buf == 10), pos) + first_line
        new_line = np.ones(len(pos), dtype=bool)
        new_line[1:] = self.line[1:] != self.line[:-1]
        self.first = np.flatnonzero(new_line)
        self.count = np.diff(self.first, append=len(self.tok))
        self.line_no = self.line[self.first]

    @classmethod
    def of(cls, path: Path, tokens: list, lines: np.ndarray) -> "Tokens":
        """Tokens made from a list (e.g. the vertex part of OBJ ``v/vt/vn`` corners) and their lines."""
        self = cls.__new__(cls)
        self.path, self.tok, self.line = path, tokens, np.asarray(lines, dtype=np.int64)
        self.length = np.fromiter((len(x) for x in tokens), dtype=np.int64, count=len(tokens))
        return self

    @property
    def n_lines(self) -> int:
        """Number of non-blank lines."""
        return len(self.first)

    def keywords(self) -> np.ndarray:
        """(L,) bytes array: the first token of each non-blank line (cut to 16 bytes)."""
        return np.array([self.tok[i][:16] for i in self.first.tolist()], dtype="S16")

    def error(self, token_index: int, problem: str, todo: str) -> InputFileError:
        """:func:`file_error` at the line of token ``token_index``."""
        return file_error(self.path, f"line {int(self.line[token_index])}", problem, todo)

    def line_error(self, line_index: int, problem: str, todo: str) -> InputFileError:
        """:func:`file_error` at non-blank line ``line_index`` (0-based among non-blank lines)."""
        return file_error(self.path, f"line {int(self.line_no[line_index])}", problem, todo)

    def spans(self, lines: np.ndarray, offset: int | np.ndarray, width: int | np.ndarray) -> np.ndarray:
        """Token indices ``first + offset + k`` for ``k < width`` of each line in ``lines``, concatenated."""
        width = np.broadcast_to(np.asarray(width, dtype=np.int64), lines.shape)
        start = np.repeat(self.first[lines] + offset, width)
        within = np.arange(int(width.sum())) - np.repeat(np.cumsum(width) - width, width)
        return start + within

    def numbers(self, index: np.ndarray, what: str, *, integer: bool = False, finite: bool = True) -> np.ndarray:
        """Convert the tokens at ``index`` to float64 (or int64) in one numpy call.

        Parameters
        ----------
        index : (K,) numpy.ndarray of int
            Token indices.
        what : str
            What the numbers are, for messages (``"vertex coordinate"``).
        integer : bool
            Parse integers (a face index ``1.0`` is refused).
        finite : bool
            Refuse NaN and infinite values (floats only).

        Returns
        -------
        (K,) numpy.ndarray of float64 or int64

        Raises
        ------
        InputFileError
            At the line of the first token that is not a number of the kind asked for.
        """
        index = np.asarray(index, dtype=np.int64)
        dtype = np.int64 if integer else np.float64
        if index.size == 0:
            return np.zeros(0, dtype=dtype)
        long = np.flatnonzero(self.length[index] > MAX_NUMBER_CHARS)
        if long.size:
            k = int(index[long[0]])
            raise self.error(k, f"{what} {show(self.tok[k])} is too long to be a number", "repair the file")
        lo = int(index[0])
        if index[-1] - lo == len(index) - 1 and np.all(np.diff(index) == 1):
            tokens = self.tok[lo:lo + len(index)]  # a contiguous block: no per-token gather
        else:
            tokens = [self.tok[i] for i in index.tolist()]
        try:
            values = np.array(tokens, dtype=bytes).astype(dtype)
        except (ValueError, OverflowError):
            k = int(index[_first_unparsable(tokens, dtype)])
            kind = "an integer" if integer else "a number"
            raise self.error(k, f"{what} {show(self.tok[k])} is not {kind}", "repair the file") from None
        if finite and not integer:
            self.check_finite(values, index, what)
        return values

    def check_finite(self, values: np.ndarray, index: np.ndarray, what: str) -> None:
        """Raise at the line of the first NaN or infinite entry of ``values`` (token ``index``)."""
        bad = np.flatnonzero(~np.isfinite(np.ravel(values)))
        if bad.size:
            k = int(np.ravel(index)[bad[0]])
            raise self.error(k, f"{what} {show(self.tok[k])} is NaN or infinite",
                             "remove or repair that row (rows are matched to the output by position)")


def _first_unparsable(tokens: list, dtype) -> int:
    """Position of the first token numpy cannot convert (chunks first, so this stays fast)."""
    chunk = 4096
    for lo in range(0, len(tokens), chunk):
        try:
            np.array(tokens[lo:lo + chunk], dtype=bytes).astype(dtype)
        except (ValueError, OverflowError):
            for k in range(lo, min(lo + chunk, len(tokens))):
                try:
                    np.array([tokens[k]], dtype=bytes).astype(dtype)
                except (ValueError, OverflowError):
                    return k
    raise AssertionError("no unparsable token found")  # pragma: no cover - only called after a failure


def polygons_to_triangles(indices: np.ndarray, sizes: np.ndarray, points: np.ndarray, where, path: Path,
                          written: np.ndarray | None = None) -> np.ndarray:
    """Check polygons and split each into triangles that cover it exactly once.

    A convex polygon (every corner turning the same way, strictly, about the polygon's
    Newell normal, and once around in all) becomes a fan from its first corner, as it always
    did; one with a single notch or straight corner (turn at most :data:`STRAIGHT_SINE`: a
    vertex in mid-edge) a fan from that corner, where every triangle of it turns the
    polygon's way (:func:`_fans`, vectorised over all polygons of a size; triangle meshes
    skip it). Any other polygon is ear-clipped in its Newell plane: a fan from a corner that
    cannot see all others covers the notch twice with overlapping triangles, and a fan
    across a straight corner makes zero-area triangles, which the Surface refuses.

    Parameters
    ----------
    indices : (K,) numpy.ndarray of int64
        0-based vertex indices of all polygons, concatenated.
    sizes : (F,) numpy.ndarray of int64
        Corners per polygon (each >= 3, summing to K).
    points : (N, 3) numpy.ndarray of float64
        The file's vertices, all finite; valid indices are ``0 .. N - 1``.
    where : callable
        ``where(f)`` gives the location string (``"line 7"``) of polygon ``f``.
    path : pathlib.Path
        For messages.
    written : (K,) numpy.ndarray of int64, optional
        The indices as the file writes them (OBJ: 1-based or negative), for messages;
        default ``indices``.

    Returns
    -------
    (sum(sizes - 2), 3) numpy.ndarray of int64
        ``sizes[f] - 2`` triangles per polygon, in polygon order, each wound like its
        polygon: for convex polygons the fan ``(v0, v_i, v_i+1)``.

    Raises
    ------
    InputFileError
        A polygon with fewer than 3 corners, an index out of range, an index repeated
        within a polygon (readers used to drop such faces silently), or a polygon of 4 or
        more corners that is not convex and has two corners at one position, no area, or
        crosses or touches itself (no ear to clip).
    """
    sizes = np.asarray(sizes, dtype=np.int64)
    n_vertices = len(points)
    small = np.flatnonzero(sizes < 3)
    if small.size:
        f = int(small[0])
        raise file_error(path, where(f), f"a face with {int(sizes[f])} corner(s)",
                         "every face needs at least 3 vertices; remove that face")
    face_of = np.repeat(np.arange(len(sizes)), sizes)
    out = np.flatnonzero((indices < 0) | (indices >= n_vertices))
    if out.size:
        f = int(face_of[out[0]])
        shown = indices if written is None else written
        raise file_error(path, where(f), f"face index {int(shown[out[0]])} is out of range "
                         f"(the file has {n_vertices} vertices)", "repair or remove that face")
    order = np.lexsort((indices, face_of))
    same = (face_of[order][1:] == face_of[order][:-1]) & (indices[order][1:] == indices[order][:-1])
    if same.any():
        f = int(face_of[order][1:][same][0])
        raise file_error(path, where(f), "a face repeats a vertex index",
                         "remove that degenerate face (e.g. pymeshlab meshing_remove_null_faces)")
    starts = np.cumsum(sizes) - sizes
    n_tri = sizes - 2
    tri_face = np.repeat(np.arange(len(sizes)), n_tri)
    k = np.arange(int(n_tri.sum())) - np.repeat(np.cumsum(n_tri) - n_tri, n_tri)
    base = starts[tri_face]
    tris = np.stack([indices[base], indices[base + k + 1], indices[base + k + 2]], axis=1).astype(np.int64)
    big = np.flatnonzero(sizes > 3)  # a triangle is its own fan
    first_tri = np.cumsum(n_tri) - n_tri
    for size in np.unique(sizes[big]).tolist():  # one (polygons, size) block per size: files hold few sizes
        group = big[sizes[big] == size]
        block = indices[starts[group][:, None] + np.arange(size)]
        fans, ok = _fans(block, points)
        rows = (first_tri[group][:, None] + np.arange(size - 2)).ravel()
        tris[rows] = fans.reshape(-1, 3)
        for f in group[~ok].tolist():
            corners = indices[starts[f]:starts[f] + size]
            tris[first_tri[f]:first_tri[f] + size - 2] = corners[_ear_clip(points[corners], where(f), path)]
    return tris


def _corner_turns(corners: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each corner's turn about its polygon's Newell normal, for polygons of one size.

    Parameters
    ----------
    corners : (P, n, 3) numpy.ndarray of float64
        P polygons of n >= 4 corners each, in order.

    Returns
    -------
    sine : (P, n) numpy.ndarray of float64
        Sine of each corner's turn (positive: turning the polygon's way; NaN without area
        or edge length).
    once : (P,) numpy.ndarray of bool
        The turns add up to one revolution (a pentagram turns the same way everywhere,
        twice round; a bowtie quad not at all).
    normal : (P, 3) numpy.ndarray of float64
        The unit Newell normals.
    """
    p = corners - corners[:, :1]  # relative to the first corner: no cancellation far from 0
    # component arrays of shape (P, n): several times faster than (P, n, 3) cross products
    x, y, z = p[..., 0], p[..., 1], p[..., 2]
    xn, yn, zn = (np.roll(c, -1, axis=1) for c in (x, y, z))
    nx = (y * zn - z * yn).sum(axis=1, keepdims=True)  # Newell normal
    ny = (z * xn - x * zn).sum(axis=1, keepdims=True)
    nz = (x * yn - y * xn).sum(axis=1, keepdims=True)
    bx, by, bz = xn - x, yn - y, zn - z  # the edge leaving each corner
    ax, ay, az = (np.roll(c, 1, axis=1) for c in (bx, by, bz))  # the edge arriving at it
    with np.errstate(invalid="ignore", divide="ignore"):
        length = np.sqrt(nx * nx + ny * ny + nz * nz)
        turn = ((ay * bz - az * by) * nx + (az * bx - ax * bz) * ny + (ax * by - ay * bx) * nz) / length
        sine = turn / np.sqrt((ax * ax + ay * ay + az * az) * (bx * bx + by * by + bz * bz))
        revolutions = np.arctan2(turn, ax * bx + ay * by + az * bz).sum(axis=1) / (2 * np.pi)
        normal = np.concatenate([nx, ny, nz], axis=1) / length
    return sine, np.abs(revolutions - 1.0) < 0.5, normal


def _fans(block: np.ndarray, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Fans that cover polygons of one size exactly once, where a fan does.

    A convex polygon is fanned from its first corner (as it always was); a polygon with one
    corner that is not convex (a notch, or a straight corner: a vertex in mid-edge) and one
    revolution is fanned from that corner, when every triangle of that fan turns the
    polygon's way (the polygon is then star-shaped from it). Files of quads hold many such
    polygons: ear-clipping them one by one took 0.6 ms each (90,000 pentagons: 57 s).

    Parameters
    ----------
    block : (P, n) numpy.ndarray of int64
        Vertex indices of P polygons of n >= 4 corners.
    points : (N, 3) numpy.ndarray of float64

    Returns
    -------
    fans : (P, n - 2, 3) numpy.ndarray of int64
        The triangles, meaningful where ``ok``.
    ok : (P,) numpy.ndarray of bool
        The polygons a fan covers; the others need ear clipping.
    """
    n = block.shape[1]
    sine, once, normal = _corner_turns(points[block])
    with np.errstate(invalid="ignore"):
        bent = ~(sine > STRAIGHT_SINE)  # NaN counts as bent
    n_bent = bent.sum(axis=1)
    apex = np.where(n_bent == 1, np.argmax(bent, axis=1), 0)
    rolled = np.take_along_axis(block, (apex[:, None] + np.arange(n)) % n, axis=1)
    fans = np.stack([np.repeat(rolled[:, :1], n - 2, axis=1), rolled[:, 1:-1], rolled[:, 2:]], axis=2)
    ok = once & (n_bent == 0)
    one = np.flatnonzero(once & (n_bent == 1))
    if one.size:
        a, b, c = (points[fans[one, :, k]] for k in range(3))
        e1, e2 = b - a, c - a
        with np.errstate(invalid="ignore", divide="ignore"):
            s = np.einsum("ptk,pk->pt", np.cross(e1, e2), normal[one]) / (
                np.linalg.norm(e1, axis=2) * np.linalg.norm(e2, axis=2))
            ok[one] = np.all(s > STRAIGHT_SINE, axis=1)
    return fans, ok


def _ear_clip(corners: np.ndarray, where: str, path: Path) -> np.ndarray:
    """Triangulate one polygon by ear clipping in its Newell plane.

    Parameters
    ----------
    corners : (n, 3) numpy.ndarray of float64
        The polygon's corners in order (n >= 4).
    where, path
        For messages.

    Returns
    -------
    (n - 2, 3) numpy.ndarray of int64
        Positions in ``corners`` of each triangle, wound like the polygon, none of them
        with a straight tip (no zero-area triangle).

    Raises
    ------
    InputFileError
        Two corners at the same position, no area, or the polygon crosses or touches
        itself (no ear is left to clip).
    """
    n = len(corners)
    _, first, inverse = np.unique(corners, axis=0, return_index=True, return_inverse=True)
    if len(first) < n:  # two vertices at one position: a collapsed edge, or a polygon pinched into two
        k = int(np.flatnonzero(first[inverse.ravel()] != np.arange(n))[0])
        raise file_error(path, where, f"corners {int(first[inverse.ravel()[k]]) + 1} and {k + 1} of a polygon of {n} "
                         "corners are at the same position", "merge the coincident vertices (e.g. pymeshlab "
                         "meshing_merge_close_vertices) or remove that face")
    rel = corners - corners[0]
    normal = np.cross(rel, np.roll(rel, -1, axis=0)).sum(axis=0)  # Newell normal (twice the area vector)
    size = float(np.ptp(rel, axis=0).max())
    if not np.linalg.norm(normal) > (STRAIGHT_SINE * size) ** 2:
        raise file_error(path, where, f"a polygon of {n} corners has no area (its corners lie on a line, or it "
                         "folds back onto itself)", "remove that face, or triangulate it in the tool that wrote it")
    normal /= np.linalg.norm(normal)
    helper = np.eye(3)[np.argmin(np.abs(normal))]
    u = np.cross(normal, helper)
    u /= np.linalg.norm(u)
    v = np.cross(normal, u)  # (u, v, normal) right-handed: the polygon runs counter-clockwise in (u, v)
    xy = np.stack([rel @ u, rel @ v], axis=1)
    if _crosses_itself(xy):  # ear clipping would cut a pentagram into overlapping triangles without noticing
        raise _crossing(path, where, n)
    left = list(range(n))
    alive = np.ones(n, dtype=bool)  # the corners still in ``left``, as a mask for the numpy tests
    out = []
    k, misses = 0, 0
    while len(left) > 3:
        m = len(left)
        k %= m
        a, b, c = left[k - 1], left[k], left[(k + 1) % m]
        if _is_ear(xy, a, b, c, alive):
            out.append((a, b, c))
            del left[k]  # the next candidate is the corner after the tip, now at position k
            alive[b] = False
            misses = 0
            continue
        k, misses = k + 1, misses + 1
        if misses >= m:
            raise _crossing(path, where, n)
    a, b, c = left
    if not max(_turn_sine(xy, a, b, c), _turn_sine(xy, b, c, a), _turn_sine(xy, c, a, b)) > STRAIGHT_SINE:
        raise _crossing(path, where, n)  # the last triangle would have no area, or run clockwise
    out.append(tuple(left))
    return np.array(out, dtype=np.int64)


def _crossing(path: Path, where: str, n: int) -> InputFileError:
    return file_error(path, where, f"a polygon of {n} corners crosses or touches itself (it cannot be split "
                      "into triangles that cover it once)", "split it into simple polygons, or triangulate it in "
                      "the tool that wrote the file")


def _crosses_itself(xy: np.ndarray) -> bool:
    """Whether two edges of the closed polygon ``xy`` ((n, 2) float64) cross (touching is left to the ears)."""
    n = len(xy)
    start, end = xy, np.roll(xy, -1, axis=0)
    for i in range(n - 2):
        j = np.arange(i + 2, n if i else n - 1)  # the edges that do not share a corner with edge i
        p, q = start[i], end[i]
        d = q - p
        side_a = d[0] * (start[j, 1] - p[1]) - d[1] * (start[j, 0] - p[0])
        side_b = d[0] * (end[j, 1] - p[1]) - d[1] * (end[j, 0] - p[0])
        e = end[j] - start[j]
        side_p = e[:, 0] * (p[1] - start[j, 1]) - e[:, 1] * (p[0] - start[j, 0])
        side_q = e[:, 0] * (q[1] - start[j, 1]) - e[:, 1] * (q[0] - start[j, 0])
        if np.any((side_a * side_b < 0) & (side_p * side_q < 0)):
            return True
    return False


def _turn_sine(xy: np.ndarray, a: int, b: int, c: int) -> float:
    """Sine of the (counter-clockwise) turn at ``b`` on the path a -> b -> c."""
    e1, e2 = xy[b] - xy[a], xy[c] - xy[b]
    length = float(np.hypot(*e1) * np.hypot(*e2))
    return float(e1[0] * e2[1] - e1[1] * e2[0]) / length if length > 0 else 0.0


def _is_ear(xy: np.ndarray, a: int, b: int, c: int, alive: np.ndarray) -> bool:
    """Whether a -> b -> c turns left (strictly) with no other ``alive`` corner inside or on the triangle.

    Corners on the triangle's border count as inside: cutting along a diagonal through a
    straight corner would leave a piece of zero area behind.
    """
    if not _turn_sine(xy, a, b, c) > STRAIGHT_SINE:
        return False
    others = alive.copy()
    others[[a, b, c]] = False
    tri = xy[[a, b, c]]
    edges = np.roll(tri, -1, axis=0) - tri
    lengths = np.hypot(edges[:, 0], edges[:, 1])
    rel = xy[others][:, None, :] - tri[None, :, :]  # (others, 3 corners, 2)
    # signed distance of each other corner from each edge's line, positive inside
    dist = (edges[None, :, 0] * rel[:, :, 1] - edges[None, :, 1] * rel[:, :, 0]) / lengths[None, :]
    inside = np.all(dist >= -STRAIGHT_SINE * lengths.max(), axis=1)
    return not inside.any()
