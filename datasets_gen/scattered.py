"""Points scattered at random over a mesh's surface, as a scanner leaves them.

The generated samplings place points along their boundary curves and keep the interior
clear next to them; a scan does not: its points fall anywhere on the surface, none on the
rim, so the boundary is ragged at the sampling's own scale. This is where the point-set
front end and ``ocp`` failed on real data (the twentieth and twenty-first sessions'
measurements in ``bench/MEASUREMENTS.md``): :func:`scatter_on_mesh` makes such data from
any disk-like mesh, with the ground truth a benchmark needs.

The ground truth: a reference triangulation of the scattered points, the Delaunay
triangulation of libigl's conformal map of the mesh (``igl.spectra.lscm``) carried to the
points by their barycentric coordinates. That map is injective (checked), so the surface
is exactly its flat image: the Delaunay triangles outside it, which fill the convex hull
across the holes, are dropped; the slivers that close the ragged rim's notches along
its outermost points are peeled off from outside as an alpha shape would (circumradius
above ``PEEL_RADIUS_SPACINGS`` mean spacings); so are the triangles that would leave a
vertex with two fans, and the islands the drops cut off. Its boundary loops are the true loops, its faces the mesh
a mesh method (``scp-igl``) is run on for the yardstick. Normals are the mesh's vertex
normals interpolated at the points.
"""

from __future__ import annotations

import igl
import igl.spectra
import numpy as np
from scipy.spatial import Delaunay, cKDTree

from .build import MIN_GENERATED_POINTS
from .errors import InvalidInputError, NotADiskError, TooFewPointsError
from .mesh_loops import boundary_loops, one_fan_per_vertex
from .surface import Surface, circumradii, counter_clockwise

__all__ = ["PEEL_RADIUS_SPACINGS", "peel_rim", "scatter_on_mesh"]

#: Rim triangles whose circumradius exceeds this many mean spacings are peeled off the
#: reference triangulation (an alpha shape from outside). Not smaller: for area-uniform
#: random points (mean spacing s = 0.5 / sqrt(density)) a Delaunay triangle's circumradius
#: exceeds a s with probability (1 + pi a^2 / 4) exp(-pi a^2 / 4): 18 % at 2 spacings,
#: 0.7 % at 3, 5e-5 at 4. At 2 the peel ran on through the wide interior triangles it
#: exposed and cut notches 10-27 spacings deep into the surface (twenty-third session);
#: the rim slivers it is meant for are far wider than 4.
PEEL_RADIUS_SPACINGS = 4.0


def scatter_on_mesh(mesh: Surface, n_points: int, seed: int | None = 0) -> Surface:
    """``n_points`` area-uniform random points on ``mesh``'s triangles, with a reference triangulation.

    Parameters
    ----------
    mesh : Surface
        A connected mesh with boundary (faces required) whose libigl conformal map folds
        no triangle.
    n_points : int
        Number of points, at least 100.
    seed : int or None
        Seeds the choice of triangles and of positions in them.

    Returns
    -------
    Surface
        ``points`` (n_actual, 3) float64; ``faces`` the reference triangulation (int64,
        counter-clockwise seen from the normals); ``normals`` interpolated unit normals;
        ``boundary_loops`` / ``boundary_mask`` of the reference triangulation (outer loop
        first). ``params``: ``sampling`` "scattered", ``n_points``, ``n_actual``,
        ``source_points`` and ``source_faces`` (the mesh's sizes), ``spacing`` (mean
        nearest-neighbour distance of the drawn points), ``n_dropped_faces`` (Delaunay
        triangles outside the mesh's image, peeled at the rim, or dropped to keep the
        triangulation one manifold piece), ``n_left_out`` (drawn points those drops left
        in no triangle, not returned: ``n_actual`` = ``n_points`` - ``n_left_out``; 0 on
        the shipped one-rim meshes at 2k-20k points). No ``exact_uv``: the carried map is
        a yardstick, not an exact map.

    Raises
    ------
    InvalidInputError
        No faces, or a reference map that folds (the mesh has no faithful conformal map
        to carry).
    TooFewPointsError
        Fewer than 100 points asked for.
    NotADiskError
        The mesh has no boundary.
    """
    if mesh.faces is None:
        raise InvalidInputError(f"{mesh.name}: scattering points needs a mesh; this surface has no faces.")
    if n_points < MIN_GENERATED_POINTS:
        raise TooFewPointsError(f"scattering needs at least {MIN_GENERATED_POINTS} points (got {n_points}).")
    v, f = mesh.points, mesh.faces
    mesh_loops = boundary_loops(f)
    if not mesh_loops:
        raise NotADiskError(f"{mesh.name} has no boundary: a closed mesh has no flattening to carry; "
                            "cut it open first.")
    mesh_uv = _mesh_map(mesh)
    rng = np.random.default_rng(seed)
    face, bary = _area_uniform(v, f, n_points, rng)
    corners = f[face]
    points = np.einsum("ni,nij->nj", bary, v[corners])
    ref_uv = np.einsum("ni,nij->nj", bary, mesh_uv[corners])
    spacing = float(cKDTree(points).query(points, k=2)[0][:, 1].mean())
    faces, n_dropped = _reference_faces(points, ref_uv, mesh_uv, mesh_loops, spacing)
    # A point no reference triangle keeps (the peel never orphans one; a pinch or an island
    # dropped could) is left out: a mesh method could not take it.
    kept = np.unique(faces)
    new_index = np.full(n_points, -1, dtype=np.int64)
    new_index[kept] = np.arange(kept.size)
    faces = new_index[faces]
    loops = boundary_loops(faces)
    mask = np.zeros(kept.size, dtype=bool)
    mask[np.concatenate(loops)] = True
    params = {"n_points": int(n_points), "sampling": "scattered", "noise": 0.0, "n_actual": int(kept.size),
              "source": mesh.name, "source_points": int(mesh.n_points), "source_faces": int(f.shape[0]),
              "spacing": spacing, "n_dropped_faces": int(n_dropped), "n_left_out": int(n_points - kept.size)}
    normals = _interpolated_normals(mesh, corners, bary)
    return Surface(points=points[kept], faces=faces, normals=normals[kept], name=mesh.name,
                   params=params, seed=seed, boundary_mask=mask, boundary_loops=loops)


