"""LAS and LAZ point clouds (airborne and terrestrial LiDAR), read with laspy in a child process.

laspy parses the LAS header and point records with numpy, LAZ through lazrs, a Rust
decompressor. Neither sees a file in this process: the file's header is checked here
first (signature, version, point count against the file's size), then laspy decodes it
in a child process capped in memory (:data:`CHILD_MEMORY_BASE` plus 6 times the
announced records). A damaged LAZ file made lazrs ask for 3.2 GB and abort the process
(``simple.copc.laz`` with a few bytes changed; another version of it grew one to 20 GB):
here that is an InputFileError. laspy also returns fewer points than the header
announces, without a word, from a file cut off at a record boundary (its ``simple.las``
cut 3,400 bytes short: 965 of 1,065 points): such a file is refused too. Points are the
scaled and offset coordinates, in file order. A LiDAR tile mixes surfaces (ground,
buildings, vegetation, wires); the ``classes`` filter keeps the points of the given ASPRS
classification codes (2 is the ground), and without it a file holding several classes
says so in a warning, with the counts. Points flagged withheld are left out, as the ASPRS
specification asks ("synonymous with deleted"), with a warning that counts them; without
a class filter the points kept say which file rows they are (a ``.csv`` keeps a nan,nan
row for each withheld one).
"""

from __future__ import annotations

import struct
import warnings
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from ._child import CHILD_EPILOGUE, CHILD_MEMORY_BASE, CHILD_PRELUDE, decode_in_child
from ._common import RawMesh, file_error

__all__ = ["read_las", "LAS_EXTENSIONS", "HEADER_BYTES", "CLASS_NAMES", "CHILD_MEMORY_BASE"]

#: Extensions read by :func:`read_las`.
LAS_EXTENSIONS = (".las", ".laz")

#: Bytes of a file the header check reads: the public header block of LAS 1.4 (375).
HEADER_BYTES = 375

#: ASPRS standard classification codes (LAS 1.4, point formats 6-10; 0-12 in every version).
CLASS_NAMES = {0: "never classified", 1: "unclassified", 2: "ground", 3: "low vegetation",
               4: "medium vegetation", 5: "high vegetation", 6: "building", 7: "low point (noise)",
               8: "model key point", 9: "water", 10: "rail", 11: "road surface", 12: "overlap",
               13: "wire guard", 14: "wire conductor", 15: "transmission tower", 16: "wire connector",
               17: "bridge deck", 18: "high noise"}

#: Largest ratio of a LAZ file's announced records to its size (LASzip packs LiDAR records
#: 5-15 times): a header announcing more is damaged, not compressed.
_MAX_COMPRESSION = 50

_TODO = "pass a LAS 1.0-1.4 or LAZ file, or export the points as XYZ text"

#: The child: decode with laspy, save coordinates and classes; one line on stderr on failure.
_CHILD_CODE = CHILD_PRELUDE + """
import laspy


def decode():
    las = laspy.read(sys.argv[1])
    np.savez(sys.argv[2], x=np.asarray(las.x, dtype=np.float64), y=np.asarray(las.y, dtype=np.float64),
             z=np.asarray(las.z, dtype=np.float64), c=np.asarray(las.classification, dtype=np.int64),
             w=np.asarray(las.withheld, dtype=bool))
""" + CHILD_EPILOGUE


