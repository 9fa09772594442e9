"""DEM tangent coordinates against exact log maps, and the geodesic-ball definition."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.sparse.csgraph import dijkstra

from parambench.datasets_gen.errors import InvalidInputError
from parambench.methods.pointset.dem import dem_balls
from parambench.methods.pointset.neighbourhoods import knn_graph, symmetric_adjacency
from parambench.methods.pointset.normals import orient_normals, pca_normals, smooth_normals, tangent_frames


def _setup(points):
    graph = knn_graph(points, 8)
    adj = symmetric_adjacency(graph)
    normals = orient_normals(points, pca_normals(points, graph.indices), graph.indices)
    return graph, adj, normals


def _balls(patch, *, dem="upwind", smooth=True, paper=False):
    graph, adj, normals = _setup(patch.points)
    if smooth:
        normals = smooth_normals(patch.points, normals, graph.indices, graph.distances, graph.mean_spacing,
                                 method="average" if paper else "linear")
    kw = dict(projection="length", front_weight=False) if paper else {}
    return dem_balls(patch.points, normals, adj, graph.mean_spacing, dem=dem, **kw)


def log_map_error(patch, balls, n_centres=150, seed=0):
    """Mean over centres of RMS(T_s p - log_s p) / ball radius, after the best proper
    rotation of the tangent frame (the DEM frame at s is arbitrary up to rotation)."""
    rng = np.random.default_rng(seed)
    errs = []
    for c in rng.choice(len(patch.points), n_centres, replace=False):
        members = balls.indices[c][balls.indices[c] >= 0]
        exact3 = patch.log_map(c, members)
        n = patch.normals[c]
        a1 = np.cross(n, [0.3, 0.1, 0.9])
        a1 /= np.linalg.norm(a1)
        a2 = np.cross(n, a1)
        exact = np.c_[exact3 @ a1, exact3 @ a2]
        ours = balls.coords[c][: members.size]
        u, _, vt = np.linalg.svd(ours.T @ exact)
        rot = u @ np.diag([1.0, np.sign(np.linalg.det(u @ vt))]) @ vt
        rms = np.sqrt(np.mean(np.sum((ours @ rot - exact) ** 2, axis=1)))
        errs.append(rms / np.linalg.norm(exact, axis=1).max())
    return float(np.mean(errs))


@pytest.mark.parametrize("sampling", ["grid", "jittered", "random"])
@pytest.mark.parametrize("dem", ["upwind", "plain", "projected"])
def test_plane_is_exact_in_the_centre_frame(make_height_patch, sampling, dem):
    patch = make_height_patch("plane", 40, sampling)
    graph, adj, normals = _setup(patch.points)
    balls = dem_balls(patch.points, normals, adj, graph.mean_spacing, dem=dem)
    e1, e2 = tangent_frames(normals)
    safe = np.where(balls.mask, balls.indices, 0)
    d = patch.points[safe] - patch.points[:, None, :]
    expected = np.stack([np.einsum("nbi,ni->nb", d, e1), np.einsum("nbi,ni->nb", d, e2)], axis=-1)
    err = np.abs(balls.coords - expected)[balls.mask].max()
    assert err < 1e-12 * 2.0  # the plane spans [-1, 1]^2: absolute ~ relative


@pytest.mark.parametrize("sampling", ["grid", "jittered", "random"])
def test_ball_is_the_k_eps_ball_of_dijkstra_distances(make_cap, sampling):
    patch = make_cap(1.0, 1.0, 30, sampling)
    graph, adj, normals = _setup(patch.points)
    balls = dem_balls(patch.points, normals, adj, graph.mean_spacing, ball_k=6, ball_eps_factor=2.5)
    radius = 2.5 * graph.mean_spacing
    centres = np.arange(0, len(patch.points), 37)
    ref = dijkstra(adj, directed=False, indices=centres)
    for row, c in enumerate(centres):
        members = balls.indices[c][balls.indices[c] >= 0]
        d = ref[row]
        # Graph distances from the kernel's own heap equal scipy's Dijkstra.
        np.testing.assert_allclose(balls.graph_dist[c][: members.size], d[members], rtol=1e-12)
        within = set(np.flatnonzero((d <= radius) & (np.arange(d.size) != c)).tolist())
        if len(within) >= 6:
            assert set(members.tolist()) == within
        else:  # fewer than K inside eps: exactly the K nearest
            assert members.size == 6
            assert np.all(d[members] <= np.sort(d[np.arange(d.size) != c])[5] + 1e-15)
    assert np.all(balls.sizes >= 6)
    steps = np.diff(np.where(balls.mask, balls.graph_dist, 1e300), axis=1)[balls.mask[:, 1:]]
    assert np.all(steps >= 0)  # members are stored nearest first
    assert np.all(balls.indices[~balls.mask] == -1) and np.all(balls.coords[~balls.mask] == 0)


def test_ball_cap_truncates_and_counts(make_height_patch):
    patch = make_height_patch("plane", 30, "grid")
    graph, adj, normals = _setup(patch.points)
    full = dem_balls(patch.points, normals, adj, graph.mean_spacing)
    balls = dem_balls(patch.points, normals, adj, graph.mean_spacing, max_ball=10)
    assert balls.indices.shape[1] == 10
    assert balls.n_truncated == int((full.sizes > 10).sum()) > 0
    # Truncation keeps the nearest members, in the same order.
    np.testing.assert_array_equal(balls.indices, full.indices[:, :10])


def test_bad_options_raise(make_height_patch):
    patch = make_height_patch("plane", 10, "grid")
    graph, adj, normals = _setup(patch.points)
    with pytest.raises(InvalidInputError, match="dem must be"):
        dem_balls(patch.points, normals, adj, graph.mean_spacing, dem="exact")
    with pytest.raises(InvalidInputError, match="projection"):
        dem_balls(patch.points, normals, adj, graph.mean_spacing, projection="ortho")
    with pytest.raises(InvalidInputError, match="ball_k"):
        dem_balls(patch.points, normals, adj, graph.mean_spacing, ball_k=0)


# Measured (mean relative RMS error, 150 centres): clean cylinder ~4e-5, clean caps
# ~1.5e-4 to 2e-3 (coarse), noise 0.05 h ~5e-4 to 3e-3. Bounds leave ~3x headroom.
CASES = [
    ("cylinder", "grid", 0.0, 2e-4),
    ("cylinder", "jittered", 0.0, 2e-4),
    ("cylinder", "jittered", 0.05, 2e-3),
    ("cap", "grid", 0.0, 6e-4),
    ("cap", "jittered", 0.0, 8e-4),
    ("cap", "jittered", 0.05, 3e-3),
    ("coarse cap", "jittered", 0.0, 6e-3),
    ("coarse cap", "random", 0.05, 1.2e-2),
]


def _patch(make_cylinder, make_cap, shape, sampling, noise, seed=0):
    if shape == "cylinder":
        return make_cylinder(1.0, 40, sampling, seed=seed, noise=noise)
    if shape == "cap":
        return make_cap(1.0, 1.0, 40, sampling, seed=seed, noise=noise)
    return make_cap(1.0, 1.4, 25, sampling, seed=seed, noise=noise)  # ball radius ~ 0.35 R


@pytest.mark.parametrize("shape,sampling,noise,bound", CASES)
def test_dem_matches_exact_log_map(make_cylinder, make_cap, shape, sampling, noise, bound):
    patch = _patch(make_cylinder, make_cap, shape, sampling, noise)
    err = log_map_error(patch, _balls(patch))
    assert err < bound


COMPARE = [(shape, sampling, noise) for shape in ("cylinder", "cap", "coarse cap")
           for sampling, noise in (("grid", 0.0), ("jittered", 0.0), ("random", 0.0), ("jittered", 0.05),
                                   ("grid", 0.1), ("random", 0.05))]


@pytest.mark.parametrize("shape,sampling,noise", COMPARE)
def test_upwind_with_smoothing_at_least_as_accurate_as_plain_dem(make_cylinder, make_cap, shape, sampling, noise):
    """Upwind average + normal smoothing (defaults) vs the plain DEM of Eq. 8.

    Against the paper's plain DEM (length-preserving projection, raw normals) ours is
    never worse; against the plain DEM with our midpoint projection, it is within 5% on
    clean regular grids (where smoothing slightly perturbs already exact PCA normals:
    measured +3% on the grid cylinder) and 10-50% better with jitter, irregularity or noise.
    """
    patch = _patch(make_cylinder, make_cap, shape, sampling, noise)
    ours = log_map_error(patch, _balls(patch, dem="upwind", smooth=True))
    paper_plain = log_map_error(patch, _balls(patch, dem="plain", smooth=False, paper=True))
    plain = log_map_error(patch, _balls(patch, dem="plain", smooth=False))
    assert ours <= paper_plain
    assert ours <= 1.05 * plain
    if noise > 0 or sampling != "grid":
        assert ours <= plain


@pytest.mark.parametrize("sampling", ["jittered", "random"])
def test_robust_variant_beats_paper_variant_under_noise(make_cap, sampling):
    patch = make_cap(1.0, 1.0, 40, sampling, noise=0.05)
    robust = log_map_error(patch, _balls(patch))
    paper = log_map_error(patch, _balls(patch, paper=True))
    assert robust < 0.6 * paper


def test_subset_of_centres_matches_full_run(make_cap):
    patch = make_cap(1.0, 1.0, 30, "jittered")
    graph, adj, normals = _setup(patch.points)
    full = dem_balls(patch.points, normals, adj, graph.mean_spacing)
    centres = np.array([5, 300, 5, 17])  # repeats are fine
    sub = dem_balls(patch.points, normals, adj, graph.mean_spacing, centres=centres)
    width = sub.indices.shape[1]
    np.testing.assert_array_equal(sub.indices, full.indices[centres, :width])
    np.testing.assert_array_equal(sub.coords, full.coords[centres, :width])
    with pytest.raises(InvalidInputError, match="centres"):
        dem_balls(patch.points, normals, adj, graph.mean_spacing, centres=[len(patch.points)])


def test_projected_keeps_the_balls_and_drops_normal_noise(make_height_patch):
    """Noise along the exact normal of a plane: the projected offsets are the exact in-plane
    ones, while the DEM's fronts turn the noise into tangential length."""
    patch = make_height_patch("plane", 40, "random")
    n = len(patch.points)
    spacing = knn_graph(patch.points, 8).mean_spacing
    noisy = patch.points.copy()
    noisy[:, 2] += np.random.default_rng(1).normal(scale=0.5 * spacing, size=n)
    graph = knn_graph(noisy, 8)
    adj = symmetric_adjacency(graph)
    normals = np.tile([0.0, 0.0, 1.0], (n, 1))
    balls = {kind: dem_balls(noisy, normals, adj, graph.mean_spacing, dem=kind)
             for kind in ("plain", "upwind", "projected")}
    proj = balls["projected"]
    np.testing.assert_array_equal(proj.indices, balls["plain"].indices)
    np.testing.assert_array_equal(proj.graph_dist, balls["plain"].graph_dist)
    safe = np.where(proj.mask, proj.indices, 0)
    in_plane = np.linalg.norm((noisy[safe] - noisy[:, None, :])[..., :2], axis=2)
    assert np.abs(np.linalg.norm(proj.coords, axis=2) - in_plane)[proj.mask].max() < 1e-12
    assert np.all(proj.coords[~proj.mask] == 0.0)
    dem_err = np.abs(np.linalg.norm(balls["upwind"].coords, axis=2) - in_plane)[proj.mask]
    assert dem_err.max() > 0.1 * spacing


def test_projected_is_close_to_the_log_map_on_a_cap(make_cap):
    """Clean and curved (unit sphere): the projection differs from the log map at third
    order in the radius, a few tenths of a percent of the ball radius here, while the DEM
    is several times closer (0.05 % against 0.3 % measured): why ``dem="auto"`` keeps the
    DEM on clean points."""
    patch = make_cap(1.0, 1.0, 30, "jittered")
    upwind = log_map_error(patch, _balls(patch, dem="upwind"))
    projected = log_map_error(patch, _balls(patch, dem="projected"))
    assert projected < 0.005
    assert upwind < projected