def _mesh_map(mesh: Surface) -> np.ndarray:
    """libigl's conformal map of the mesh, counter-clockwise; refused if it folds.

    The mesh is centred and scaled to a unit bounding-box diagonal first: libigl's
    spectral solver failed on matplotlib's topobathy DEM in metres (2,650 vertices, 260 km
    across; at unit size 0.04 s) and took 146 s to fail on its jacksboro DEM (34,744
    vertices, 2.8 s at unit size). A conformal map does not care.
    """
    points = mesh.points - mesh.points.mean(axis=0)
    points = points / max(float(np.linalg.norm(np.ptp(points, axis=0))), np.finfo(float).tiny)
    uv = np.asarray(igl.spectra.lscm(points, mesh.faces), dtype=np.float64)
    e1 = uv[mesh.faces[:, 1]] - uv[mesh.faces[:, 0]]
    e2 = uv[mesh.faces[:, 2]] - uv[mesh.faces[:, 0]]
    signed = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    if np.count_nonzero(signed < 0) > np.count_nonzero(signed > 0):
        uv[:, 1] *= -1.0
        signed = -signed
    n_folded = int(np.count_nonzero(signed <= 0))
    if n_folded:
        raise InvalidInputError(f"{mesh.name}: libigl's conformal map folds {n_folded} of {signed.size} triangles, "
                                "so it cannot carry a reference triangulation to scattered points; "
                                "use a mesh with one boundary loop, or a cut that opens it to a disk.")
    return uv


