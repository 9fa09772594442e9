"""From a shape, a size, a sampling and a seed to a :class:`~parambench.datasets_gen.surface.Surface`.

Steps (each seeded from its own stream of ``numpy.random.SeedSequence(seed)``):

0. Shapes whose geometry scales with the spacing (the narrow gaps of "slit" and "fold")
   are rebuilt for the nominal surface spacing of the requested count (:func:`nominal_spacing`).
1. Spacing h from the requested count (:func:`~parambench.datasets_gen.sampling.sizing.spacing_for_count`),
   measured in the parameter domain for lattice samplings of flat-ish shapes, on the surface
   for the area-uniform samplings (and for shapes whose lattice is area-uniform).
2. Boundary points along every boundary curve at spacing h (jittered along the curve unless
   the sampling is "grid").
3. Interior points:

   - ``grid``: the shape's lattice: a triangular lattice in the parameter domain, except on
     protrusions (rings of constant arc length on the fingers, uniform on the surface). The
     cap's domain is its geodesic polar chart (area factor 0.83-1), so its lattice is
     near-regular on the sphere; on the graphs (saddle: area factor up to 2.24, bump: 1.42)
     a parameter lattice is sparser in 3D where the surface is steep;
   - ``jittered``: the same, each point moved uniformly within a disk of radius 0.3 h;
   - ``random``: uniform by surface area (rejection sampling), exactly the requested count;
   - ``blue-noise``: dart throwing on the surface (Poisson disk, radius 0.59 h, measured in
     3D) over 3x as many area-uniform candidates, the boundary points fixed first; computed
     as a maximal independent set with array operations (:mod:`~parambench.datasets_gen.sampling.poisson_disk`);
   - ``graded``: the same with a local spacing h sigma(x) from a smooth seeded sizing field
     (:mod:`~parambench.datasets_gen.sampling.graded`, density varying 11x), candidates drawn with
     density ~ sigma^-2 and Poisson radius 0.59 h sigma; the boundary follows h sigma too.

   Shapes with a merged-scan strip (gnome-strip) add a second, rotated scan inside the strip.
4. Interior points crowding the boundary are removed (in the meshing chart).
5. Constrained Delaunay in the shape's meshing chart, the boundary chords as constraints and
   the holes removed; boundary loops checked against the planted curves.
6. A seeded shuffle of the point order (no method can rely on generation order), then the
   normal-direction noise.
"""

from __future__ import annotations

import numbers

import numpy as np

from .errors import InvalidInputError, TooFewPointsError, UnknownNameError
from .meshing import delaunay_in_chart, ordered_loops
from .sampling import SAMPLINGS
from .sampling.area_uniform import sample_by_area
from .sampling.boundary import curve_length, near_boundary, place_boundary
from .sampling.graded import graded_sizing, sample_by_density
from .sampling.poisson_disk import poisson_disk_select
from .sampling.sizing import spacing_for_count
from .surface import Surface

__all__ = ["build_surface", "add_normal_noise", "mean_edge_length", "check_noise", "nominal_spacing",
           "MIN_GENERATED_POINTS"]

#: Smallest size a generator accepts: below it the boundary alone would use most points.
MIN_GENERATED_POINTS = 100
#: Jitter of "jittered" lattices and of boundary points, as fractions of the spacing.
LATTICE_JITTER = 0.3
BOUNDARY_JITTER = 0.25
#: Blue noise: candidates per wanted point, and Poisson-disk radius / lattice spacing
#: (calibrated so that the count matches a lattice of the same h).
BLUE_NOISE_OVERSAMPLING = 3
BLUE_NOISE_RADIUS = 0.59
#: Shift of a merged second scan's lattice origin, as fractions of h (it is also rotated).
SECOND_SCAN_SHIFT = (0.37, 0.21)


