"""A point-set map checks itself: uv triangulation with loops, flips, degenerates, turning, coverage."""

from __future__ import annotations

import json

import numpy as np
import pytest
from matplotlib.path import Path
from scipy.spatial import cKDTree

from parambench.methods.pointset.selfcheck import (MAX_COHERENT_BELTRAMI, check_pointset_map, loop_coverage,
                                                   pointset_faces)
from parambench.methods.pointset.selfcheck_advice import suggest_fix
from parambench.datasets_gen.errors import InvalidInputError
from parambench.methods.pointset.uv_triangulation import delaunay_faces, triangulate_uv


def _ring(n):
    """Indices of the boundary of an n x n grid (row-major), counter-clockwise."""
    idx = np.arange(n * n).reshape(n, n)
    return np.r_[idx[0, :-1], idx[:-1, -1], idx[-1, :0:-1], idx[:0:-1, 0]]


def _area(uv, faces):
    d1, d2 = uv[faces[:, 1]] - uv[faces[:, 0]], uv[faces[:, 2]] - uv[faces[:, 0]]
    return 0.5 * (d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0])


def _grid_with_hole(n=21, hole=5.0):
    """A flat n x n grid of spacing 1 without the points within ``hole`` of the centre."""
    x, y = np.meshgrid(np.arange(n, dtype=float), np.arange(n, dtype=float))
    pts = np.c_[x.ravel(), y.ravel(), np.zeros(n * n)]
    c = (n - 1) / 2
    keep = np.hypot(pts[:, 0] - c, pts[:, 1] - c) > hole
    old_to_new = np.cumsum(keep) - 1
    outer = old_to_new[_ring(n)]
    pts = pts[keep]
    rim_mask = np.hypot(pts[:, 0] - c, pts[:, 1] - c) <= hole + 1.5
    rim = np.flatnonzero(rim_mask)
    # The hole loop clockwise (holes turn -1 seen from the normals' side).
    rim = rim[np.argsort(-np.arctan2(pts[rim, 1] - c, pts[rim, 0] - c))]
    return pts, outer, rim


def test_cdt_of_a_square_annulus_keeps_the_hole_empty():
    # 5 x 5 grid without its centre: outer ring of 16 points, hole ring of 8 around the centre.
    idx = np.arange(25).reshape(5, 5)
    x, y = np.meshgrid(np.arange(5.0), np.arange(5.0))
    uv_full = np.c_[x.ravel(), y.ravel()]
    keep = np.arange(25) != 12
    new = np.cumsum(keep) - 1
    uv = uv_full[keep]
    outer = new[_ring(5)]
    hole = new[np.r_[idx[1, 1:3], idx[1:3, 3], idx[3, 3:1:-1], idx[3:1:-1, 1]]][::-1]
    tri = triangulate_uv(uv, [outer, hole])
    assert tri.kind == "cdt"
    # Every vertex is a boundary vertex: T = 2n - b - 2 + 2h = 48 - 24 - 2 + 2 = 24, area 16 - 4.
    assert len(tri.faces) == 24
    assert np.all(_area(uv, tri.faces) > 0)
    assert _area(uv, tri.faces).sum() == pytest.approx(12.0)
    centroids = uv[tri.faces].mean(axis=1)
    assert not Path(uv[hole]).contains_points(centroids).any()


def test_self_intersecting_boundary_falls_back_to_delaunay():
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0.2]], dtype=float)
    bow_tie = [np.array([0, 2, 1, 3])]  # crossing segments: Triangle would add a vertex
    tri = triangulate_uv(square, bow_tie)
    assert tri.kind == "delaunay-fallback"
    assert tri.faces.max() < len(square)


def _brute_winding(query, polygon):
    """Crossing-rule winding number, one query x every edge: the reference."""
    a, b = polygon, np.roll(polygon, -1, axis=0)
    qx, qy = query[:, :1], query[:, 1:]
    cross = (b[:, 0] - a[:, 0]) * (qy - a[:, 1]) - (b[:, 1] - a[:, 1]) * (qx - a[:, 0])
    up = (a[:, 1] <= qy) & (b[:, 1] > qy) & (cross > 0)
    down = (a[:, 1] > qy) & (b[:, 1] <= qy) & (cross < 0)
    return up.sum(axis=1) - down.sum(axis=1)


def test_banded_winding_matches_every_edge_against_every_query():
    from parambench.methods.pointset.uv_triangulation import _edges_winding, loop_winding_numbers

    def _winding(q, poly):
        return loop_winding_numbers(q, poly, [np.arange(len(poly))])

    rng = np.random.default_rng(0)
    # A loop wound twice (winding 2 inside the small circle) and random self-crossing polygons.
    t = np.linspace(0, 4 * np.pi, 80, endpoint=False)
    polygons = [np.c_[np.cos(t), np.sin(t)] * (1 + 0.2 * (t > 2 * np.pi))[:, None]]
    polygons += [rng.standard_normal((int(rng.integers(3, 150)), 2)) for _ in range(10)]
    for poly in polygons:
        q = rng.standard_normal((3000, 2))
        q[:40] = poly[rng.integers(0, len(poly), 40)]  # on vertices
        q[40:80, 1] = poly[rng.integers(0, len(poly), 40), 1]  # level with vertices
        np.testing.assert_array_equal(_winding(q, poly), _brute_winding(q, poly))
    assert _winding(np.zeros((1, 2)), polygons[0])[0] == 2
    # Several polygons' edges at once wind as the sum of each.
    a = np.concatenate(polygons[1:4])
    b = np.concatenate([np.roll(p, -1, axis=0) for p in polygons[1:4]])
    np.testing.assert_array_equal(_edges_winding(q, a, b), sum(_brute_winding(q, p) for p in polygons[1:4]))