def _area_uniform(v: np.ndarray, f: np.ndarray, n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Triangles chosen by area and uniform barycentric coordinates in them."""
    area = 0.5 * np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1)
    face = rng.choice(f.shape[0], n, p=area / area.sum())
    r1, r2 = rng.random(n), rng.random(n)
    s = np.sqrt(r1)  # uniform on the triangle, not crowded at a corner
    return face, np.column_stack([1.0 - s, s * (1.0 - r2), s * r2])


def _reference_faces(points: np.ndarray, ref_uv: np.ndarray, mesh_uv: np.ndarray,
                     mesh_loops: list[np.ndarray], spacing: float) -> tuple[np.ndarray, int]:
    """Delaunay in the carried map, less the triangles outside the mesh's image, pinches and islands.

    Returns the faces (counter-clockwise in ``ref_uv``) and how many were dropped.
    """
    faces = counter_clockwise(ref_uv, np.asarray(Delaunay(ref_uv).simplices, dtype=np.int64))
    n_all = faces.shape[0]
    faces = faces[_inside_image(ref_uv, faces, mesh_uv, mesh_loops)]
    faces = peel_rim(points, faces, PEEL_RADIUS_SPACINGS * spacing)
    try:
        faces = one_fan_per_vertex(faces, points.shape[0])
    except InvalidInputError as exc:
        raise InvalidInputError("the scattered points' reference triangulation keeps pinched vertices; "
                                "use more points or another seed.") from exc
    faces = _largest_piece(faces)
    return faces, n_all - faces.shape[0]


def peel_rim(points: np.ndarray, faces: np.ndarray, radius: float) -> np.ndarray:
    """Rim triangles with a 3D circumradius above ``radius`` peeled off, from outside inwards.

    The Delaunay triangulation closes the rim's notches with slivers along the outermost
    points; the peel opens them as an alpha shape would (an empty disk of that radius
    reaching in from outside). A triangle goes only when it has one rim edge and its third
    corner is not on the rim yet: the triangulation stays a disk, no point is left out
    and no vertex gets two fans (every drawn point is kept, so the sampling near the rim
    stays uniform).

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    faces : (M, 3) numpy.ndarray of int64
        An edge-manifold triangulation; its boundary edges are where the peel starts.
    radius : float
        Circumradius (length units) above which a rim triangle is peeled.

    Returns
    -------
    (K, 3) numpy.ndarray of int64
        The faces kept, in their order.
    """
    too_wide = circumradii(points, faces) > radius
    edge_faces: dict[tuple[int, int], set[int]] = {}
    for face, (i, j, k) in enumerate(faces.tolist()):
        for edge in ((i, j), (j, k), (k, i)):
            edge_faces.setdefault((min(edge), max(edge)), set()).add(face)
    rim_edges_at = np.zeros(points.shape[0], dtype=np.int64)
    for (i, j), owners in edge_faces.items():
        if len(owners) == 1:
            rim_edges_at[[i, j]] += 1
    kept = np.ones(faces.shape[0], dtype=bool)
    queue = np.flatnonzero(too_wide & (rim_edges_at[faces] > 0).any(axis=1)).tolist()
    while queue:
        face = queue.pop()
        if not kept[face]:
            continue
        i, j, k = faces[face].tolist()
        edges = [(min(e), max(e)) for e in ((i, j), (j, k), (k, i))]
        rim = [e for e in edges if len(edge_faces[e]) == 1]
        if len(rim) != 1:
            continue
        third = ({i, j, k} - set(rim[0])).pop()
        if rim_edges_at[third] > 0:  # peeling would pinch the rim at its third corner
            continue
        kept[face] = False
        rim_edges_at[list(rim[0])] -= 1
        for edge in edges:
            edge_faces[edge].discard(face)
            if edge != rim[0]:
                rim_edges_at[list(edge)] += 1
                queue.extend(f for f in edge_faces[edge] if too_wide[f])
    return faces[kept]


def _inside_image(ref_uv: np.ndarray, faces: np.ndarray, mesh_uv: np.ndarray, mesh_loops: list[np.ndarray]) -> np.ndarray:
    """Triangles whose centroid and edge midpoints lie in the mesh's flat image.

    The Delaunay triangulation fills the convex hull of the points; the mesh's map is
    injective, so the surface is exactly its image: inside the outer loop and outside
    every hole. Testing the midpoints too drops the triangles that span a notch of the
    rim with their centroid still inside.
    """
    from matplotlib.path import Path

    corners = ref_uv[faces]
    probes = np.concatenate([corners.mean(axis=1), 0.5 * (corners + corners[:, [1, 2, 0]]).reshape(-1, 2)])
    inside = Path(mesh_uv[mesh_loops[0]]).contains_points(probes)
    for hole in mesh_loops[1:]:
        inside &= ~Path(mesh_uv[hole]).contains_points(probes)
    m = faces.shape[0]
    return inside[:m] & inside[m:].reshape(m, 3).all(axis=1)


def _largest_piece(faces: np.ndarray) -> np.ndarray:
    """The faces of the largest edge-connected piece (islands a dropped triangle cut off go)."""
    pieces = np.asarray(igl.facet_components(faces)[1], dtype=np.int64)
    return faces[pieces == np.bincount(pieces).argmax()]


def _interpolated_normals(mesh: Surface, corners: np.ndarray, bary: np.ndarray) -> np.ndarray:
    """The mesh's vertex normals at the points, barycentric, unit length."""
    normals = mesh.normals
    if normals is None:
        normals = igl.per_vertex_normals(mesh.points, mesh.faces, igl.PER_VERTEX_NORMALS_WEIGHTING_TYPE_AREA)
    out = np.einsum("ni,nij->nj", bary, np.asarray(normals, dtype=np.float64)[corners])
    return out / np.linalg.norm(out, axis=1, keepdims=True)
