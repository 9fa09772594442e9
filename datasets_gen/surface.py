"""The ``Surface`` hand-off: what every generator and loader produces and every method reads.

Validation lives here, once, at the public boundary (the pattern of scikit-learn and
robust-laplacian): a ``Surface`` that exists has finite float64 points, in-range int64
faces without degenerate triangles, and unit normals if any.

Coincident points are accepted where they are data: in a bare point set (point-set methods
merge them, :mod:`parambench.methods.pointset.coincident`) and in a mesh whose faces keep them apart
(the cut seams of textured exports). A mesh edge joining two coincident vertices is refused.

Ground truth (exact map, true boundary, the generator's normals) travels on the
``Surface`` for evaluation. What a method may see is a :class:`MethodInput`: what a user's
file would hold (points, faces, normals that are data, a name, loops the caller supplies)
and no ground-truth attribute at all; :meth:`Surface.method_input` builds one for a sweep,
and :meth:`parambench.methods.base.Method.__call__` converts any ``Surface`` it is given.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from .errors import (
    DegenerateFacesError,
    DuplicatePointsError,
    InvalidInputError,
    TooFewPointsError,
    repairable,
)

__all__ = ["Surface", "MethodInput", "validate_points", "validate_faces", "flat_faces", "circumradii",
           "counter_clockwise", "validate_normals",
           "find_duplicate_points", "require_unique_points", "require_no_collapsed_edges", "duplicate_tolerance", "core_box",
           "degenerate_faces",
           "MIN_POINTS"]

#: What ``--repair`` does about degenerate faces (completes "pass --repair to ...").
DROP_DEGENERATE_ACTION = "drop them (a mesh with a hole where they were)"

#: Fewer points than this cannot define a surface patch with an interior.
MIN_POINTS = 4

#: Points closer than this fraction of the box diagonal (:func:`duplicate_tolerance`) count as duplicates.
DUPLICATE_TOL = 1e-9

#: Faces whose area is below this fraction of (mean edge length)^2 count as degenerate.
DEGENERATE_AREA_TOL = 1e-12


def validate_points(points: Any, *, name: str = "points", min_points: int = MIN_POINTS) -> np.ndarray:
    """Check and convert a point array.

    Parameters
    ----------
    points : (N, 3) array_like of float
        Point coordinates.
    name : str
        Used in error messages.
    min_points : int
        Smallest accepted N.

    Returns
    -------
    (N, 3) numpy.ndarray of float64, C-contiguous.

    Raises
    ------
    InvalidInputError
        Wrong shape, non-numeric dtype, NaN or infinite coordinates.
    TooFewPointsError
        N < ``min_points``.
    """
    try:
        arr = np.asarray(points)
    except ValueError as exc:  # ragged rows: numpy's "inhomogeneous shape"
        raise InvalidInputError(f"{name} must be an (N, 3) array; rows of different lengths were given "
                                f"({exc}).") from None
    if arr.dtype.kind not in "fiu":
        raise InvalidInputError(f"{name} must be a numeric array, got dtype {arr.dtype}; pass float coordinates.")
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise InvalidInputError(f"{name} must have shape (N, 3), got {arr.shape}; pass one row x, y, z per point.")
    arr = np.ascontiguousarray(arr, dtype=np.float64)
    bad = ~np.isfinite(arr).all(axis=1)
    if bad.any():
        idx = np.flatnonzero(bad)
        raise InvalidInputError(
            f"{name} has {idx.size} row(s) with NaN or infinite coordinates (first: row {idx[0]}); "
            "remove or repair those points before flattening."
        )
    if arr.shape[0] < min_points:
        raise TooFewPointsError(
            f"{name} has {arr.shape[0]} point(s); at least {min_points} are needed. Sample the surface more densely."
        )
    return arr


#: Percentile of the points along each axis where :func:`core_box` starts (and 100 minus it where it ends).
CORE_PERCENTILE = 1.0


def core_box(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The box from the ``CORE_PERCENTILE``-th to the (100 - ``CORE_PERCENTILE``)-th percentile of each axis.

    A few junk rows far away (a scan's ``0 0 0`` returns) do not widen it, as they widen
    the bounding box.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64

    Returns
    -------
    lo, hi : (3,) numpy.ndarray of float64
    """
    lo, hi = np.percentile(points, [CORE_PERCENTILE, 100.0 - CORE_PERCENTILE], axis=0)
    return lo, hi