def test_cdt_regions_classify_like_every_centroid():
    """Flooding Triangle's neighbours without crossing a loop gives each face the class its
    own centroid has (the grid with a round hole, and the same map sheared)."""
    from parambench.methods.pointset.uv_triangulation import _inside

    pts, outer, rim = _grid_with_hole(n=31, hole=6.0)
    for uv in (pts[:, :2], pts[:, :2] @ np.array([[1.0, 0.3], [0.0, 1.0]])):
        tri = triangulate_uv(uv, [outer, rim])
        assert tri.kind == "cdt" and tri.n_removed > 0
        assert _inside(uv[tri.faces].mean(axis=1), uv, [outer, rim]).all()
        assert _area(uv, tri.faces).sum() == pytest.approx(_area(uv, triangulate_uv(uv).faces).sum()
                                                           - abs(_polygon_area(uv[rim])), rel=1e-9)


def _polygon_area(p):
    return 0.5 * np.sum(p[:, 0] * np.roll(p[:, 1], -1) - np.roll(p[:, 0], -1) * p[:, 1])


def test_identity_and_mirror_of_a_flat_patch_pass():
    pts, outer, rim = _grid_with_hole()
    normals = np.tile([0.0, 0.0, 1.0], (len(pts), 1))
    check = check_pointset_map(pts, pts[:, :2], normals, [outer, rim])
    assert check["passed"] and check["reason"] == "ok" and check["failed"] == []
    assert check["n_flipped"] == 0 and check["n_degenerate"] == 0 and not check["mirrored"]
    assert check["turning_numbers"] == [1.0, -1.0]
    json.dumps(check)  # JSON-serialisable
    mirror = check_pointset_map(pts, pts[:, :2] * [-1.0, 1.0], normals, [outer, rim])
    assert mirror["passed"] and mirror["mirrored"] and mirror["turning_numbers"] == [-1.0, 1.0]


def _open_cylinder(n_round=60, n_up=31, height=3.0):
    """An open cylinder (radius 1, outward normals), its rims as loops (the surface on their left), and
    its exact conformal map exp(h - i theta), which keeps the orientation."""
    t, h = np.meshgrid(np.linspace(0, 2 * np.pi, n_round, endpoint=False), np.linspace(0.0, height, n_up))
    pts = np.c_[np.cos(t).ravel(), np.sin(t).ravel(), h.ravel()]
    w = np.exp(h.ravel() - 1j * t.ravel())
    bottom, top = np.arange(n_round), np.arange(n_round)[::-1] + n_round * (n_up - 1)
    normals = np.c_[pts[:, :2], np.zeros(len(pts))]
    return pts, normals, np.c_[w.real, w.imag], bottom, top


def test_either_rim_of_an_open_cylinder_may_map_outside():
    """Before: a correct map with the detected outer loop inside was refused as "loop 0 turns -1.00 (expected +1)"."""
    pts, normals, uv, bottom, top = _open_cylinder()
    for loops in ([top, bottom], [bottom, top]):  # the top rim maps outside, listed first or second
        check = check_pointset_map(pts, uv, normals, loops)
        assert check["passed"] and not check["mirrored"], check["reason"]
        assert sorted(check["turning_numbers"]) == [-1.0, 1.0]
    inverted = 1.0 / (uv[:, 0] + 1j * uv[:, 1])  # the bottom rim outside: as conformal
    check = check_pointset_map(pts, np.c_[inverted.real, inverted.imag], normals, [top, bottom])
    assert check["passed"] and check["turning_numbers"] == [-1.0, 1.0]
    # Both rims turning the same way is still wrong, whichever is outside.
    check = check_pointset_map(pts, uv, normals, [top, bottom[::-1]])
    assert not check["passed"] and "turning" in check["failed"]


def test_a_small_hole_turned_outside_fails():
    """A flat annulus, radii 1 and 0.2: its inversion puts the hole's short rim outside (a hole
    turned inside out, the rest squeezed inside), which the turning check refuses."""
    r, t = np.meshgrid(np.geomspace(0.2, 1.0, 20), np.linspace(0, 2 * np.pi, 64, endpoint=False))
    z = (r * np.exp(1j * t)).ravel()
    pts = np.c_[z.real, z.imag, np.zeros(z.size)]
    normals = np.tile([0.0, 0.0, 1.0], (len(pts), 1))
    outer = np.flatnonzero(np.isclose(r.ravel(), 1.0))  # counter-clockwise: the surface on the left
    hole = np.flatnonzero(np.isclose(r.ravel(), 0.2))[::-1]
    assert check_pointset_map(pts, pts[:, :2], normals, [outer, hole])["passed"]
    w = 0.2 / z  # conformal and orientation-preserving too
    check = check_pointset_map(pts, np.c_[w.real, w.imag], normals, [outer, hole])
    assert not check["passed"] and "turning" in check["failed"]


def test_a_local_fold_is_counted_as_flipped():
    pts, outer, rim = _grid_with_hole()
    normals = np.tile([0.0, 0.0, 1.0], (len(pts), 1))
    uv = pts[:, :2].copy()
    inner = np.flatnonzero((pts[:, 0] == 3) & (pts[:, 1] == 3))[0]
    uv[inner] += [1.6, 1.6]  # pushed past its diagonal neighbour: the triangles around it fold
    check = check_pointset_map(pts, uv, normals, [outer, rim])
    assert not check["passed"] and "flipped" in check["failed"] and check["n_flipped"] > 0
    assert "flipped" in check["reason"]


def test_a_spinning_boundary_fails_the_turning_check():
    r, t = np.meshgrid(np.linspace(0.3, 1.0, 8), np.linspace(0, 2 * np.pi, 48, endpoint=False))
    pts = np.c_[(r * np.cos(t)).ravel(), (r * np.sin(t)).ravel(), np.zeros(r.size)]
    z = (pts[:, 0] + 1j * pts[:, 1]) ** 2  # winds the boundary twice
    outer = np.flatnonzero(np.isclose(r.ravel(), 1.0))
    outer = outer[np.argsort(np.arctan2(pts[outer, 1], pts[outer, 0]))]
    check = check_pointset_map(pts, np.c_[z.real, z.imag], np.tile([0.0, 0.0, 1.0], (len(pts), 1)), [outer])
    assert not check["passed"] and "turning" in check["failed"]
    assert check["turning_numbers"][0] == pytest.approx(2.0, abs=1e-6)


