"""ASTM E57 laser-scan files (terrestrial scanners), read with pye57 in a child process.

pye57 wraps libE57Format (C++, with xerces for the file's XML section). Neither sees a
file in this process: the file's 48-byte header is checked here first (signature,
version 1, the file's physical length against its size, where the XML section lies, the
standard's 1024-byte pages), then pye57 decodes the scans in a child process capped in
memory (:data:`CHILD_MEMORY_BASE` plus :data:`MEMORY_PER_FILE_BYTE` times the file's size),
as LAS/LAZ files are (:mod:`.las`). A crash, the cap reached or the time limit is an
InputFileError.

An E57 file holds one or more scans, each in its scanner's own frame with a pose (a unit
quaternion and a translation) that places it in the file's frame. Every scan is read in
the scanner's frame (spherical range/azimuth/elevation scans converted to cartesian by
pye57) and placed by its pose here, so the scans of a registered project come out in one
frame, in file order. The scans are read with pye57's buffers and reader rather than its
``read_scan``, which ignores how many records its reader found: a header counting more
points than the data holds gave uninitialised memory as points; here that is an
InputFileError. Points flagged invalid (``cartesianInvalidState`` or
``sphericalInvalidState`` not 0: no return, or a direction only) and points without
coordinates (all NaN, as some scanners write their no-returns) are left out, with one
warning counting them; a point with some but not all coordinates NaN, or an infinite one,
is a damaged file. The ``scans`` filter keeps the given scans (0-based, in file order);
without it a file holding several scans says so in a warning, with the points per scan.
"""

from __future__ import annotations

import importlib.util
import struct
import warnings
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from ._child import CHILD_EPILOGUE, CHILD_MEMORY_BASE, CHILD_PRELUDE, decode_in_child
from ._common import RawMesh, file_error

__all__ = ["read_e57", "E57_EXTENSIONS", "HEADER_BYTES", "PAGE_SIZE", "MEMORY_PER_FILE_BYTE"]

#: Extensions read by :func:`read_e57`.
E57_EXTENSIONS = (".e57",)

#: Bytes of a file the header check reads: the E57 file header (ASTM E2807, section 8.2).
HEADER_BYTES = 48

#: The standard's page size: each page is 1020 bytes of data and a CRC-32C checksum.
PAGE_SIZE = 1024

#: The child's address space per byte of the file, besides :data:`CHILD_MEMORY_BASE`. pye57
#: reads a scan into float64 arrays, then the child stacks them: 5M points of float32 (a
#: 60 MB file, 12 bytes a point) ran under a cap of 451 MiB in all, some 50 bytes a point
#: above the interpreter's 200 MiB. Scaled integers pack a point into fewer bytes, hence
#: the margin.
MEMORY_PER_FILE_BYTE = 40

_TODO = "pass an ASTM E57 file as the scanner's software wrote it, or export the points as XYZ text"