def duplicate_tolerance(points: np.ndarray, rel_tol: float = DUPLICATE_TOL) -> float:
    """``rel_tol`` times the diagonal of the box of ``points`` (same length unit), never 0.

    The box is :func:`core_box` (the bounding box where that is empty): one junk row far away (``0 0 0`` in a georeferenced scan, 5.4e6 m from a
    12 cm part sampled every 2 mm) widened the whole box's tolerance to 5.4 mm and merged
    3999 of the part's 4000 points. It is taken along the points' principal axes, so that
    the tolerance does not turn with the points: along x, y and z, coincident points were
    merged at 2.83e-9 in the input's frame and then refused as copies at 4.15e-9 in the
    rotated frame a method runs in (half of 9,940 rows copies shifted by 1e-9).
    """
    centred = points - points.mean(axis=0)
    _, axes = np.linalg.eigh(centred.T @ centred)
    along = centred @ axes
    lo, hi = core_box(along)
    diag = float(np.linalg.norm(hi - lo))
    if diag == 0.0:
        diag = float(np.linalg.norm(along.max(axis=0) - along.min(axis=0)))
    return max(rel_tol * diag, np.finfo(float).tiny)


def find_duplicate_points(points: np.ndarray, rel_tol: float = DUPLICATE_TOL, *, tol: float | None = None,
                          tree: cKDTree | None = None) -> np.ndarray:
    """Pairs of points closer than ``rel_tol`` times the box diagonal of :func:`duplicate_tolerance` (or ``tol``).

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    rel_tol : float
        Tolerance as a fraction of the box diagonal (:func:`duplicate_tolerance`).
    tol : float, optional
        Absolute tolerance (length unit of ``points``); replaces ``rel_tol`` when given.
    tree : scipy.spatial.cKDTree, optional
        A tree already built over ``points`` (saves rebuilding it).

    Returns
    -------
    (P, 2) numpy.ndarray of int64, each row ``i < j``.
    """
    if tol is None:
        tol = duplicate_tolerance(points, rel_tol)
    tree = cKDTree(points) if tree is None else tree
    return tree.query_pairs(max(tol, np.finfo(float).tiny), output_type="ndarray").astype(np.int64)


def require_unique_points(points: np.ndarray, name: str | None = None) -> None:
    """Raise if two points coincide (see :func:`find_duplicate_points`).

    Raises
    ------
    DuplicatePointsError
        With the number of pairs and the first pair's indices.
    """
    dup = find_duplicate_points(points)
    if dup.size:
        i, j = (int(v) for v in dup[0])
        prefix = f"{name}: " if name else ""
        raise DuplicatePointsError(
            f"{prefix}{len(dup)} pair(s) of duplicate points (first: {i} and {j}); "
            "merge them first (e.g. pymeshlab meshing_remove_duplicate_vertices) and retry."
        )