def test_a_missing_hole_loop_shows_as_bridging_triangles_and_uncovered_candidates():
    pts, outer, rim = _grid_with_hole()
    normals = np.tile([0.0, 0.0, 1.0], (len(pts), 1))
    candidates = np.zeros(len(pts), dtype=bool)
    candidates[outer] = candidates[rim] = True
    check = check_pointset_map(pts, pts[:, :2], normals, [outer], candidates=candidates)
    assert not check["passed"]
    # The hole is triangulated over: triangles across it are longer than 4 spacings in 3D
    # (with the hole loop given there are none, see the identity test).
    assert check["n_bridging"] > 0 and check["n_degenerate"] >= check["n_bridging"]
    cov = check["coverage"]
    assert "coverage" in check["failed"] and not cov["passed"]
    assert cov["n_uncovered"] == len(rim) and cov["largest_uncovered_group"] == len(rim)


def test_coverage_passes_when_every_candidate_is_near_a_loop():
    pts, outer, rim = _grid_with_hole()
    knn = np.argsort(np.linalg.norm(pts[:, None] - pts[None], axis=-1), axis=1)[:, 1:9]
    candidates = np.zeros(len(pts), dtype=bool)
    candidates[outer] = candidates[rim] = True
    cov = loop_coverage(pts, [outer, rim], candidates, knn, spacing=1.0)
    assert cov == {"n_candidates": len(outer) + len(rim), "n_uncovered": 0, "largest_uncovered_group": 0,
                   "n_scattered": 0, "applicable": True, "empty_ring": 0, "passed": True}


def _two_of_three_rim_points(pts, rim):
    """Candidates on two of every three points of a hole's innermost rim, as where the
    angle criterion passes only some of a small hole's rim points: kNN groups of two."""
    c = (pts[:, 0].max() + pts[:, 0].min()) / 2
    order = rim[np.argsort(np.arctan2(pts[rim, 1] - c, pts[rim, 0] - c))]
    inner = order[np.hypot(pts[order, 0] - c, pts[order, 1] - c) < 3.5]  # the innermost ring of the rim
    return inner[np.arange(inner.size) % 3 != 2]


def test_coverage_fails_scattered_candidates_ringing_an_empty_disk():
    """A hole the loops missed whose rim passes the angle criterion only here and there:
    the kNN graph groups its candidates in twos, so the group rule (MIN_MISSED_RING)
    passes it; chained within 2.5 spacings they ring an empty disk."""
    from parambench.methods.pointset.selfcheck import MIN_MISSED_RING, uncovered_phrase

    n = 41  # a large enough grid that the ring's candidates are under 2 % of the points
    pts, outer, rim = _grid_with_hole(n=n, hole=2.6)
    ring = _two_of_three_rim_points(pts, rim)
    cov = _coverage_of(pts, outer, ring)
    assert cov["applicable"] and cov["largest_uncovered_group"] < MIN_MISSED_RING
    assert cov["empty_ring"] == len(ring) >= 5 and not cov["passed"]
    assert uncovered_phrase(cov) == f"{len(ring)} boundary candidates ring an empty disk on no detected loop"
    # The same candidates round a disk that holds points: a void of the sampling, not a hole.
    full, full_outer, _ = _grid_with_hole(n=n, hole=-1.0)
    cov = _coverage_of(full, full_outer, cKDTree(full).query(pts[ring])[1])
    assert cov["n_uncovered"] == len(ring) and cov["empty_ring"] == 0 and cov["passed"]


def _coverage_of(pts, outer, ring):
    """loop_coverage of the outer loop alone, with ``outer`` and ``ring`` as the candidates."""
    knn = cKDTree(pts).query(pts, k=9)[1][:, 1:]
    candidates = np.zeros(len(pts), dtype=bool)
    candidates[outer] = candidates[ring] = True
    return loop_coverage(pts, [outer], candidates, knn, spacing=1.0)


def test_non_finite_map_fails_without_raising():
    pts, outer, rim = _grid_with_hole()
    uv = pts[:, :2].copy()
    uv[0] = np.nan
    check = check_pointset_map(pts, uv, np.tile([0.0, 0.0, 1.0], (len(pts), 1)), [outer, rim])
    assert check["passed"] is False and "non-finite" in check["reason"]


def test_pointset_faces_without_loops_drop_bridging_triangles():
    pts, _, _ = _grid_with_hole()  # hole of radius 5 around (10, 10), spacing 1

    def near_centre(faces):
        return np.hypot(*(pts[:, :2][faces].mean(axis=1) - 10.0).T) < 3.0

    assert near_centre(triangulate_uv(pts[:, :2]).faces).any()  # plain Delaunay covers the hole
    faces = pointset_faces(pts, pts[:, :2], None)
    assert not near_centre(faces).any()
    assert np.all(_area(pts[:, :2], faces) > 0)


def test_following_the_advice_ends():
    """fbcp-pc on random points of a square proposed ball_eps_factor 3.5, 4.9, 6.86, 9.6, 13.5 in turn
    (each relative to the value the run used), none helping: proposals stop two steps past the
    default, then name the next parameter, then another method."""
    params = {"ball_eps_factor": 2.5, "k_nn": 8, "k_local": 16}
    seen = []
    for _ in range(8):
        advice = suggest_fix(["turning"], params, "fbcp-pc")
        seen.append(advice)
        if "--param" not in advice:
            break
        key, value = advice.removeprefix("try --param ").split("=")
        params[key] = type(params[key])(float(value))
    assert seen == ["try --param ball_eps_factor=3.5", "try --param ball_eps_factor=4.9", "try --param k_nn=12",
                    "try --param k_nn=16", "try another method, e.g. --method ocp"]


