"""Reading user files into a :class:`~parambench.datasets_gen.surface.Surface`.

Meshes (OFF, OBJ, PLY, STL) and point clouds (XYZ, also named ``.txt``, ``.csv`` or
``.asc``; PTS; PLY without faces; ESRI ASCII grids, ``.asc`` with an ``ncols`` header, whose
point i is the centre of the i-th cell with data, row by row from the north) are read by our
own numpy readers (:mod:`parambench.datasets_gen.formats`, one module per format): no
native reader sees the file, so a hostile file cannot crash, hang or silently alter the
data. LAS/LAZ LiDAR files are decoded by laspy (LAZ through lazrs, in Rust) and E57 laser
scans by pye57 (libE57Format, in C++) in a child process capped in memory, after their
header is checked here, and the same checks follow
(:mod:`parambench.datasets_gen.formats.las`, :mod:`parambench.datasets_gen.formats.e57`).
Guarantees that
users rely on:

- Row i of ``points`` is vertex i of the file (of its points of the requested classes, for
  a LAS/LAZ file read with ``las_classes``; of the valid points of its scans, scan after
  scan, for an E57 file), unreferenced vertices included; a vertex
  with a NaN, infinite or unparsable coordinate is an error, never dropped (STL has no
  vertex list: its vertices are the distinct corners in order of first appearance, corners
  closer than a millionth of the median triangle edge counting as one).
- Every malformed file (counts that disagree with the file, truncated data, face indices
  out of range or repeated in a face, OBJ index 0, XYZ text lines other than a header of
  column names, polygons that cross themselves, ...) raises InputFileError with one line:
  the file, the line or byte offset, the problem, what to do.
- Normals are kept only when the file stores them (PLY ``nx ny nz``, OFF ``NOFF``, OBJ with
  one ``vn`` per ``v``, XYZ/PTS text columns that a header names ``nx ny nz`` or, without a
  header, that hold normals, binary Expe ``.pts`` with a normal property) and they are
  finite and non-zero (otherwise they are ignored with a warning); computed normals are
  never passed off as data.
- Duplicate points are not merged here: row i stays vertex i (the Surface decides what to do with them).
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from .formats import READERS, read_file
from .mesh_loops import mesh_boundary
from .surface import Surface, degenerate_faces

__all__ = ["load_surface", "SUPPORTED_EXTENSIONS"]

#: Lower-case extensions :func:`load_surface` reads (``.txt``, ``.csv``, ``.asc``: XYZ text; ``.asc``
#: with an ``ncols`` header: an ESRI ASCII grid).
SUPPORTED_EXTENSIONS = tuple(READERS)


def load_surface(path, *, points_only: bool = False, name: str | None = None,
                 drop_degenerate_faces: bool = False, las_classes=None, e57_scans=None) -> Surface:
    """Read a mesh or point cloud.

    Parameters
    ----------
    path : str or os.PathLike
        An ``.off``, ``.obj``, ``.ply``, ``.stl`` mesh or ``.xyz`` (also ``.txt``, ``.csv``,
        ``.asc``), ``.pts``, ``.ply``, ``.las``, ``.laz``, ``.pcd``, ``.e57`` point cloud.
    points_only : bool
        Drop the faces (keep the vertices as a point set); their count goes to
        ``params["faces_dropped"]``.
    name : str, optional
        Surface name; default: the file name without extension.
    drop_degenerate_faces : bool
        Drop faces that repeat a vertex or have zero area (``--repair``; CAD exports' STL
        null facets) instead of refusing the mesh; their count goes to
        ``params["degenerate_faces_dropped"]``.
    las_classes : iterable of int, optional
        For a LAS/LAZ file, the ASPRS classification codes whose points are kept (2: the
        ground), recorded in ``params["las_classes"]``; rows are then the kept points in
        file order. Refused for other formats.
    e57_scans : iterable of int, optional
        For an E57 file, the 0-based indices of the scans whose points are kept (each
        placed by its pose), recorded in ``params["e57_scans"]``; rows are then their valid
        points, scan after scan in file order. Refused for other formats.

    Returns
    -------
    Surface
        ``params`` holds ``source`` (the path) and ``format`` (and ``normals_guessed``: True
        where the normals are columns the file does not name; where the reader dropped
        points the format marks as empty (a PCD's points without a return, an E57 file's
        records flagged invalid), ``input_rows``,
        (N,) int64, the file row of each point, and ``file_rows``, the file's point count);
        for a mesh with manifold edges, ``boundary_loops`` (longest first, following the
        faces) and ``boundary_mask``.

    Raises
    ------
    InputFileError
        Missing, unreadable or special file, a directory, unsupported extension, or
        malformed contents (see :mod:`parambench.datasets_gen.formats`).
    DuplicatePointsError, DegenerateFacesError, InvalidInputError, TooFewPointsError
        From the Surface's validation of the file's contents.
    """
    path = Path(path)
    ext = path.suffix.lower()
    raw = read_file(path, las_classes=las_classes, e57_scans=e57_scans)  # an unknown extension is refused there
    normals = _file_normals(path, raw.normals)
    faces = None if points_only else raw.faces
    params = {"source": str(path), "format": ext[1:]}
    if las_classes is not None:
        params["las_classes"] = sorted({int(c) for c in las_classes})
    if e57_scans is not None:
        params["e57_scans"] = sorted({int(s) for s in e57_scans})
    if raw.rows is not None:  # points the format marks as empty were dropped: where the others sit in the file
        params["input_rows"], params["file_rows"] = np.asarray(raw.rows, dtype=np.int64), int(raw.n_rows)
    if points_only and raw.faces is not None and len(raw.faces):
        params["faces_dropped"] = int(len(raw.faces))  # so a failure can point back to them
    if faces is not None and drop_degenerate_faces:
        keep = ~(degenerate_faces(raw.points, faces))
        if not keep.all():
            faces, params["degenerate_faces_dropped"] = faces[keep], int((~keep).sum())
    loops, mask = mesh_boundary(faces, len(raw.points)) if faces is not None else (None, None)
    return Surface(points=raw.points, faces=faces, normals=normals, name=name or path.stem,
                   params={**params,
                           **({"normals_guessed": True} if raw.normals_guessed and normals is not None else {})},
                   boundary_loops=loops, boundary_mask=mask)


def _file_normals(path: Path, normals: np.ndarray | None) -> np.ndarray | None:
    """The file's normals, unit length, or None (with a warning) if any is non-finite or zero."""
    if normals is None:
        return None
    length = np.linalg.norm(normals, axis=1)
    if not np.all(np.isfinite(length)) or np.any(length < 1e-12):
        warnings.warn(f"{path}: the file's normals are non-finite or zero for some vertices; "
                      "they are ignored.", stacklevel=3)
        return None
    return normals / length[:, None]
