"""Our own readers for the supported mesh and point-cloud formats, one module per format.

They replace pymeshlab's loaders, which crashed (segfault, abort), hung or silently changed
data on hostile files: every reader parses the whole file with numpy, checks counts against
the file size, indices against the vertex count and every coordinate for finiteness, and
raises :class:`~parambench.datasets_gen.errors.InputFileError` with one line naming the file, the line
or byte offset, the problem and what to do.
"""

from __future__ import annotations

from pathlib import Path

from ._common import RawMesh, read_bytes
from .obj import read_obj
from .off import read_off
from .ply import read_ply
from .pts import read_pts
from .stl import read_stl
from .xyz import read_xyz

__all__ = ["RawMesh", "READERS", "read_file"]

#: Reader per lower-case extension: ``reader(path, data) -> RawMesh``.
READERS = {".off": read_off, ".obj": read_obj, ".ply": read_ply, ".stl": read_stl, ".xyz": read_xyz,
           ".pts": read_pts}


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
        Missing, unreadable or special file, or malformed contents.
    KeyError
        The suffix has no reader (callers check the extension first).
    """
    reader = READERS[path.suffix.lower()]
    return reader(path, read_bytes(path))