def test_suggestions_name_a_parameter_of_the_method():
    assert suggest_fix(["flipped", "turning"], {"k": 1.0, "k_nn": 8}, "scp-tan") == "try --param k=10"
    assert suggest_fix(["coverage"], {"boundary_angle_deg": 120.0}, "ocp") == "try --param boundary_angle_deg=100"
    assert suggest_fix(["flipped"], {"n_neighbors": 12}, "ltsa-sklearn") == "try --param n_neighbors=16"
    assert "--method ocp" in suggest_fix(["flipped"], {}, "isomap-sklearn")


@pytest.fixture(scope="module")
def bump():
    from parambench.datasets_gen.registry import make_surface

    return make_surface("bump", 900, sampling="jittered", seed=0).points_only()


def test_every_pointset_method_result_carries_its_check(bump):
    from parambench.methods import get_method

    spinning = get_method("scp-tan")(bump)
    check = spinning.diagnostics["selfcheck"]
    assert check["passed"] is False and "turning" in check["failed"]
    assert check["turning_numbers"][0] > 1.5  # the spinning of Sec. 4.2
    assert spinning.uv.shape == (bump.n_points, 2) and np.all(np.isfinite(spinning.uv))  # map kept
    good = get_method("sdp")(bump).diagnostics["selfcheck"]
    assert good["passed"] and good["triangulation"] == "cdt" and good["coverage"]["passed"]
    json.dumps(good)


def test_candidates_for_coverage_are_the_front_ends_own(bump):
    from parambench.methods.pointset.frontend import build_frontend
    from parambench.methods.pointset.plugin_support import frontend_candidates

    front = build_frontend(bump.points)
    candidates = frontend_candidates(front)
    assert not front.diagnostics["boundary"]["retried_with_wider_balls"]
    assert candidates.sum() == front.diagnostics["boundary"]["n_candidates"] > 0
    assert candidates[front.boundary_mask].mean() > 0.9  # loop points pass the angle criterion
    assert frontend_candidates(front.without_balls()) is None


def test_check_runs_on_the_distinct_points_when_some_coincide(bump):
    import warnings

    from parambench.datasets_gen.surface import Surface
    from parambench.methods import get_method

    points = np.r_[bump.points, bump.points[:5]]  # five copies: merged before the method runs
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = get_method("sdp")(Surface(points=points, name="copies"))
    check = result.diagnostics["selfcheck"]
    # Same front end, same map on the distinct points: the check with its loops (CDT) passes.
    assert check["passed"] and check["triangulation"] == "cdt" and check["coverage"] is not None


def test_coverage_does_not_apply_to_a_uniform_random_sample():
    """Around the voids of a uniform random sample the angle criterion fires on ~12 % of
    the points, in groups of 20+, although the one true loop is found and the map is
    right: coverage says it cannot tell (not applicable) instead of failing the map; on a
    jittered sample of the same surface it applies."""
    from parambench.datasets_gen.registry import make_surface
    from parambench.datasets_gen.surface import Surface
    from parambench.methods import get_method

    for sampling, applicable in (("random", False), ("jittered", True)):
        surface = make_surface("plane", 20000, sampling=sampling, seed=0)
        check = get_method("ocp")(Surface(points=surface.points, name="p")).diagnostics["selfcheck"]
        assert check["coverage"]["applicable"] is applicable
        assert check["passed"], check["reason"]
    assert check["coverage"]["largest_uncovered_group"] < 8


