"""PTS point clouds: the text form (read as XYZ) and the binary Expe form.

Binary Expe files (``[Expe/PointSet/Binary/0.1]``, as in pymeshlab's ``chameleon.pts``)
have a text header of ``property NAME BYTES`` lines, ``nofpoints N`` and ``data``, then N
little-endian records holding the properties in header order. ``position`` (3 float32)
is required; ``normal`` (3 float32) is kept; other properties are skipped.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ._common import RawMesh, file_error, show, text_of
from .xyz import read_xyz

__all__ = ["read_pts"]

_EXPE = b"[Expe/PointSet/Binary"
_DATA = re.compile(rb"(?m)^data\r?\n")


def read_pts(path: Path, data: bytes) -> RawMesh:
    """Parse a text or binary Expe PTS file.

    Parameters
    ----------
    path : pathlib.Path
        For messages.
    data : bytes
        The file's contents.

    Returns
    -------
    RawMesh
        Points in file order, normals when stored.

    Raises
    ------
    InputFileError
        As :func:`~parambench.datasets_gen.formats.xyz.read_xyz` for text; for binary: a malformed
        header, no ``position`` property, a point count that disagrees with the file size,
        NaN or infinite coordinates.
    """
    if data.startswith(_EXPE):
        return _expe(path, data)  # binary: never through text_of
    text = text_of(data)
    if text.lstrip().startswith(b"["):
        raise file_error(path, "line 1", f"unsupported PTS variant {show(text.split(None, 1)[0])}",
                         "save the points as text x y z [nx ny nz] rows or binary Expe")
    return read_xyz(path, text)


def _expe(path: Path, data: bytes) -> RawMesh:
    end = _DATA.search(data, 0, 65536)
    if end is None:
        raise file_error(path, None, "no 'data' line ending the Expe header", "the header is truncated or corrupt")
    props, n_points, offset = [], None, 0
    for no, raw in enumerate(data[:end.start()].split(b"\n")[1:], start=2):
        words = raw.split()
        if not words:
            continue
        if words[0] == b"property" and len(words) == 3 and words[2].isdigit():
            props.append((words[1].decode("ascii", "replace"), offset, int(words[2])))
            offset += int(words[2])
        elif words[0] == b"nofpoints" and len(words) == 2 and words[1].isdigit():
            n_points = int(words[1])
        else:
            raise file_error(path, f"line {no}", f"unexpected header line {show(raw.strip())}",
                             "expected 'property NAME BYTES' or 'nofpoints N'")
    sizes = {name: (start, size) for name, start, size in props}
    if sizes.get("position", (0, 0))[1] != 12:
        raise file_error(path, None, "no 12-byte 'position' property", "the header must declare 'property position 12'")
    if n_points is None:
        raise file_error(path, None, "no 'nofpoints' line", "the header must state the number of points")
    body = len(data) - end.end()
    if body != n_points * offset:
        raise file_error(path, f"byte {end.end()}", f"the header declares {n_points} points of {offset} bytes "
                         f"({n_points * offset} bytes) but {body} bytes follow",
                         "the file is truncated or corrupt: export it again")
    names = ["position"] + (["normal"] if sizes.get("normal", (0, 0))[1] == 12 else [])
    dtype = np.dtype({"names": names, "formats": [("<f4", (3,))] * len(names),
                      "offsets": [sizes[k][0] for k in names], "itemsize": offset})
    records = np.frombuffer(data, dtype, count=n_points, offset=end.end())
    points = records["position"].astype(np.float64)
    bad = np.flatnonzero(~np.isfinite(points).all(axis=1))
    if bad.size:
        raise file_error(path, f"byte {end.end() + offset * int(bad[0])}",
                         f"point {int(bad[0])} has a NaN or infinite coordinate",
                         "remove or repair that point (rows are matched to the output by position)")
    normals = records["normal"].astype(np.float64) if "normal" in names else None
    return RawMesh(points=points, normals=normals)