def build_surface(shape, n_points: int, sampling: str, seed: int | None, noise: float) -> Surface:
    """Sample, mesh and package a procedural shape.

    Parameters
    ----------
    shape : parambench.datasets_gen.shapes.base.Shape
    n_points : int
        Requested number of points (the result is within a few percent).
    sampling : {"grid", "jittered", "random", "blue-noise", "graded"}
    seed : int or None
    noise : float
        Standard deviation of the displacement along the exact normal, as a fraction of
        the mean edge length of the ground-truth mesh.

    Returns
    -------
    Surface
        ``params`` holds the request and ``n_actual`` / ``spacing`` (mean edge length).

    Raises
    ------
    UnknownNameError
        Unknown sampling.
    TooFewPointsError
        ``n_points`` below :data:`MIN_GENERATED_POINTS`.
    InvalidInputError
        Negative or non-finite noise, a count that is not a whole number.
    """
    if sampling not in SAMPLINGS:
        raise UnknownNameError(f"unknown sampling {sampling!r}; valid samplings: {', '.join(SAMPLINGS)}.")
    n_points = _check_count(n_points)
    noise = check_noise(noise)
    # a sixth child stream leaves the first five (and so the older samplings) unchanged
    rngs = dict(zip(("boundary", "interior", "scan", "order", "noise", "sizing"),
                    (np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(6))))
    if shape.spacing_dependent:
        # twice: the domain (hence the spacing) changes slightly with the gap it was built for
        for _ in range(2):
            shape = shape.at_spacing(nominal_spacing(shape, n_points))

    x, labels, loop_sizes = _sample(shape, n_points, sampling, rngs)
    faces = _triangulate(shape, x, loop_sizes)
    used = np.zeros(len(x), dtype=bool)
    used[faces.ravel()] = True
    if not used.all():  # a point no triangle uses (none expected); drop it and renumber
        remap = np.cumsum(used) - 1
        x, labels, faces = x[used], labels[used], remap[faces]

    order = rngs["order"].permutation(len(x))
    inverse = np.empty_like(order)
    inverse[order] = np.arange(len(order))
    x, labels, faces = x[order], labels[order], inverse[faces]
    points, normals = shape.lift(x)
    loops = ordered_loops(faces, labels, shape.chart(x))
    spacing = mean_edge_length(points, faces)
    if noise > 0:
        points = add_normal_noise(points, normals, noise * spacing, rngs["noise"])
    exact = shape.exact_uv(x)
    mask = np.zeros(len(x), dtype=bool)
    mask[np.concatenate(loops)] = True
    params = {"n_points": n_points, "sampling": sampling, "noise": noise, **shape.options,
              "n_actual": int(len(x)), "spacing": spacing}
    return Surface(points=points, faces=faces, normals=normals, name=shape.name, params=params, seed=seed,
                   boundary_mask=mask, boundary_loops=loops, exact_uv=exact,
                   exact_map_kind=shape.exact_map_kind if exact is not None else None)


def nominal_spacing(shape, n_points: int) -> float:
    """Surface spacing of an area-uniform sampling of ``n_points`` on ``shape`` (3D units).

    The mean edge length of the "jittered", "random" and "blue-noise" samplings (within
    ~6 %), and the spacing a narrow gap is measured in, whatever the sampling.

    Parameters
    ----------
    shape : parambench.datasets_gen.shapes.base.Shape
    n_points : int
        Requested number of points.

    Returns
    -------
    float
    """
    return spacing_for_count(n_points / shape.count_factor(), shape.surface_area, curve_length(shape, "3d"))


def check_noise(noise) -> float:
    """``noise`` as a float, or InvalidInputError unless finite and non-negative."""
    try:
        value = float(noise)
    except (TypeError, ValueError):
        value = float("nan")
    if not np.isfinite(value) or value < 0:
        raise InvalidInputError(f"noise={noise!r} must be a finite, non-negative fraction of the mean spacing.")
    return value


def _check_count(n_points) -> int:
    integral = isinstance(n_points, numbers.Real) and not isinstance(n_points, bool) and \
        np.isfinite(float(n_points)) and float(n_points).is_integer()
    if not integral:
        raise InvalidInputError(f"n_points={n_points!r} must be a whole number of points.")
    if n_points < MIN_GENERATED_POINTS:
        raise TooFewPointsError(f"n_points={n_points!r}: ask for at least {MIN_GENERATED_POINTS} points.")
    return int(n_points)


def _sample(shape, n_points: int, sampling: str, rngs: dict) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """Parameter points (boundary curves first, in order), their curve labels (-1 inside), loop sizes."""
    sizing = graded_sizing(shape, rngs["sizing"]) if sampling == "graded" else None
    metric = "3d" if sampling in ("random", "blue-noise", "graded") or shape.lattice_metric == "3d" else "param"
    if sizing is not None:
        area = sizing.effective_area
    else:
        area = shape.surface_area if metric == "3d" else shape.domain.area
    h = spacing_for_count(n_points / shape.count_factor(), area, curve_length(shape, metric, sizing=sizing))
    if metric == "param":
        h = shape.snap_spacing(h)

    loops_x = place_boundary(shape, h, metric, jitter=0.0 if sampling == "grid" else BOUNDARY_JITTER,
                             rng=rngs["boundary"], sizing=sizing)
    loops_chart = [shape.chart(lp) for lp in loops_x]
    boundary_x = np.concatenate(loops_x)
    n_interior = max(1, round(n_points / shape.count_factor()) - len(boundary_x))

    interior = _scan(shape, sampling, h, n_interior, boundary_x, loops_chart, rngs["interior"], sizing=sizing)
    if hasattr(shape, "in_strip"):  # a merged-scan shape (gnome-strip)
        interior = _merge_second_scan(shape, sampling, h, metric, interior, n_interior, boundary_x,
                                      loops_chart, rngs["scan"], sizing)
    interior = interior[~near_boundary(shape.chart(interior), loops_chart)]

    x = np.concatenate([boundary_x, interior])
    labels = np.concatenate([np.full(len(lp), k) for k, lp in enumerate(loops_x)] + [np.full(len(interior), -1)])
    return x, labels, [len(lp) for lp in loops_x]


