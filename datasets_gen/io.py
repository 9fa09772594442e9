"""Reading user files into a :class:`~datasets_gen.surface.Surface`.

Meshes (OFF, OBJ, PLY, STL) and point clouds (XYZ, PTS, PLY without faces) are read with
pymeshlab. Guarantees that users rely on:

- Row i of ``points`` is vertex i of the file, unreferenced vertices included (checked
  against the vertex count the file declares; STL has no vertex list: its vertices are the
  distinct corners in order of first appearance).
- Normals are kept only when the file stores them (PLY ``nx ny nz``, OFF ``NOFF``, OBJ with
  one ``vn`` per ``v``, XYZ/PTS text with six columns, binary Expe ``.pts`` with a normal
  property) and they are finite and non-zero; pymeshlab's own computed normals are never
  passed off as data.
- Duplicate points are not merged: the Surface raises DuplicatePointsError.
"""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np

from .errors import InputFileError
from .mesh_loops import mesh_boundary
from .surface import Surface

__all__ = ["load_surface", "SUPPORTED_EXTENSIONS"]

SUPPORTED_EXTENSIONS = (".off", ".obj", ".ply", ".stl", ".xyz", ".pts")
#: Bytes of a file's head read to find its header.
HEADER_BYTES = 65536


def load_surface(path, *, points_only: bool = False, name: str | None = None) -> Surface:
    """Read a mesh or point cloud.

    Parameters
    ----------
    path : str or os.PathLike
        An ``.off``, ``.obj``, ``.ply``, ``.stl`` mesh or ``.xyz``, ``.pts``, ``.ply`` point cloud.
    points_only : bool
        Drop the faces (keep the vertices as a point set).
    name : str, optional
        Surface name; default: the file name without extension.

    Returns
    -------
    Surface
        ``params`` holds ``source`` (the path) and ``format``; for a mesh with manifold
        edges, ``boundary_loops`` (longest first, following the faces) and ``boundary_mask``.

    Raises
    ------
    InputFileError
        Missing or unreadable file, unsupported extension, or a reader that changed the
        vertex count.
    DuplicatePointsError, DegenerateFacesError, InvalidInputError, TooFewPointsError
        From the Surface's validation of the file's contents.
    """
    import pymeshlab

    path = Path(path)
    ext = path.suffix.lower()
    if ext not in SUPPORTED_EXTENSIONS:
        raise InputFileError(f"{path}: unsupported file type {ext or '(none)'!r}; supported: "
                             f"{', '.join(SUPPORTED_EXTENSIONS)}.")
    if not path.is_file():
        raise InputFileError(f"{path}: no such file; check the path.")
    try:
        with path.open("rb") as fh:
            head = fh.read(HEADER_BYTES)
    except OSError as exc:
        raise InputFileError(f"{path}: cannot read the file ({exc}).") from None
    meshset = pymeshlab.MeshSet()
    try:
        meshset.load_new_mesh(str(path))
    except Exception as exc:  # pymeshlab raises its own exception types for any bad file
        raise InputFileError(f"{path}: cannot read it as {ext[1:].upper()} ({exc}); check the file.") from None
    mesh = meshset.current_mesh()
    points = np.array(mesh.vertex_matrix(), dtype=np.float64)
    obj_vertices, obj_normals = _scan_obj(path) if ext == ".obj" else (None, None)
    declared = obj_vertices if ext == ".obj" else _declared_vertex_count(head, ext)
    if declared is not None and declared != len(points):
        raise InputFileError(f"{path}: the file declares {declared} vertices but {len(points)} were read; "
                             "the reader drops vertices with NaN, infinite or unparsable coordinates, and the vertex "
                             "order cannot then be guaranteed, so the file is refused: repair those vertices.")
    faces = np.array(mesh.face_matrix(), dtype=np.int64) if mesh.face_number() > 0 else None
    normals = _file_normals(path, head, ext, mesh, len(points), obj_normals)
    if points_only:
        faces = None
    loops, mask = mesh_boundary(faces, len(points)) if faces is not None else (None, None)
    return Surface(points=points, faces=faces, normals=normals, name=name or path.stem,
                   params={"source": str(path), "format": ext[1:]}, boundary_loops=loops, boundary_mask=mask)


def _declared_vertex_count(head: bytes, ext: str) -> int | None:
    """The vertex count a PLY or OFF header states (None for other formats or odd headers)."""
    if ext == ".ply":
        m = re.search(rb"element\s+vertex\s+(\d+)", head)
        return int(m.group(1)) if m else None
    if ext == ".off":
        tokens = re.sub(rb"#[^\n]*", b"", head).split()
        # "[ST][C][N][4][n]OFF nv nf ne"; the rare n-dimensional variant puts a dimension first
        if len(tokens) > 1 and tokens[0].endswith(b"OFF") and b"n" not in tokens[0] and tokens[1].isdigit():
            return int(tokens[1])
    return None


def _file_has_normals(head: bytes, ext: str) -> bool:
    if ext == ".ply":
        header = head.split(b"end_header", 1)[0]
        return re.search(rb"property\s+\w+\s+nx\b", header) is not None
    if ext == ".off":
        tokens = re.sub(rb"#[^\n]*", b"", head).split()
        return bool(tokens) and b"N" in tokens[0][:-3]
    if ext in (".xyz", ".pts"):
        if head.startswith(b"[Expe/PointSet"):
            return b"property normal" in head.split(b"data", 1)[0]
        for line in head.splitlines():
            fields = line.replace(b",", b" ").split()
            if fields and not line.lstrip().startswith(b"#"):
                return len(fields) >= 6
        return False
    return False


def _scan_obj(path: Path) -> tuple[int, list]:
    """Count the ``v`` lines of an OBJ and collect its ``vn`` rows."""
    n_vertices, normal_rows = 0, []
    with path.open("rb") as fh:
        for line in fh:
            if line.startswith(b"v "):
                n_vertices += 1
            elif line.startswith(b"vn "):
                normal_rows.append(line.split()[1:4])
    return n_vertices, normal_rows


def _file_normals(path: Path, head: bytes, ext: str, mesh, n_points: int, obj_rows) -> np.ndarray | None:
    if ext == ".obj":
        # OBJ normals count as per-vertex data only with one ``vn`` per ``v``, in order.
        normals = None
        if obj_rows and len(obj_rows) == n_points:
            try:
                normals = np.array(obj_rows, dtype=np.float64)
            except ValueError:
                normals = None
    elif _file_has_normals(head, ext):
        normals = np.array(mesh.vertex_normal_matrix(), dtype=np.float64)
    else:
        normals = None
    if normals is None:
        return None
    length = np.linalg.norm(normals, axis=1)
    if normals.shape != (n_points, 3) or not np.all(np.isfinite(length)) or np.any(length < 1e-12):
        warnings.warn(f"{path}: the file's normals are missing, non-finite or zero for some vertices; "
                      "they are ignored.", stacklevel=3)
        return None
    return normals / length[:, None]