def require_no_collapsed_edges(points: np.ndarray, faces: np.ndarray, name: str | None = None) -> None:
    """Raise if a face edge joins two coincident vertices.

    Coincident vertices that no face joins are a cut seam (textured OBJ exports store seams
    so): the faces keep the two sides apart, and merging them would glue the cut. An edge
    between coincident vertices has zero length and makes its faces degenerate.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    faces : (M, 3) numpy.ndarray of int64, indices in ``[0, N)``
    name : str, optional
        Used in the error message.

    Raises
    ------
    DegenerateFacesError
        With the number of such edges and the first face and vertex pair.
    """
    dup = find_duplicate_points(points)
    if not dup.size:
        return
    n = np.int64(points.shape[0])
    pair_keys = dup[:, 0] * n + dup[:, 1]
    edges = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    edge_keys = edges.min(axis=1) * n + edges.max(axis=1)
    collapsed = np.isin(edge_keys, pair_keys)
    if collapsed.any():
        first = int(np.flatnonzero(collapsed)[0])
        i, j = (int(v) for v in np.sort(edges[first]))
        prefix = f"{name}: " if name else ""
        raise DegenerateFacesError(
            f"{prefix}{int(np.unique(edge_keys[collapsed]).size)} edge(s) join coincident vertices "
            f"(first: vertices {i} and {j} in face {first % len(faces)}); merge each such pair and drop the "
            "faces that collapse (e.g. pymeshlab meshing_merge_close_vertices, then meshing_remove_null_faces), "
            "and retry."
        )


def flat_faces(points: np.ndarray, faces: np.ndarray, rel_tol: float = DEGENERATE_AREA_TOL) -> np.ndarray:
    """(M,) bool: faces whose doubled area is at most ``rel_tol`` times the squared mean edge length.

    The rule :func:`validate_faces` refuses a mesh by (zero-area faces).
    """
    e1 = points[faces[:, 1]] - points[faces[:, 0]]
    e2 = points[faces[:, 2]] - points[faces[:, 0]]
    area2 = np.linalg.norm(np.cross(e1, e2), axis=1)
    scale = np.mean(np.linalg.norm(e1, axis=1)) ** 2 if len(faces) else 0.0
    return area2 <= rel_tol * max(scale, np.finfo(float).tiny)


