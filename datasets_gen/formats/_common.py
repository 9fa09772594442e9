"""Shared parts of the file readers: opening, one-line errors, tokens, numbers, faces.

Every reader parses the whole file with numpy before anything is built from it, so no
native reader ever sees an unchecked file. Text is tokenised once (``bytes.split`` plus
the line each token starts on, found with vectorised numpy); numbers are converted in one
numpy call and the slow per-token search runs only to name the bad token in an error.
"""

from __future__ import annotations

import re
import stat
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputFileError

__all__ = ["RawMesh", "read_bytes", "file_error", "show", "strip_comments", "Tokens",
           "polygons_to_triangles", "MAX_NUMBER_CHARS"]

#: Longer tokens are refused before conversion: a number never needs more characters, and
#: one huge token would make numpy's fixed-width byte array as wide as itself per row.
MAX_NUMBER_CHARS = 64


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
    """

    points: np.ndarray
    faces: np.ndarray | None = None
    normals: np.ndarray | None = None


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
            data = fh.read()
    except OSError as exc:
        raise file_error(path, None, f"cannot read the file ({exc.strerror or exc})",
                         "check its permissions") from None
    if not data.strip():
        raise file_error(path, None, "the file is empty", "pass a file that holds the mesh or points")
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


def polygons_to_triangles(indices: np.ndarray, sizes: np.ndarray, n_vertices: int, where, path: Path,
                          written: np.ndarray | None = None) -> np.ndarray:
    """Check polygons and split each into a fan of triangles.

    Parameters
    ----------
    indices : (K,) numpy.ndarray of int64
        0-based vertex indices of all polygons, concatenated.
    sizes : (F,) numpy.ndarray of int64
        Corners per polygon (each >= 3, summing to K).
    n_vertices : int
        Valid indices are ``0 .. n_vertices - 1``.
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
        Triangles ``(v0, v_i, v_i+1)`` in polygon order.

    Raises
    ------
    InputFileError
        A polygon with fewer than 3 corners, an index out of range, or an index repeated
        within a polygon (readers used to drop such faces silently).
    """
    sizes = np.asarray(sizes, dtype=np.int64)
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
    return np.stack([indices[base], indices[base + k + 1], indices[base + k + 2]], axis=1).astype(np.int64)