def _triangulate(shape, x: np.ndarray, loop_sizes: list[int]) -> np.ndarray:
    """Constrained Delaunay in the shape's chart; the leading points are the boundary loops in order."""
    starts = np.cumsum([0] + loop_sizes)
    segments = np.concatenate([np.column_stack([np.arange(a, b), np.roll(np.arange(a, b), -1)])
                               for a, b in zip(starts[:-1], starts[1:])])
    centers = np.array([hole.center for hole in shape.domain.holes], dtype=float).reshape(-1, 2)
    return delaunay_in_chart(shape.chart(x), segments, shape.chart(centers))


def _scan(shape, sampling: str, h: float, n_interior: int, boundary_x: np.ndarray, loops_chart: list,
          rng: np.random.Generator, *, angle: float = 0.0, offset=(0.0, 0.0), sizing=None) -> np.ndarray:
    """Interior parameter points of one scan (before the near-boundary removal)."""
    if sampling == "grid":
        return shape.lattice(h, angle=angle, offset=offset)
    if sampling == "jittered":
        return shape.lattice(h, angle=angle, offset=offset, jitter=LATTICE_JITTER, rng=rng)
    if sampling == "random":
        return _random_interior(shape, n_interior, loops_chart, rng)
    return _blue_noise_interior(shape, h, n_interior, boundary_x, rng, sizing)


def _random_interior(shape, n: int, loops_chart: list, rng: np.random.Generator) -> np.ndarray:
    """Exactly ``n`` area-uniform points that do not crowd the boundary."""
    out, got = [], 0
    while got < n:
        x = sample_by_area(shape, int(1.3 * (n - got)) + 32, rng)
        x = x[~near_boundary(shape.chart(x), loops_chart)]
        out.append(x)
        got += len(x)
    return np.concatenate(out)[:n]


def _blue_noise_interior(shape, h: float, n: int, boundary_x: np.ndarray, rng: np.random.Generator,
                         sizing=None) -> np.ndarray:
    """Poisson-disk points on the surface, boundary points fixed; about ``n`` of them.

    With a ``sizing`` the candidates have density ~ sigma^-2 and the radius is local (graded).
    """
    if sizing is None:
        candidates = sample_by_area(shape, BLUE_NOISE_OVERSAMPLING * n, rng)
    else:
        candidates = sample_by_density(shape, sizing, BLUE_NOISE_OVERSAMPLING * n, rng)
    x = np.concatenate([boundary_x, candidates])
    pts3 = shape.lift(x)[0]
    n_fixed = len(boundary_x)
    radius = BLUE_NOISE_RADIUS * h * (1.0 if sizing is None else sizing(x))
    keep = poisson_disk_select(pts3, radius, n_fixed)[n_fixed:]
    # One correction if the calibrated radius misses by more than 4 % (small or odd shapes).
    if abs(keep.sum() / max(n, 1) - 1.0) > 0.04:
        radius *= np.sqrt(keep.sum() / max(n, 1))
        keep = poisson_disk_select(pts3, radius, n_fixed)[n_fixed:]
    return candidates[keep]


def _merge_second_scan(shape, sampling: str, h: float, metric: str, first: np.ndarray, n_interior: int,
                       boundary_x: np.ndarray, loops_chart: list, rng: np.random.Generator,
                       sizing=None) -> np.ndarray:
    """Add a rotated second scan inside the shape's strip, dropping near-duplicates (at the local spacing)."""
    angle = np.radians(shape.options["strip_angle"])
    second = _scan(shape, sampling, h, n_interior, boundary_x, loops_chart, rng,
                   angle=angle, offset=(SECOND_SCAN_SHIFT[0] * h, SECOND_SCAN_SHIFT[1] * h), sizing=sizing)
    second = second[shape.in_strip(second)]
    merged = np.concatenate([first, second])
    coords = shape.lift(merged)[0] if metric == "3d" else merged
    radius = shape.options["min_spacing"] * h * (1.0 if sizing is None else sizing(merged))
    keep = poisson_disk_select(coords, radius, n_fixed=len(first))
    return merged[keep]


def mean_edge_length(points: np.ndarray, faces: np.ndarray, max_faces: int = 200_000) -> float:
    """Mean length of the faces' edges (each face's three edges; interior edges count twice).

    Parameters
    ----------
    points : (n, 3) numpy.ndarray of float64
    faces : (m, 3) numpy.ndarray of int64
    max_faces : int
        Larger meshes are measured on every k-th face (a deterministic subsample; the
        mean of 200k faces is exact to ~0.1 %).

    Returns
    -------
    float
    """
    faces = faces[:: max(1, len(faces) // max_faces)]
    total = 0.0
    for i, j in ((0, 1), (1, 2), (2, 0)):
        total += np.linalg.norm(points[faces[:, j]] - points[faces[:, i]], axis=1).sum()
    return float(total / (3 * len(faces)))


def add_normal_noise(points: np.ndarray, normals: np.ndarray, sigma: float, rng: np.random.Generator) -> np.ndarray:
    """Points displaced along their normals by Gaussian amounts of standard deviation ``sigma``.

    Parameters
    ----------
    points, normals : (n, 3) numpy.ndarray of float64
    sigma : float
    rng : numpy.random.Generator

    Returns
    -------
    (n, 3) numpy.ndarray of float64
    """
    return points + normals * (sigma * rng.standard_normal(len(points)))[:, None]
