"""Our own readers for the supported mesh and point-cloud formats, one module per format.

They replace pymeshlab's loaders, which crashed (segfault, abort), hung or silently changed
data on hostile files: every reader parses the whole file with numpy, checks counts against
the file size, indices against the vertex count and every coordinate for finiteness, and
raises :class:`~parambench.datasets_gen.errors.InputFileError` with one line naming the file, the line
or byte offset, the problem and what to do.
"""

from __future__ import annotations

from pathlib import Path

from ..errors import InputFileError
from ._common import RawMesh, read_bytes
from .esri_grid import read_asc
from .obj import read_obj
from .off import read_off
from .ply import read_ply
from .pts import read_pts
from .stl import read_stl
from .xyz import read_xyz

__all__ = ["RawMesh", "READERS", "read_file"]

#: Reader per lower-case extension: ``reader(path, data) -> RawMesh``. ``.txt``, ``.csv`` and
#: ``.asc`` are the names other tools give XYZ text (CloudCompare, spreadsheets, scanners);
#: a ``.asc`` with an ``ncols`` / ``nrows`` header is an ESRI ASCII grid (GIS elevation models).
READERS = {".off": read_off, ".obj": read_obj, ".ply": read_ply, ".stl": read_stl, ".xyz": read_xyz,
           ".pts": read_pts, ".txt": read_xyz, ".csv": read_xyz, ".asc": read_asc}


def read_file(path: Path) -> RawMesh:
    """Read and check a file with the reader its extension names.

    Parameters
    ----------
    path : pathlib.Path
        A file whose lower-case suffix is a key of :data:`READERS`.

    Returns
    -------
    RawMesh

    Raises
    ------
    InputFileError
        An extension without a reader (the message lists the accepted ones), a missing,
        unreadable or special file, or malformed contents.
    """
    ext = path.suffix.lower()
    if ext not in READERS:
        raise InputFileError(f"{path}: unsupported file type {ext or '(none)'!r}; supported: "
                             f"{', '.join(READERS)}.")
    return READERS[ext](path, read_bytes(path))