#: The child: decode the chosen scans (argv[4]: "all" or "0,2") with pye57, each in its
#: scanner's frame, and save the points with each scan's pose; one line on stderr on failure.
_CHILD_CODE = CHILD_PRELUDE + """
import pye57
from pye57.utils import convert_spherical_to_cartesian


def pose(node):
    # by name: the XML may list w, x, y, z in any order (pye57's header reads them in file order)
    q, t = [1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0]
    if node.isDefined("pose/rotation"):
        q = [node["pose"]["rotation"][k].value() for k in "wxyz"]
    if node.isDefined("pose/translation"):
        t = [node["pose"]["translation"][k].value() for k in "xyz"]
    return q, t


CARTESIAN = ["cartesianX", "cartesianY", "cartesianZ"]
SPHERICAL = ["sphericalRange", "sphericalAzimuth", "sphericalElevation"]


def local_points(e57, i, header):
    # pye57's read_scan ignores the count its reader returns: a scan whose header counts
    # more records than its data holds came back padded with uninitialised memory
    fields = header.point_fields
    if all(f in fields for f in CARTESIAN):
        names, state = CARTESIAN, "cartesianInvalidState"
    elif all(f in fields for f in SPHERICAL):
        names, state = SPHERICAL, "sphericalInvalidState"
    else:
        raise ValueError(f"scan {i} holds neither cartesian nor spherical coordinates (its fields: {fields})")
    n = header.point_count
    if n == 0:  # libE57Format refuses a reader on no records, and would fail the whole file
        return np.empty((0, 3)), np.empty(0, dtype=bool)
    data, buffers = e57.make_buffers(names + ([state] if state in fields else []), n)
    reader = header.points.reader(buffers)
    got = reader.read()
    reader.close()
    if got != n:
        raise ValueError(f"scan {i} holds {got} points where its header counts {n}: it is truncated")
    xyz = np.column_stack([data[name] for name in names]).astype(np.float64)
    valid = data[state] == 0 if state in data else np.ones(n, dtype=bool)  # 1: a direction only, 2: no return
    return (xyz if names is CARTESIAN else convert_spherical_to_cartesian(xyz)), valid


def decode():
    e57 = pye57.E57(sys.argv[1])
    n_scans = e57.scan_count
    wanted = list(range(n_scans)) if sys.argv[4] == "all" else [int(i) for i in sys.argv[4].split(",")]
    if any(i >= n_scans for i in wanted):
        np.savez(sys.argv[2], n_scans=n_scans)
        return
    parts, flags, announced, quaternions, translations = [], [], [], [], []
    for i in wanted:
        header = e57.get_header(i)
        announced.append(header.point_count)
        q, t = pose(header.node)
        quaternions.append(q)
        translations.append(t)
        xyz, valid = local_points(e57, i, header)
        parts.append(xyz)
        flags.append(valid)
    counts = np.array([len(p) for p in parts], dtype=np.int64)
    xyz = np.concatenate(parts) if parts else np.empty((0, 3))
    valid = np.concatenate(flags) if flags else np.empty(0, dtype=bool)
    del parts
    np.savez(sys.argv[2], n_scans=n_scans, read=np.array(wanted, dtype=np.int64), valid=valid,
             announced=np.array(announced, dtype=np.int64), counts=counts,
             scan=np.repeat(np.arange(len(wanted)), counts), xyz=xyz,
             quaternion=np.array(quaternions, dtype=np.float64).reshape(-1, 4),
             translation=np.array(translations, dtype=np.float64).reshape(-1, 3))
""" + CHILD_EPILOGUE