def degenerate_faces(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(M,) bool: the faces :func:`validate_faces` refuses a mesh for (a repeated vertex, or zero area)."""
    repeated = (faces[:, 0] == faces[:, 1]) | (faces[:, 1] == faces[:, 2]) | (faces[:, 0] == faces[:, 2])
    return repeated | flat_faces(points, faces)


def counter_clockwise(xy: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """The faces, each with its corners counter-clockwise in the plane ``xy`` (a copy).

    Parameters
    ----------
    xy : (N, 2+) numpy.ndarray of float64
        Plane coordinates (the first two columns are used).
    faces : (M, 3) numpy.ndarray of int64

    Returns
    -------
    (M, 3) numpy.ndarray of int64
        Clockwise faces with their last two corners swapped; the others as they were.
    """
    a, b, c = (xy[faces[:, i], :2] for i in range(3))
    clockwise = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]) < 0
    out = np.array(faces, dtype=np.int64, copy=True)
    out[clockwise] = out[clockwise][:, [0, 2, 1]]
    return out


def circumradii(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(M,) float64: each face's circumradius in 3D, ``abc / (4 area)``; inf for a face without area."""
    a, b, c = points[faces[:, 0]], points[faces[:, 1]], points[faces[:, 2]]
    product = np.linalg.norm(b - c, axis=1) * np.linalg.norm(a - c, axis=1) * np.linalg.norm(a - b, axis=1)
    twice_area = np.linalg.norm(np.cross(b - a, c - a), axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(twice_area > 0, product / (2.0 * twice_area), np.inf)


def validate_faces(faces: Any, n_points: int, points: np.ndarray | None = None) -> np.ndarray:
    """Check and convert a triangle array.

    Parameters
    ----------
    faces : (M, 3) array_like of int
        Vertex indices per triangle, 0-based.
    n_points : int
        Number of vertices the indices refer to.
    points : (N, 3) numpy.ndarray of float64, optional
        When given, zero-area triangles are detected too.

    Returns
    -------
    (M, 3) numpy.ndarray of int64, C-contiguous.

    Raises
    ------
    InvalidInputError
        Wrong shape or dtype, indices out of range.
    DegenerateFacesError
        Repeated vertex in a face, or zero area.
    """
    arr = np.asarray(faces)
    if arr.size == 0:
        raise InvalidInputError("faces is empty; pass None for a point set without faces.")
    if arr.dtype.kind not in "iu" and not (arr.dtype.kind == "f" and np.all(np.mod(arr, 1) == 0)):
        raise InvalidInputError(f"faces must be an integer array, got dtype {arr.dtype}.")
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise InvalidInputError(f"faces must have shape (M, 3) (triangles only), got {arr.shape}; triangulate first.")
    # the range is read before the cast: uint64 above 2**63 and huge whole floats wrapped to negatives
    lo, hi = (x if isinstance(x, int) or abs(x) >= 2**64 else int(x) for x in (arr.min().item(), arr.max().item()))
    if lo < 0 or hi >= n_points:
        raise InvalidInputError(
            f"face indices must lie in [0, {n_points - 1}], found range [{lo}, {hi}]; indices are 0-based."
        )
    arr = np.ascontiguousarray(arr, dtype=np.int64)
    repeated = (arr[:, 0] == arr[:, 1]) | (arr[:, 1] == arr[:, 2]) | (arr[:, 0] == arr[:, 2])
    if repeated.any():
        raise repairable(DegenerateFacesError(
            f"{int(repeated.sum())} face(s) repeat a vertex (first: face {int(np.flatnonzero(repeated)[0])}); "
            "remove degenerate faces (e.g. pymeshlab meshing_remove_null_faces) and retry."
        ), DROP_DEGENERATE_ACTION)
    if points is not None:
        flat = flat_faces(points, arr)
        if flat.any():
            raise repairable(DegenerateFacesError(
                f"{int(flat.sum())} face(s) have zero area (first: face {int(np.flatnonzero(flat)[0])}, vertices "
                f"{', '.join(str(int(v)) for v in arr[np.flatnonzero(flat)[0]])}); remove null faces or collapse "
                "their short edges before flattening."
            ), DROP_DEGENERATE_ACTION)
    return arr


def validate_normals(normals: Any, n_points: int) -> np.ndarray:
    """Check normals and return them unit-length.

    Parameters
    ----------
    normals : (N, 3) array_like of float
    n_points : int

    Returns
    -------
    (N, 3) numpy.ndarray of float64 with unit rows.

    Raises
    ------
    InvalidInputError
        Wrong shape, non-finite or zero-length normals.
    """
    arr = np.asarray(normals, dtype=np.float64)
    if arr.shape != (n_points, 3):
        raise InvalidInputError(f"normals must have shape ({n_points}, 3) to match the points, got {arr.shape}.")
    length = np.linalg.norm(arr, axis=1)
    if not np.all(np.isfinite(length)) or np.any(length < 1e-12):
        raise InvalidInputError("normals contain NaN, infinite or zero-length rows; omit them to let parambench estimate normals.")
    return arr / length[:, None]


def _validate_loops(loops: Any) -> list | None:
    """Boundary loops as a list of int64 arrays (None stays None).

    Raises
    ------
    InvalidInputError
        A loop that is not a flat list of whole numbers (0.5 was silently truncated to 0).
    """
    if loops is None:
        return None
    out = []
    for i, loop in enumerate(loops):
        arr = np.asarray(loop)
        if arr.ndim != 1 or not (arr.dtype.kind in "iu" or (arr.dtype.kind == "f" and np.all(np.mod(arr, 1) == 0))):
            raise InvalidInputError(f"boundary loop {i} must be a flat list of whole point indices, got "
                                    f"{np.asarray(loop).tolist()[:5]!r}...")
        out.append(arr.astype(np.int64))
    return out


class _PointData:
    """What :class:`Surface` and :class:`MethodInput` share: the data fields' validation and views.

    Subclasses are frozen dataclasses with the fields ``points``, ``faces``, ``normals``,
    ``name`` and ``boundary_loops``.
    """

    def _validate_data(self) -> None:
        """Validate and convert the data fields in place (frozen: via ``object.__setattr__``).

        Raises
        ------
        InvalidInputError, TooFewPointsError, DegenerateFacesError
            See :func:`validate_points`, :func:`validate_faces`, :func:`validate_normals`
            and :func:`require_no_collapsed_edges`.
        """
        pts = validate_points(self.points)
        object.__setattr__(self, "points", pts)
        n = pts.shape[0]
        if self.faces is not None:
            faces = validate_faces(self.faces, n, pts)
            require_no_collapsed_edges(pts, faces, self.name)
            object.__setattr__(self, "faces", faces)
        if self.normals is not None:
            object.__setattr__(self, "normals", validate_normals(self.normals, n))

    @property
    def n_points(self) -> int:
        """Number of points N."""
        return int(self.points.shape[0])

    @property
    def has_faces(self) -> bool:
        """True when the surface carries a triangle mesh."""
        return self.faces is not None


@dataclass(frozen=True, eq=False)
class Surface(_PointData):
    """A sampled surface, with ground truth where it is known.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
        Sample positions.
    faces : (M, 3) numpy.ndarray of int64 or None
        Triangles over the points (the ground-truth mesh for generated data); None for a
        bare point set.
    normals : (N, 3) numpy.ndarray of float64 or None
        Unit normals, if known.
    name : str
        Dataset name (e.g. ``"saddle"``, ``"real/camelhead"``).
    params : dict
        Generator parameters (size, sampling, noise, ...), JSON-serialisable.
    seed : int or None
        Seed the generator used.
    boundary_mask : (N,) numpy.ndarray of bool or None
        True at points on the true boundary.
    boundary_loops : list of (L_i,) numpy.ndarray of int64, or None
        True boundary loops in order, outer loop first and counter-clockwise as seen from
        the normals' side, holes clockwise.
    exact_uv : (N, 2) numpy.ndarray of float64 or None
        The exact map to the plane (conformal or isometric) evaluated at the points.
    exact_map_kind : str or None
        ``"conformal"`` or ``"isometric"`` when ``exact_uv`` is given.

    Raises
    ------
    InvalidInputError, TooFewPointsError, DegenerateFacesError
        On invalid arrays (see :func:`validate_points`, :func:`validate_faces`).
    DegenerateFacesError
        Also when a face edge joins two coincident vertices (coincident vertices that no
        face joins are accepted: cut seams; so are coincident points of a point set).
    """

    points: np.ndarray
    faces: np.ndarray | None = None
    normals: np.ndarray | None = None
    name: str = "surface"
    params: dict = field(default_factory=dict)
    seed: int | None = None
    boundary_mask: np.ndarray | None = None
    boundary_loops: list | None = None
    exact_uv: np.ndarray | None = None
    exact_map_kind: str | None = None

    def __post_init__(self) -> None:
        self._validate_data()
        n = self.n_points
        if self.boundary_mask is not None:
            mask = np.asarray(self.boundary_mask, dtype=bool)
            if mask.shape != (n,):
                raise InvalidInputError(f"boundary_mask must have shape ({n},), got {mask.shape}.")
            object.__setattr__(self, "boundary_mask", mask)
        object.__setattr__(self, "boundary_loops", _validate_loops(self.boundary_loops))
        if self.exact_uv is not None:
            uv = np.asarray(self.exact_uv, dtype=np.float64)
            if uv.shape != (n, 2):
                raise InvalidInputError(f"exact_uv must have shape ({n}, 2), got {uv.shape}.")
            object.__setattr__(self, "exact_uv", uv)

    @property
    def diameter(self) -> float:
        """Bounding-box diagonal length, the unit for relative errors."""
        return float(np.linalg.norm(self.points.max(axis=0) - self.points.min(axis=0)))

    def points_only(self) -> "Surface":
        """The same surface with its faces dropped; ground truth is kept.

        For tests and evaluation helpers that need the ground truth beside a point set.
        What a method may be given is :meth:`method_input`.
        """
        return replace(self, faces=None)

    def method_input(self, needs_faces: bool, *, keep_normals: bool = False) -> "MethodInput":
        """What a method may see: what a user's file would hold, no ground truth.

        Parameters
        ----------
        needs_faces : bool
            True for a mesh method (points and faces); False for a point-set method
            (positions only).
        keep_normals : bool
            Keep ``normals`` for a point-set method. Only for normals that are data (read
            from a file, positions unchanged since); a generator's exact normals are ground
            truth and a user would have to estimate them.

        Returns
        -------
        MethodInput
            Same ``points`` and ``name``; ``faces`` only if ``needs_faces`` (None on a point
            set: the method then reports the missing faces itself); no boundary loops (a
            sweep adds the true ones only for cells that ask for them). A ``MethodInput``
            has no exact map, mask, generator parameters or seed.
        """
        normals = self.normals if (keep_normals and not needs_faces) else None
        return MethodInput(self.points, self.faces if needs_faces else None, normals, self.name)

    def as_method_input(self) -> "MethodInput":
        """What the caller gave, as a :class:`MethodInput`: points, faces, normals, loops, name.

        :meth:`parambench.methods.base.Method.__call__` uses this when called with a
        ``Surface``. The arrays are shared, not copied or validated again (this surface
        validated them); the exact map, mask, generator parameters and seed are left
        behind. Unlike :meth:`method_input` nothing the caller gave is withheld.

        Returns
        -------
        MethodInput
        """
        loops = None if self.boundary_loops is None else list(self.boundary_loops)
        return MethodInput._trusted(self.points, self.faces, self.normals, self.name, loops)

    def describe(self) -> dict:
        """A JSON-serialisable summary (name, sizes, parameters, seed)."""
        return {
            "name": self.name,
            "n_points": self.n_points,
            "n_faces": 0 if self.faces is None else int(self.faces.shape[0]),
            "params": dict(self.params),
            "seed": self.seed,
        }


@dataclass(frozen=True, eq=False)
class MethodInput(_PointData):
    """What a method is given: what a user's file would hold, and no ground truth.

    Validated like :class:`Surface` (same functions). There are no ``exact_uv``,
    ``exact_map_kind``, ``boundary_mask``, ``params`` or ``seed`` attributes: evaluation
    reads those from the :class:`Surface`.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
        Sample positions.
    faces : (M, 3) numpy.ndarray of int64 or None
        Triangles over the points; None for a point set.
    normals : (N, 3) numpy.ndarray of float64 or None
        Unit normals when they are data (e.g. stored in the user's file); None otherwise.
    name : str
        Dataset or file name, for messages.
    boundary_loops : list of (L_i,) numpy.ndarray of int64, or None
        Loops the caller supplies (outer first, counter-clockwise as seen from the normals'
        side, holes clockwise); None by default. A sweep fills them only for cells that ask
        for the true boundary (e.g. ``fbcp-pc boundary=given``).

    Raises
    ------
    InvalidInputError, TooFewPointsError, DegenerateFacesError
        As :class:`Surface`.
    """

    points: np.ndarray
    faces: np.ndarray | None = None
    normals: np.ndarray | None = None
    name: str = "surface"
    boundary_loops: list | None = None

    def __post_init__(self) -> None:
        self._validate_data()
        object.__setattr__(self, "boundary_loops", _validate_loops(self.boundary_loops))

    @classmethod
    def _trusted(cls, points: np.ndarray, faces: np.ndarray | None, normals: np.ndarray | None, name: str,
                 boundary_loops: list | None) -> "MethodInput":
        """A MethodInput over arrays a :class:`Surface` validated already (no copy, no re-validation)."""
        obj = object.__new__(cls)
        for key, value in (("points", points), ("faces", faces), ("normals", normals), ("name", name),
                           ("boundary_loops", boundary_loops)):
            object.__setattr__(obj, key, value)
        return obj