def test_a_boundary_image_that_crosses_itself_fails():
    """A map that folds at the boundary: the outer loop's image is a figure eight (two
    corners of a square grid swapped in uv). Triangle must add a vertex where the
    constraint segments cross; the check says so instead of silently falling back to an
    unconstrained triangulation whose triangles all look fine."""
    pts, outer, rim = _grid_with_hole()
    uv = pts[:, :2].copy()
    a, b = outer[2], outer[len(outer) // 2 + 2]  # two loop points on opposite sides
    uv[[a, b]] = uv[[b, a]]
    check = check_pointset_map(pts, uv, np.tile([0.0, 0.0, 1.0], (len(pts), 1)), [outer, rim])
    assert check["boundary_crosses"] is True
    assert not check["passed"] and "boundary-crossing" in check["failed"]
    assert "cross" in check["reason"]
    # the untouched map's loops do not cross
    clean = check_pointset_map(pts, pts[:, :2], np.tile([0.0, 0.0, 1.0], (len(pts), 1)), [outer, rim])
    assert clean["boundary_crosses"] is False and clean["passed"]


def test_crossing_loop_segments_never_reach_triangle(monkeypatch):
    """Triangle splits crossing constraint segments itself, and on one map (15,656 points, 219
    crossing pairs) never returned: crossings are found first, and Triangle is not called."""
    import triangle

    from parambench.methods.pointset.uv_triangulation import triangulate_uv

    pts, outer, rim = _grid_with_hole()
    uv = pts[:, :2].copy()
    a, b = outer[2], outer[len(outer) // 2 + 2]
    uv[[a, b]] = uv[[b, a]]

    unconstrained = triangle.triangulate

    def no_segments(data, *args, **kwargs):
        assert "segments" not in data, "Triangle was given crossing segments"
        return unconstrained(data, *args, **kwargs)

    monkeypatch.setattr(triangle, "triangulate", no_segments)
    tri = triangulate_uv(uv, [outer, rim])
    assert tri.boundary_crosses and tri.kind == "delaunay-fallback" and len(tri.faces)


def _noisy_grid(n=40, noise=0.5, seed=5):
    """A jittered n x n grid of spacing 1 with normal (z) noise of ``noise`` spacings, its
    outer loop and the true map (x, y)."""
    rng = np.random.default_rng(seed)
    x, y = np.meshgrid(np.arange(n, dtype=float), np.arange(n, dtype=float))
    xy = np.c_[x.ravel(), y.ravel()]
    inner = ~np.isin(np.arange(n * n), _ring(n))
    xy[inner] += rng.uniform(-0.3, 0.3, (int(inner.sum()), 2))  # boundary kept straight
    pts = np.c_[xy, noise * rng.standard_normal(n * n)]
    return pts, _ring(n), xy


def _estimated_normals(pts, adaptive: bool):
    from parambench.methods.pointset.neighbourhoods import knn_graph
    from parambench.methods.pointset.normals import noise_adaptive_normals, orient_normals, pca_normals

    graph = knn_graph(pts, 8)
    fitted = noise_adaptive_normals(pts, graph.indices)[0] if adaptive else pca_normals(pts, graph.indices)
    return orient_normals(pts, fitted, graph.indices)


def test_the_true_map_of_a_noisy_sampling_passes(monkeypatch):
    # Noise of 0.5 spacings along the normal: the exact map has no fold, but 8-point PCA
    # normals (18 degrees mean error) without the normal tolerance made the flip test
    # call some of its triangles flipped. Either defence alone removes that here.
    import parambench.methods.pointset.selfcheck as selfcheck

    pts, outer, xy = _noisy_grid()
    plain, adaptive = _estimated_normals(pts, adaptive=False), _estimated_normals(pts, adaptive=True)
    for normals in (plain, adaptive):
        check = check_pointset_map(pts, xy, normals, [outer])
        assert check["passed"], check["reason"]
        assert check["n_flipped"] == 0 and check["turning_ok"]
    monkeypatch.setattr(selfcheck, "NORMAL_TOL_DEG", 0.0)  # caps the tolerance at 0
    assert check_pointset_map(pts, xy, plain, [outer])["n_flipped"] > 0  # the false alarm
    assert check_pointset_map(pts, xy, adaptive, [outer])["n_flipped"] == 0


def test_a_fold_in_a_noisy_sampling_still_fails():
    pts, outer, xy = _noisy_grid()
    normals = _estimated_normals(pts, adaptive=True)
    uv = xy.copy()
    centre = np.argmin(np.hypot(xy[:, 0] - 20.0, xy[:, 1] - 20.0))
    uv[centre] += [1.8, 1.8]  # pushed past its diagonal neighbour: a local fold
    check = check_pointset_map(pts, uv, normals, [outer])
    assert not check["passed"] and "flipped" in check["failed"] and check["n_flipped"] >= 2


@pytest.mark.parametrize("drop_bridging", [False, True])
def test_chunked_face_facts_equal_one_pass(monkeypatch, drop_bridging):
    """The per-triangle facts are computed in row chunks on threads: chunks of 7 rows give
    the same counts as one chunk of every row (a noisy grid with folds pushed in and the
    uv of far-apart points swapped, so some triangles bridge)."""
    import parambench.methods.pointset.selfcheck as selfcheck
    import parambench.methods.pointset.uv_triangulation as uv_triangulation

    pts, outer, xy = _noisy_grid()
    normals = _estimated_normals(pts, adaptive=True)
    uv = xy.copy()
    rng = np.random.default_rng(3)
    uv[rng.choice(len(uv), 12, replace=False)] += rng.normal(scale=1.5, size=(12, 2))
    swap = rng.choice(len(uv), 12, replace=False)  # uv swapped between points far apart in 3D
    uv[swap] = uv[swap[::-1]]
    loops = None if drop_bridging else [outer]
    facts = []
    for chunk in (7, 10**9):
        monkeypatch.setattr(selfcheck, "_CHUNK", chunk)
        monkeypatch.setattr(uv_triangulation, "_CHUNK", chunk)
        check = check_pointset_map(pts, uv, normals, loops)
        check.pop("seconds")
        facts.append(check)
    assert facts[0] == facts[1]
    assert facts[0]["n_flipped"] > 0 and facts[0]["n_bridging" if loops else "n_removed_outside"] > 0


def test_a_tangent_plane_sliver_of_noisy_points_is_not_judged():
    # Three points nearly collinear in the tangent plane, lifted by noise into a
    # well-shaped 3D triangle (3D quality 0.23): the sign of its projected area, which
    # the flip test reads, is the noise's. It is a sliver; a well-shaped one is not.
    from parambench.methods.pointset.selfcheck import SLIVER_QUALITY, _tangent_sliver

    tri = np.array([[[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [1.0, 0.05, 0.9]],
                    [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [1.0, 1.5, 0.9]]])
    normal3d = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    q3d = 0.5 * np.linalg.norm(normal3d, axis=1) / 4.0
    assert q3d[0] > SLIVER_QUALITY  # the old 3D test called it well shaped
    mean_normal = np.tile([0.0, 0.0, 3.0], (2, 1))  # three vertex normals summed
    sliver, uncertain = _tangent_sliver(tri, normal3d, mean_normal)
    assert sliver.tolist() == [True, False] and not uncertain.any()


def test_a_triangle_stood_up_by_noise_is_uncertain_only_within_the_tolerance():
    # 3D normal 81.5 degrees from the mean normal, tangent-plane quality 0.15: a tilt of
    # the reference normal by 10 degrees could make it a sliver, by 0 it cannot.
    from parambench.methods.pointset.selfcheck import _tangent_sliver

    tri = np.array([[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.5, 0.3, 2.0]]])
    normal3d = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    mean_normal = np.array([[0.0, 0.0, 3.0]])
    assert [m.tolist() for m in _tangent_sliver(tri, normal3d, mean_normal, 10.0)] == [[False], [True]]
    assert [m.tolist() for m in _tangent_sliver(tri, normal3d, mean_normal, 0.0)] == [[False], [False]]


def test_many_uncertain_flips_fail_the_check(monkeypatch):
    # Each uncertain flip alone is forgiven; more than MAX_UNCERTAIN_FRACTION of them is
    # what a fold under noise looks like (random samplings at noise 0.5: 0.24-0.58 %).
    import parambench.methods.pointset.selfcheck as selfcheck

    pts, outer, xy = _noisy_grid()
    normals = _estimated_normals(pts, adaptive=True)
    base = check_pointset_map(pts, xy, normals, [outer])
    assert base["passed"] and base["n_flipped_uncertain"] <= selfcheck.MAX_UNCERTAIN_FRACTION * base["n_triangles"]
    facts = dict(base, n_flipped_uncertain=int(0.002 * base["n_triangles"]) + 1)
    assert selfcheck._too_uncertain(facts) and "within the normals' error" in selfcheck._reason(facts)


def test_normal_tolerance_follows_the_noise_level():
    from parambench.methods.pointset.neighbourhoods import knn_graph
    from parambench.methods.pointset.selfcheck import NORMAL_TOL_DEG, normal_tolerance_deg

    clean, _, _ = _noisy_grid(noise=0.0)
    clean[:, 2] = 0.01 * (clean[:, 0] - 20.0) ** 2  # curved, radius >= 50 spacings
    noisy, outer, xy = _noisy_grid(noise=0.5)
    assert normal_tolerance_deg(clean, knn_graph(clean, 8).indices) < 1.0
    assert normal_tolerance_deg(noisy, knn_graph(noisy, 8).indices) == NORMAL_TOL_DEG
    check = check_pointset_map(noisy, xy, _estimated_normals(noisy, adaptive=True), [outer])
    assert check["normal_tol_deg"] == NORMAL_TOL_DEG


def test_without_loops_bridging_triangles_are_dropped_and_the_rest_judged():
    # No loops (a peer without a front end): the Delaunay triangles across the hole are
    # dropped as outside before the flip test (which once indexed the undropped ones).
    pts, _, _ = _grid_with_hole()
    normals = np.tile([0.0, 0.0, 1.0], (len(pts), 1))
    check = check_pointset_map(pts, pts[:, :2], normals, None)
    assert check["passed"], check["reason"]
    assert check["n_removed_outside"] > 0 and check["n_flipped"] == 0
    uv = pts[:, :2].copy()
    inner = np.flatnonzero((pts[:, 0] == 3) & (pts[:, 1] == 3))[0]
    uv[inner] += [1.6, 1.6]
    assert check_pointset_map(pts, uv, normals, None)["n_flipped"] > 0


def _grid_with_voids_and_a_chain(chain_length, n=100):
    """An n x n unit grid whose boundary ring is its loop, with boundary candidates on the
    ring, on isolated points of a stride-4 lattice (voids of an irregular sampling: more
    than 2 % of the points, none connected) and on a straight interior chain."""
    from scipy.spatial import cKDTree

    x, y = np.meshgrid(np.arange(n, dtype=float), np.arange(n, dtype=float))
    pts = np.c_[x.ravel(), y.ravel(), np.zeros(n * n)]
    outer = _ring(n)
    candidates = np.zeros(n * n, dtype=bool)
    candidates[outer] = True
    lattice = (x % 4 == 2) & (y % 4 == 2) & (np.abs(y - n // 2) > 4) & (x > 4) & (x < n - 5) & (y > 4) & (y < n - 5)
    candidates[lattice.ravel()] = True
    chain = (y == n // 2) & (x >= 10) & (x < 10 + chain_length)
    candidates[chain.ravel()] = True
    knn = cKDTree(pts).query(pts, k=9)[1][:, 1:]
    return pts, outer, candidates, knn


def test_coverage_fails_a_long_missed_chain_even_where_voids_make_it_not_applicable():
    """On an irregular sampling (uncovered void rings on more than 2 % of the points) the
    check cannot tell a small missed hole from a void, but 64 connected uncovered
    candidates are no void: a real face scan's missed 2484-point outer boundary showed
    as a group of 514 there, and passed before."""
    from parambench.methods.pointset.selfcheck import MIN_MISSED_CHAIN

    for length, passed in ((30, True), (MIN_MISSED_CHAIN, False), (80, False)):
        pts, outer, candidates, knn = _grid_with_voids_and_a_chain(length)
        cov = loop_coverage(pts, [outer], candidates, knn, spacing=1.0)
        assert cov["applicable"] is False and cov["n_scattered"] > 0.02 * len(pts)
        assert cov["largest_uncovered_group"] == length
        assert cov["passed"] is passed


def test_a_solver_error_on_loops_that_miss_candidates_is_restated_with_front_end_remedies():
    from parambench.datasets_gen.errors import ConvergenceError
    from parambench.datasets_gen.surface import MethodInput
    from parambench.methods.hints import Hint, fit_hints, hinted
    from parambench.methods.pointset import plugin_support as support
    from parambench.methods.registry import get_method

    pts, outer, rim = _grid_with_hole()
    knn = np.argsort(np.linalg.norm(pts[:, None] - pts[None], axis=-1), axis=1)[:, 1:9]
    candidates = np.zeros(len(pts), dtype=bool)
    candidates[outer] = candidates[rim] = True
    normals = np.tile([0.0, 0.0, 1.0], (len(pts), 1))
    surface = MethodInput(points=pts, name="grid")

    def solver_error():
        # The cause may offer front-end remedies of its own (the line search does).
        return hinted(ConvergenceError, "no t = 1 crossing found", Hint("use k_search='direct'", "k_search", "direct"),
                      *support.BOUNDARY_HINTS)

    # The hole's rim is on no loop: the error says the boundary first, with its remedies.
    support._CHECK_INPUTS[surface] = support._CheckInputs(normals, knn, 1.0, [outer], candidates)
    doubt = support.boundary_doubt(surface, solver_error())
    assert isinstance(doubt, ConvergenceError)
    ocp = get_method("ocp")
    fit_hints(doubt, ocp.defaults, ocp.defaults)
    text = str(doubt)
    assert text.startswith(f"the detected boundary looks wrong: {len(rim)} connected boundary candidates lie on no detected loop")
    assert "no t = 1 crossing found" in text
    assert text.index("boundary_angle_deg") < text.index("k_search='direct'")
    for hint in support.BOUNDARY_HINTS:  # restating adds no remedy twice (real/cortex-lh said each twice)
        assert text.count(hint.text) == 1
    # With both loops the boundary is not in doubt: the solver's own error stands.
    support._CHECK_INPUTS[surface] = support._CheckInputs(normals, knn, 1.0, [outer, rim], candidates)
    assert support.boundary_doubt(surface, solver_error()) is None
    assert support.boundary_doubt(surface, solver_error()) is None  # nothing left to check with


def test_ocp_check_takes_the_normals_stage_fit_error_unchanged(monkeypatch):
    """The check's normal tolerance comes from the front end's kNN fits instead of fitting
    the same graph again: it is handed the median error, and the tolerance is the one the
    recomputation gives."""
    from parambench.datasets_gen.registry import make_surface
    from parambench.methods.pointset import selfcheck
    from parambench.methods.pointset.frontend import build_frontend
    from parambench.methods.registry import get_method

    surface = make_surface("bump", 2500, sampling="jittered", seed=0, noise=0.05)
    expected = selfcheck.normal_tolerance_deg(surface.points, build_frontend(surface.points).knn_indices)
    assert 0.0 < expected < selfcheck.NORMAL_TOL_DEG  # neither a noise-free plane nor the cap
    handed = []
    original = selfcheck.normal_tolerance_deg
    monkeypatch.setattr(selfcheck, "normal_tolerance_deg",
                        lambda points, knn, median=None: (handed.append(median), original(points, knn, median))[1])
    result = get_method("ocp")(surface.method_input(False))
    assert handed and all(m is not None for m in handed)
    assert result.diagnostics["selfcheck"]["normal_tol_deg"] == pytest.approx(round(expected, 3), abs=1e-3)


@pytest.mark.parametrize("on_the_loop", [True, False])
def test_a_flipped_sliver_off_the_loops_fails_a_rim_sliver_does_not(on_the_loop):
    """Flipped slivers are not flips (three nearly collinear points), but off the loops
    none was seen on 108 correct maps; on protrusions' fingertips two were all the check
    saw of a map folding 4 true triangles. A rim sliver (every corner on a loop) stays free,
    and so does any sliver where slivers are common (a stretched map makes them)."""
    from parambench.methods.pointset.selfcheck import _face_facts, _reason, _too_many_inner_slivers

    side = 16  # 450 well-shaped triangles and the sliver: slivers are rare (0.2 %)
    xs, ys = np.meshgrid(np.arange(float(side)), np.arange(float(side)))
    grid = np.c_[xs.ravel(), ys.ravel(), np.zeros(side * side)]
    quads = [(r * side + c, r * side + c + 1, (r + 1) * side + c + 1, (r + 1) * side + c)
             for r in range(side - 1) for c in range(side - 1)]
    faces = [f for a, b, c, d in quads for f in ((a, b, c), (a, c, d))]  # counter-clockwise seen from +z
    sliver = np.array([[10.0, 0, 0], [11.0, 0.01, 0], [12.0, 0, 0]])  # clockwise seen from +z
    points = np.vstack([grid, sliver])
    uv = points[:, :2].copy()
    n = side * side
    uv[n:, 1] *= -1  # counter-clockwise in uv, as the uv triangulation's faces are: a flip
    faces = np.array(faces + [(n, n + 1, n + 2)])
    normals = np.tile([0.0, 0.0, 1.0], (n + 3, 1))
    on_loop = np.zeros(n + 3, dtype=bool)
    on_loop[n:] = on_the_loop
    facts, _, _ = _face_facts(points, uv, normals, faces, np.ones(n + 3), drop_bridging=False, tol_deg=0.0,
                           on_loop=on_loop)
    assert facts["n_flipped"] == 0 and facts["n_flipped_slivers"] == 1
    assert facts["n_flipped_inner_slivers"] == (0 if on_the_loop else 1)
    assert _too_many_inner_slivers(facts) is (not on_the_loop)
    assert ("flipped sliver" in _reason(facts)) is (not on_the_loop)
    # Without detected loops (a peer without the front end) no sliver is known to lie off them.
    no_loops, _, _ = _face_facts(points, uv, normals, faces, np.ones(n + 3), drop_bridging=True, tol_deg=0.0,
                              on_loop=np.zeros(n + 3, dtype=bool))
    assert no_loops["n_flipped_slivers"] == 1 and no_loops["n_flipped_inner_slivers"] == 0
    # Where slivers are common (3 % of the triangles), one flipped says nothing.
    common = dict(facts, n_triangles=33, n_slivers=1)
    assert _too_many_inner_slivers(common) is False


def _hull_area(uv):
    from scipy.spatial import ConvexHull

    return ConvexHull(uv).volume  # in 2D, the area


def test_delaunay_faces_tile_the_hull_with_each_distinct_point_once():
    rng = np.random.default_rng(3)
    uv = rng.random((2000, 2))
    faces = delaunay_faces(uv)
    assert faces.shape == (2 * 2000 - 2 - _hull_vertex_count(uv), 3)  # Euler: 2n - 2 - h triangles
    assert np.abs(_area(uv, faces)).sum() == pytest.approx(_hull_area(uv), rel=1e-12)
    assert np.array_equal(np.unique(faces), np.arange(2000))
    # Delaunay: no point strictly inside any face's circumcircle.
    a, b, c = uv[faces[:, 0]], uv[faces[:, 1]], uv[faces[:, 2]]
    d = 2 * ((a[:, 0] - c[:, 0]) * (b[:, 1] - c[:, 1]) - (b[:, 0] - c[:, 0]) * (a[:, 1] - c[:, 1]))
    sa, sb = ((a - c) ** 2).sum(axis=1), ((b - c) ** 2).sum(axis=1)
    centre = c + np.c_[sa * (b[:, 1] - c[:, 1]) - sb * (a[:, 1] - c[:, 1]),
                       sb * (a[:, 0] - c[:, 0]) - sa * (b[:, 0] - c[:, 0])] / d[:, None]
    radius = np.linalg.norm(a - centre, axis=1)
    nearest = cKDTree(uv).query(centre)[0]
    assert (nearest >= radius * (1 - 1e-9)).all()


def _hull_vertex_count(uv):
    from scipy.spatial import ConvexHull

    return len(ConvexHull(uv).vertices)


def test_delaunay_faces_of_a_collapsed_map_keep_one_of_each_coincident_group():
    """A collapsed map: most points in tight clusters, many exactly coincident. Qhull's
    facet merging ran for over ten minutes on such a layout (a range scan's folded map);
    the faces must use the first row of each coincident group and tile the hull."""
    rng = np.random.default_rng(0)
    centres = rng.random((300, 2))
    uv = np.repeat(centres, 40, axis=0) + 1e-9 * rng.standard_normal((12000, 2))
    uv[::3] = np.repeat(centres, 40, axis=0)[::3]  # exact copies of each cluster's centre
    uv = np.vstack([uv, rng.random((3000, 2))])
    faces = delaunay_faces(uv)
    used = np.unique(faces)
    _, first = np.unique(uv, axis=0, return_index=True)
    assert np.isin(used, first).all()  # no duplicate row is a vertex
    assert used.size == first.size  # every distinct point is one
    assert np.abs(_area(uv, faces)).sum() == pytest.approx(_hull_area(uv), rel=1e-9)
    assert (np.abs(_area(uv, faces)) > 0).all()


@pytest.mark.parametrize("uv", [np.c_[np.arange(5.0), 2 * np.arange(5.0)], np.zeros((6, 2)),
                                np.array([[0.0, 0.0], [1.0, 1.0], [0.0, 0.0]])])
def test_delaunay_faces_refuse_a_map_with_no_area(uv):
    with pytest.raises(InvalidInputError, match="collapsed"):
        delaunay_faces(uv)


def test_coherent_beltrami_is_zero_for_similarities_and_measures_a_stretch():
    from parambench.methods.pointset.selfcheck import coherent_beltrami

    pts, outer, xy = _noisy_grid()
    flat = np.c_[xy, np.zeros(len(xy))]
    faces = pointset_faces(flat, xy, [outer])
    turn = np.array([[np.cos(0.7), -np.sin(0.7)], [np.sin(0.7), np.cos(0.7)]])
    assert coherent_beltrami(flat, 3.0 * xy @ turn.T + 5.0, faces) < 1e-12
    # uv = (x, 2y): the metric in uv is diag(1, 1/4), nu = (1 - 1/4) / (1 + 1/4) everywhere.
    assert coherent_beltrami(flat, xy * [1.0, 2.0], faces) == pytest.approx(0.6, abs=1e-9)


def test_a_stretched_map_fails_as_distorted_only_where_a_conformal_map_is_promised():
    pts, outer, xy = _noisy_grid()
    normals = _estimated_normals(pts, adaptive=True)
    exact = check_pointset_map(pts, xy, normals, [outer], conformal=True)
    # Noise 0.5 spacings makes nu random per triangle; the cells average it away.
    assert exact["passed"], exact["reason"]
    assert exact["coherent_beltrami"] < 0.5 * MAX_COHERENT_BELTRAMI
    stretched = xy * [1.0, 1.6]  # no flip, no crossing: only the shape is wrong
    judged = check_pointset_map(pts, stretched, normals, [outer], conformal=True)
    assert not judged["passed"] and judged["failed"] == ["distorted"]
    assert "not conformal" in judged["reason"] and judged["coherent_beltrami"] > MAX_COHERENT_BELTRAMI
    assert suggest_fix(judged["failed"], {"refine": "auto", "k_nn": 8}, "ocp") == "try --param refine=mesh"
    unjudged = check_pointset_map(pts, stretched, normals, [outer])
    assert unjudged["passed"] and unjudged["coherent_beltrami"] == judged["coherent_beltrami"]


def test_the_distortion_allowed_follows_the_noise():
    """A clean input's conformal map may stretch less than a noisy one's: the limit is
    MAX_COHERENT_BELTRAMI_CLEAN up to CLEAN_TOL_DEG of normal tolerance, MAX_COHERENT_BELTRAMI
    at NORMAL_TOL_DEG, linear between."""
    from parambench.methods.pointset.selfcheck import (CLEAN_TOL_DEG, MAX_COHERENT_BELTRAMI_CLEAN, NORMAL_TOL_DEG,
                                                       coherent_limit)

    assert coherent_limit(0.0) == coherent_limit(CLEAN_TOL_DEG) == coherent_limit(None) == MAX_COHERENT_BELTRAMI_CLEAN
    assert coherent_limit(NORMAL_TOL_DEG) == pytest.approx(MAX_COHERENT_BELTRAMI)
    middle = coherent_limit(0.5 * (CLEAN_TOL_DEG + NORMAL_TOL_DEG))
    assert middle == pytest.approx(0.5 * (MAX_COHERENT_BELTRAMI_CLEAN + MAX_COHERENT_BELTRAMI))
    # A clean grid stretched by s = sqrt(11/9) in v: nu = (s^2 - 1) / (s^2 + 1) = 0.1 everywhere,
    # past the clean limit and under the noisy one (the old, single limit let it pass).
    x, y = np.meshgrid(np.linspace(0, 1, 21), np.linspace(0, 1, 21))
    xy = np.c_[x.ravel(), y.ravel()]
    flat = np.c_[xy, np.zeros(len(xy))]
    outer = np.r_[np.arange(21), 20 + 21 * np.arange(1, 21), 440 - np.arange(1, 21), 420 - 21 * np.arange(1, 20)]
    normals = np.tile([0.0, 0.0, 1.0], (len(xy), 1))
    judged = check_pointset_map(flat, xy * [1.0, np.sqrt(11.0 / 9.0)], normals, [outer], conformal=True)
    assert judged["normal_tol_deg"] <= CLEAN_TOL_DEG
    assert judged["coherent_beltrami"] == pytest.approx(0.1, abs=1e-4)
    assert MAX_COHERENT_BELTRAMI_CLEAN < 0.1 < MAX_COHERENT_BELTRAMI
    assert judged["failed"] == ["distorted"]
    assert check_pointset_map(flat, xy, normals, [outer], conformal=True)["passed"]