def read_e57(path: Path, data: bytes, scans: Iterable[int] | None = None, *, size: int | None = None) -> RawMesh:
    """Parse an E57 file into the points of its scans, each placed by its pose (no faces, no normals).

    Parameters
    ----------
    path : pathlib.Path
        The file (the child process reads it), and for messages.
    data : bytes
        The file's contents, or its first :data:`HEADER_BYTES` at least (its header is
        checked here; the child process reads the file).
    scans : iterable of int, optional
        0-based indices of the scans to keep (in file order, whatever the order given);
        all scans when omitted.
    size : int, optional
        The file's size in bytes (default: ``len(data)``, the whole file).

    Returns
    -------
    RawMesh
        ``points`` (N, 3) float64: the valid points of the kept scans in the file's frame,
        scan after scan in file order, each scan's points in its order; where records were
        left out, ``rows`` (the kept points' positions among the scans' records) and
        ``n_rows`` (the records of the scans read).

    Raises
    ------
    InputFileError
        Not an E57 file; a version other than 1; a truncated or padded one (its size
        differs from its header's length); a header placing the XML section outside the
        file, or pages other than 1024 bytes; pye57 not installed (a platform without
        its wheels); a damaged one (its decoder fails, crashes,
        runs out of its memory or time); a scan index out of range (the message says how
        many scans the file holds); a pose that is not a rotation; a point with some
        coordinates NaN or any infinite; no valid point.

    Warns
    -----
    UserWarning
        When points are left out as invalid (with their count); without ``scans``, when
        the file holds several scans (with the points of each).
    """
    size = len(data) if size is None else int(size)
    _check_header(path, data, size)
    wanted = _wanted_scans(path, scans)
    if not _pye57_installed():
        raise file_error(path, None, "reading E57 files needs pye57, which is not installed (it comes with parambench "
                         "where pye57 publishes wheels: Linux x86-64, macOS arm64, Windows x86-64)",
                         "pip install pye57 where it builds (it needs libxerces-c), or export the points as LAS, PLY "
                         "or XYZ text (CloudCompare, PDAL)")
    arrays = decode_in_child(path, _CHILD_CODE, CHILD_MEMORY_BASE + MEMORY_PER_FILE_BYTE * size,
                             120 + size / 1e6, "E57", _TODO,
                             args=("all" if wanted is None else ",".join(map(str, wanted)),))
    n_scans = int(arrays["n_scans"])
    if n_scans == 0:
        raise file_error(path, None, "the file holds no scans", "pass a file with scanned points")
    if wanted is not None and wanted[-1] >= n_scans:
        raise file_error(path, None, f"no scan {wanted[-1]}: the file holds {n_scans} scan(s), numbered 0 to "
                         f"{n_scans - 1}", "choose scans the file holds")
    read = arrays["read"]
    xyz, kept = _valid_points(path, arrays["xyz"], arrays["valid"], arrays["scan"], read)
    xyz = _placed(path, xyz, arrays["scan"][kept], read, arrays["quaternion"], arrays["translation"])
    dropped = int(arrays["announced"].sum()) - len(xyz)
    if dropped:
        warnings.warn(f"{path}: {dropped} of {int(arrays['announced'].sum())} points are flagged invalid or have no "
                      "coordinates (NaN) and are left out", stacklevel=4)
    if not len(xyz):
        raise file_error(path, None, f"no valid point in scan(s) {', '.join(map(str, read.tolist()))}",
                         "pass a file (or choose scans) with valid points")
    if wanted is None and n_scans > 1:
        per_scan = np.bincount(arrays["scan"][kept], minlength=len(read))
        held = ", ".join(f"{s}: {c}" for s, c in zip(read.tolist(), per_scan.tolist()))
        warnings.warn(f"{path}: all {len(xyz)} points of {n_scans} scans are read, each placed by its pose (points per "
                      f"scan: {held}); keep some with e57_scans (--e57-scans), e.g. {read[np.argmax(per_scan)]}",
                      stacklevel=4)
    if kept.all():
        return RawMesh(points=xyz)
    # Where the points left out sit among the scans' records: output per row (a .csv) keeps
    # a row for each record of the scans read, instead of shifting past each one left out.
    return RawMesh(points=xyz, rows=np.flatnonzero(kept), n_rows=int(kept.size))


def _pye57_installed() -> bool:
    """Whether the child can import pye57 (it is a dependency only where it has wheels)."""
    return importlib.util.find_spec("pye57") is not None


def _check_header(path: Path, data: bytes, size: int) -> None:
    """Refuse a file whose 48-byte header is not E57 version 1 or disagrees with the file's ``size``."""
    if len(data) < HEADER_BYTES or data[:8] != b"ASTM-E57":
        raise file_error(path, None, "not a readable E57 file (no E57 header: it must start with 'ASTM-E57' and hold "
                         f"at least {HEADER_BYTES} bytes)", _TODO)
    major, minor, length, xml_offset, xml_length, page = struct.unpack_from("<IIQQQQ", data, 8)
    if major != 1:
        raise file_error(path, "byte 8", f"not a readable E57 file (version {major}.{minor}; 1.x is read)", _TODO)
    if size < length:
        raise file_error(path, None, f"its header gives its length as {length} bytes but the file holds {size}: "
                         "it is truncated", "pass the whole file")
    if size > length:
        raise file_error(path, None, f"the file holds {size - length} bytes more than the {length} its header gives: "
                         "bytes were appended or the header is damaged", "pass an undamaged copy of the file")
    if page != PAGE_SIZE:
        raise file_error(path, "byte 40", f"not a readable E57 file (pages of {page} bytes; the standard's are "
                         f"{PAGE_SIZE})", _TODO)
    if xml_length == 0 or xml_offset < HEADER_BYTES or xml_offset + xml_length > size:
        raise file_error(path, "byte 24", f"its header places the XML section at byte {xml_offset}, {xml_length} "
                         f"bytes long, outside the file of {size} bytes: the header is damaged",
                         "pass an undamaged copy of the file")


