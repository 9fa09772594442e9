"""Our own readers for the supported mesh and point-cloud formats, one module per format.

They replace pymeshlab's loaders, which crashed (segfault, abort), hung or silently changed
data on hostile files: every reader parses the whole file with numpy, checks counts against
the file size, indices against the vertex count and every coordinate for finiteness, and
raises :class:`~parambench.datasets_gen.errors.InputFileError` with one line naming the file, the line
or byte offset, the problem and what to do. LAS/LAZ LiDAR files and E57 laser scans are the exception: their
header is checked here, laspy or pye57 decodes them in a child process capped in memory
(:mod:`.las`, :mod:`.e57`), and the same checks follow.
"""

from __future__ import annotations

from pathlib import Path

from ..errors import InputFileError
from ._common import RawMesh, read_bytes, read_head
from .e57 import E57_EXTENSIONS, read_e57
from .e57 import HEADER_BYTES as E57_HEADER_BYTES
from .esri_grid import read_asc
from .las import HEADER_BYTES, LAS_EXTENSIONS, read_las
from .obj import read_obj
from .off import read_off
from .pcd import read_pcd
from .ply import read_ply
from .pts import read_pts
from .stl import read_stl
from .xyz import read_xyz

__all__ = ["RawMesh", "READERS", "read_file"]

#: Reader per lower-case extension: ``reader(path, data) -> RawMesh``. ``.txt``, ``.csv`` and
#: ``.asc`` are the names other tools give XYZ text (CloudCompare, spreadsheets, scanners);
#: a ``.asc`` with an ``ncols`` / ``nrows`` header is an ESRI ASCII grid (GIS elevation models);
#: ``.las`` / ``.laz`` are LiDAR point clouds (:func:`read_las`, which also takes classes to keep);
#: ``.pcd`` is the Point Cloud Library's format, ascii, binary or LZF-compressed (:func:`read_pcd`);
#: ``.e57`` laser scans (:func:`read_e57`, which also takes scans to keep).
READERS = {".off": read_off, ".obj": read_obj, ".ply": read_ply, ".stl": read_stl, ".xyz": read_xyz,
           ".pts": read_pts, ".txt": read_xyz, ".csv": read_xyz, ".asc": read_asc, ".las": read_las,
           ".laz": read_las, ".pcd": read_pcd, ".e57": read_e57}


#: Formats a native decoder reads in a child process (:mod:`._child`): the bytes of their
#: header checked here, and the option that selects their points.
_CHILD_DECODED = {**{ext: (HEADER_BYTES, "las_classes") for ext in LAS_EXTENSIONS},
                  **{ext: (E57_HEADER_BYTES, "e57_scans") for ext in E57_EXTENSIONS}}

#: What each selecting option does, and what to leave out, for a file it does not apply to.
_SELECTIONS = {"las_classes": ("LAS classes select points of a .las or .laz file by their classification", "classes"),
               "e57_scans": ("E57 scans select the scans of an .e57 file", "scans")}


def read_file(path: Path, *, las_classes=None, e57_scans=None) -> RawMesh:
    """Read and check a file with the reader its extension names.

    Parameters
    ----------
    path : pathlib.Path
        A file whose lower-case suffix is a key of :data:`READERS`.
    las_classes : iterable of int, optional
        For a LAS/LAZ file, the classification codes to keep (:func:`read_las`).
    e57_scans : iterable of int, optional
        For an E57 file, the 0-based indices of the scans to keep (:func:`read_e57`).

    Returns
    -------
    RawMesh

    Raises
    ------
    InputFileError
        An extension without a reader (the message lists the accepted ones), a missing,
        unreadable or special file, malformed contents, ``las_classes`` for a file
        that is not LAS/LAZ, or ``e57_scans`` for a file that is not E57.
    """
    ext = path.suffix.lower()
    if ext not in READERS:
        raise InputFileError(f"{path}: unsupported file type {ext or '(none)'!r}; supported: "
                             f"{', '.join(READERS)}.")
    chosen = {"las_classes": las_classes, "e57_scans": e57_scans}
    header_bytes, option = _CHILD_DECODED.get(ext, (None, None))
    for name, value in chosen.items():
        if value is not None and name != option:
            what, leave = _SELECTIONS[name]
            raise InputFileError(f"{path}: {what}; this is a {ext} file: leave the {leave} out.")
    if option is not None:  # its decoder reads the file itself: only the header here
        head, size = read_head(path, header_bytes)
        return READERS[ext](path, head, chosen[option], size=size)
    return READERS[ext](path, read_bytes(path))