def read_las(path: Path, data: bytes, classes: Iterable[int] | None = None, *, size: int | None = None) -> RawMesh:
    """Parse a LAS or LAZ file into its points (no faces, no normals).

    Parameters
    ----------
    path : pathlib.Path
        The file (the child process reads it), and for messages.
    data : bytes
        The file's contents, or its first :data:`HEADER_BYTES` at least (its header is
        checked here; the child process reads the file).
    classes : iterable of int, optional
        ASPRS classification codes to keep (e.g. ``[2]``: the ground); all points when
        omitted.
    size : int, optional
        The file's size in bytes (default: ``len(data)``, the whole file).

    Returns
    -------
    RawMesh
        ``points`` (N, 3) float64: the scaled coordinates of the kept points, in file order;
        without ``classes``, where points flagged withheld were left out, ``rows`` (the
        file rows of the points kept) and ``n_rows``.

    Raises
    ------
    InputFileError
        Not a LAS/LAZ file; a damaged one (its decoder fails, crashes or runs out of its
        memory); a truncated one (fewer point records than its header counts);
        non-finite coordinates (a header's scale or offset); no points; or no point of
        the requested classes (the message lists the classes the file holds).

    Warns
    -----
    UserWarning
        Without ``classes``, when the points belong to several classes; when points
        flagged withheld are left out (with their count).
    """
    announced, record_length = _checked_header(path, data, len(data) if size is None else int(size))
    if announced == 0:
        raise file_error(path, None, "the file holds no points", "pass a file with points")
    xyz, codes, withheld = _decoded(path, announced * record_length)
    n = len(codes)
    if n != announced:
        raise file_error(path, None, f"the header counts {announced} points but the file holds {n}: it is truncated",
                         "pass the whole file")
    if not np.all(np.isfinite(xyz)):
        raise file_error(path, None, "its header's scale or offset makes coordinates non-finite",
                         "repair the header (scale and offset) with the tool that wrote the file")
    if withheld.any():
        # ASPRS: a withheld point "should not be included in processing (synonymous with deleted)".
        warnings.warn(f"{path}: {int(withheld.sum())} of {n} points are flagged withheld (deleted) and are left out",
                      stacklevel=4)
        if withheld.all():
            raise file_error(path, None, f"all {n} points are flagged withheld (deleted)", "pass a file with points")
    held = _class_counts(codes[~withheld])
    if classes is None:
        n_classes = np.unique(codes[~withheld]).size
        if n_classes > 1:
            warnings.warn(f"{path}: all {int((~withheld).sum())} points are read, of {n_classes} classification "
                          f"classes ({held}); keep some with las_classes (--las-classes), e.g. 2 for the ground",
                          stacklevel=4)
        if not withheld.any():
            return RawMesh(points=xyz)
        # The file's rows of the points kept, so that a .csv keeps a row per record.
        return RawMesh(points=xyz[~withheld], rows=np.flatnonzero(~withheld), n_rows=n)
    wanted = sorted({int(c) for c in classes})
    keep = np.isin(codes, wanted) & ~withheld
    if not keep.any():
        raise file_error(path, None, f"no point of class {', '.join(map(str, wanted))}; the file holds {held}",
                         "choose classes the file holds")
    return RawMesh(points=xyz[keep])


def _checked_header(path: Path, data: bytes, size: int) -> tuple[int, int]:
    """The header's point count and record length, after checking them against the file's ``size``."""
    if len(data) < 227 or data[:4] != b"LASF":
        raise file_error(path, None, "not a readable LAS/LAZ file (no LAS header: it must start with 'LASF' and "
                         "hold at least 227 bytes)", _TODO)
    major, minor = data[24], data[25]
    if major != 1 or minor > 4:
        raise file_error(path, None, f"not a readable LAS/LAZ file (version {major}.{minor}; 1.0-1.4 are read)", _TODO)
    header_size, = struct.unpack_from("<H", data, 94)
    offset, = struct.unpack_from("<I", data, 96)
    compressed = bool(data[104] & 0x80)
    record_length, = struct.unpack_from("<H", data, 105)
    count, = struct.unpack_from("<I", data, 107)
    if minor == 4 and header_size >= 255 and len(data) >= 255:
        count = max(count, struct.unpack_from("<Q", data, 247)[0])  # the 64-bit count of LAS 1.4
    if offset > size or record_length == 0:
        raise file_error(path, None, f"not a readable LAS/LAZ file (point data at byte {offset}, records of "
                         f"{record_length} bytes, in a file of {size} bytes)", _TODO)
    room = size - offset
    if not compressed and count * record_length > room:
        raise file_error(path, None, f"the header counts {count} points but the file holds "
                         f"{room // record_length}: it is truncated", "pass the whole file")
    if compressed and count * record_length > _MAX_COMPRESSION * max(room, 1):
        raise file_error(path, None, f"the header counts {count} points, more than a compressed file of "
                         f"{size} bytes can hold: it is damaged", "pass an undamaged copy of the file")
    return int(count), int(record_length)


def _decoded(path: Path, record_bytes: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """laspy's coordinates (N, 3), classification codes (N,) and withheld flags (N,) of the file, decoded in a capped child."""
    arrays = decode_in_child(path, _CHILD_CODE, CHILD_MEMORY_BASE + 6 * record_bytes, 120 + record_bytes / 1e6,
                             "LAS/LAZ", _TODO)
    return np.column_stack([arrays["x"], arrays["y"], arrays["z"]]), arrays["c"], arrays["w"]


def _class_counts(codes: np.ndarray) -> str:
    """``"1 unclassified: 789, 2 ground: 276"``: the classes held, with their point counts."""
    values, counts = np.unique(codes, return_counts=True)
    return ", ".join(f"{v} {CLASS_NAMES.get(int(v), 'user-defined')}: {c}" for v, c in zip(values, counts))