def _wanted_scans(path: Path, scans: Iterable[int] | None) -> list[int] | None:
    """The chosen scan indices, sorted and distinct (None: all), after refusing negative ones."""
    if scans is None:
        return None
    wanted = sorted({int(s) for s in scans})
    if not wanted:
        raise file_error(path, None, "no scan chosen", "give at least one scan index, or leave the scans out")
    if wanted[0] < 0:
        raise file_error(path, None, f"no scan {wanted[0]}: scans are numbered from 0", "choose scans the file holds")
    return wanted


def _valid_points(path: Path, xyz: np.ndarray, valid: np.ndarray, scan: np.ndarray,
                  read: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The points kept (N', 3) and the mask of them among the records ``xyz`` (R, 3).

    A record is left out where its scan flags it invalid (``valid`` False: its coordinates
    mean nothing) or its coordinates are all NaN (a no-return, as some scanners write it).
    Raises InputFileError at the first other record with some but not all coordinates NaN,
    or an infinite one: the scan is damaged there, and dropping the point would hide it.
    """
    kept = valid & np.isfinite(xyz).all(axis=1)
    damaged = np.flatnonzero(valid & ~kept & ~np.isnan(xyz).all(axis=1))
    if damaged.size:
        k = int(damaged[0])
        first_of_scan = int(np.searchsorted(scan, scan[k]))
        raise file_error(path, None, f"point {k - first_of_scan} of scan {int(read[scan[k]])} has a non-finite "
                         f"coordinate {xyz[k].tolist()} ({damaged.size} such point(s))",
                         "repair the scan, or flag such points invalid, in the tool that wrote the file")
    return xyz[kept], kept


def _placed(path: Path, xyz: np.ndarray, scan: np.ndarray, read: np.ndarray, quaternion: np.ndarray,
            translation: np.ndarray) -> np.ndarray:
    """The points (N, 3) of each scan rotated and translated by its pose into the file's frame.

    ``scan`` (N,) is each point's position in ``read`` (ascending: the scans come one after
    the other); ``quaternion`` (S, 4) is ``w, x, y, z``; ``translation`` (S, 3).
    """
    out = np.empty_like(xyz)
    bounds = np.searchsorted(scan, np.arange(len(read) + 1))
    for s in range(len(read)):  # one matrix product per scan
        rotation = _rotation(path, int(read[s]), quaternion[s])
        if not np.all(np.isfinite(translation[s])):
            raise file_error(path, None, f"the pose of scan {int(read[s])} has a non-finite translation "
                             f"{translation[s].tolist()}", "repair the scan's pose in the tool that wrote the file")
        lo, hi = bounds[s], bounds[s + 1]
        _rotate_into(xyz[lo:hi], rotation, translation[s], out[lo:hi])
    if not np.all(np.isfinite(out)):
        raise file_error(path, None, "its poses place points at non-finite coordinates",
                         "repair the scans' poses in the tool that wrote the file")
    return out


def _rotate_into(points: np.ndarray, rotation: np.ndarray, shift: np.ndarray, out: np.ndarray) -> None:
    """``out = points @ rotation.T + shift`` for (N, 3) float64 arrays, one output column at a time.

    numpy's matmul of an (N, 3) by a (3, 3) array took 0.5 s for 1M points here; whole-array
    products make five (N, 3) temporaries (0.8 s for 5M points); this makes one (N,) (0.3 s).
    """
    for i in range(3):  # the three coordinates, not the points
        column = out[:, i]
        np.multiply(points[:, 0], rotation[i, 0], out=column)
        column += points[:, 1] * rotation[i, 1]
        column += points[:, 2] * rotation[i, 2]
        column += shift[i]


def _rotation(path: Path, index: int, q: np.ndarray) -> np.ndarray:
    """The (3, 3) rotation of the quaternion ``q`` (w, x, y, z), normalised: files store it to float precision."""
    norm = float(np.linalg.norm(q)) if np.all(np.isfinite(q)) else 0.0
    if not norm > 1e-6:
        raise file_error(path, None, f"the pose of scan {index} has rotation quaternion {q.tolist()}, not a rotation",
                         "repair the scan's pose in the tool that wrote the file")
    w, x, y, z = q / norm
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
