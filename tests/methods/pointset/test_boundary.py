"""Boundary points by the angle criterion and their loops, against planted ground truth."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from parambench.datasets_gen.errors import InvalidInputError, NoBoundaryError
from parambench.datasets_gen.registry import make_surface
from parambench.methods.geometry2d import signed_area_2d
from parambench.methods.pointset.boundary import (_LOOPS_PER_TREE, angular_gaps, bridge_successors, cycles,
                                                  empty_radii_inside, empty_radius_inside,
                                                  find_boundary, is_outer_rim, no_boundary_error, successors)
from parambench.methods.pointset.boundary_putback import loop_zigzag, put_back_passed_over
from parambench.methods.pointset.frontend import build_frontend
from parambench.methods.pointset.normals import tangent_frames

HOLES = [(-0.45, -0.4, 0.25), (0.45, 0.35, 0.3)]


def _surface(make_height_patch, make_cap, name, sampling):
    if name == "cap":
        return make_cap(1.0, 1.0, 80, sampling)  # ~5k points
    if name == "holes":
        return make_height_patch("bump", 75, sampling, holes=HOLES)
    return make_height_patch(name, 70, sampling)


def assert_same_cycle(found: np.ndarray, truth: np.ndarray) -> None:
    """``found`` restricted to the true points is ``truth`` up to rotation (same direction)."""
    in_truth = np.isin(found, truth)
    sub = found[in_truth]
    assert sub.size == truth.size, f"loop visits {sub.size} of {truth.size} true boundary points"
    start = int(np.flatnonzero(truth == sub[0])[0])
    np.testing.assert_array_equal(sub, np.roll(truth, -start))


@pytest.mark.parametrize("sampling", ["grid", "jittered"])
@pytest.mark.parametrize("name", ["bump", "saddle", "cap", "holes"])
def test_boundary_matches_registry_ground_truth(name, sampling):
    """The project's datasets (~5k points, shuffled point order): recall 1, precision >= 0.95,
    every true loop found once, in the same cyclic order and direction (outer counter-
    clockwise, holes clockwise seen from the normals' side), no fake loops.
    Measured: recall 1.0 and precision >= 0.996 on all of them (also for random and
    blue-noise samplings, and for holes-bumped, cylinder, protrusions, gnome-strip),
    except the saddle: since notches are put back (see ``_NOTCH_DETOUR`` in ``boundary_putback``),
    some of its first interior row, where the steep rim's lattice is sparse and looks like
    a zigzag rim's notches, joins the loop (precision 0.943 grid, 0.924 jittered); issue
    11's target, 0.9, holds there."""
    surface = make_surface(name, 5000, sampling=sampling, seed=0)
    fe = build_frontend(surface.points)
    assert np.einsum("ij,ij->i", fe.normals, surface.normals).min() > 0  # same side as the truth
    _check_loops(fe, surface.boundary_mask, surface.boundary_loops, 0.9 if name == "saddle" else 0.95)


@pytest.mark.parametrize("sampling", ["grid", "jittered"])
@pytest.mark.parametrize("name", ["bump", "saddle", "cap", "holes"])
def test_boundary_matches_local_ground_truth(make_height_patch, make_cap, name, sampling):
    """The same on the local generators (square lattice, boundary points exactly on the
    boundary curves), where the outer loop is also checked to wind counter-clockwise in
    the xy projection (normals point to +z) and holes clockwise."""
    patch = _surface(make_height_patch, make_cap, name, sampling)
    fe = build_frontend(patch.points)
    _check_loops(fe, patch.boundary_mask, patch.loops)
    for i, loop in enumerate(fe.boundary_loops):
        area = signed_area_2d(fe.points[loop, :2])
        assert (area > 0) == (i == 0)


def _check_loops(fe, truth_mask, true_loops, min_precision=0.95):
    found = fe.boundary_mask
    recall = (found & truth_mask).sum() / truth_mask.sum()
    precision = (found & truth_mask).sum() / found.sum()
    assert recall == 1.0
    assert precision >= min_precision
    assert len(fe.boundary_loops) == len(true_loops)  # no fake loops
    for k, true_loop in enumerate(true_loops):
        owners = [i for i, loop in enumerate(fe.boundary_loops) if np.isin(loop, true_loop).any()]
        assert len(owners) == 1
        assert_same_cycle(fe.boundary_loops[owners[0]], true_loop)
        if k == 0:
            assert owners == [0]  # outer loop first


def test_angular_gaps_by_hand():
    # Spokes at 0, 90 and 180 degrees: the largest gap is 180 degrees, centred on -90.
    coords = np.array([[[1.0, 0.0], [0.0, 2.0], [-1.0, 0.0], [0.0, 0.0]]])
    mask = np.array([[True, True, True, False]])
    gap, bis = angular_gaps(coords, mask)
    np.testing.assert_allclose(gap, [np.pi])
    np.testing.assert_allclose(bis, [[0.0, -1.0]], atol=1e-15)
    # A full ring of 8 spokes has gaps of 45 degrees.
    t = np.arange(8) * np.pi / 4 + 0.1
    ring = np.stack([np.cos(t), np.sin(t)], axis=1)[None]
    gap, _ = angular_gaps(ring, np.ones((1, 8), dtype=bool))
    np.testing.assert_allclose(gap, [np.pi / 4])


@pytest.mark.parametrize("seed", range(3))
def test_angular_gaps_kernel_equals_the_numpy_expressions(monkeypatch, seed):
    import parambench.methods.pointset.boundary as bm

    rng = np.random.default_rng(seed)
    n, b = 700, int(rng.integers(1, 40))
    coords = rng.normal(size=(n, b, 2))
    mask = rng.random((n, b)) < rng.uniform(0.2, 1.0)
    mask[:, 0] = True
    mask[:5] = False  # no member: -inf and NaN, as the numpy expressions give
    mask[5:10] = np.arange(b) < 1  # one member: the whole circle
    coords[10] = [1.0, 0.0]  # all spokes along one direction, ties everywhere
    coords[11, ::2] = [0.0, -0.0]  # spokes of angle -0 and +0
    coords[11, 1::2] = [0.0, 0.0]
    coords[12, :, 1] = 0.0  # angles 0 and pi only
    coords[12, :, 0] = np.where(np.arange(b) % 3 == 0, -1.0, 2.0)
    monkeypatch.setattr(bm, "_GAP_CHUNK", 64)  # several batches on the threads
    with np.errstate(invalid="ignore"):
        want = bm._angular_gaps_numpy(coords, mask)
        got = angular_gaps(coords, mask)
    for a, c in zip(want, got):
        np.testing.assert_array_equal(np.isnan(a), np.isnan(c))
        ok = ~np.isnan(a)
        np.testing.assert_array_equal(a[ok].view(np.int64), c[ok].view(np.int64))  # bit for bit, signed zeros too
    radii = np.sqrt(np.einsum("nbi,nbi->nb", coords, coords)).max(axis=1)
    assert np.array_equal(bm._ball_radii(coords), radii)


def test_successor_walks_with_the_surface_on_the_left():
    # Points on the x axis, surface above (y > 0): outward is -y, so walking goes +x.
    idx = np.array([[1, 2], [0, 2], [1, 0]])
    xs = np.array([0.0, 1.0, 2.0])
    coords = np.stack([np.stack([xs[idx[i]] - xs[i], np.zeros(2)], axis=1) for i in range(3)])
    outward = np.tile([0.0, -1.0, 0.0], (3, 1))
    bis = np.tile([0.0, -1.0], (3, 1))
    succ = successors(idx, coords, np.ones(3, dtype=bool), outward, bis)
    np.testing.assert_array_equal(succ, [1, 2, -1])


def test_cycles_of_a_successor_map():
    succ = np.array([1, 2, 0, 0, 5, 4, -1, 3])
    found = cycles(succ, np.arange(8))
    assert sorted(map(tuple, found)) == [(0, 1, 2), (4, 5)]


def test_decimation_keeps_every_mth_point_in_order(make_height_patch):
    patch = make_height_patch("bump", 40, "jittered")
    full = build_frontend(patch.points)
    half = build_frontend(patch.points, boundary_decimate=2)
    np.testing.assert_array_equal(half.boundary_loops[0], full.boundary_loops[0][::2])
    assert half.boundary_mask.sum() == (full.boundary_loops[0].size + 1) // 2


def test_closed_sphere_raises_no_boundary(make_sphere):
    with pytest.raises(NoBoundaryError, match="closed"):
        build_frontend(make_sphere(3000))


@pytest.mark.parametrize("sampling,radius,n_loops", [("jittered", 1.5, 1), ("jittered", 5.0, 2), ("grid", 1.0, 2),
                                                     ("grid", 5.0, 2)])
def test_gap_versus_hole(make_height_patch, sampling, radius, n_loops):
    """Removing the points within ``radius`` spacings of a point: on a jittered sampling 1.5
    spacings is a sampling gap (no loop), 5 spacings is a hole (a clockwise loop around it,
    closed even though the jagged rim has notches the angle criterion misses). On a lattice
    every missing grid point opens the cells around it, as a raster's no-data points do in
    its mesh: 4 points removed give an 8-point loop (the lattice's own cells,
    :mod:`parambench.methods.pointset.lattice_loops`)."""
    patch = make_height_patch("plane", 60, sampling)
    h = 2 / 59
    centre = np.array([0.1, -0.2])
    keep = np.hypot(*(patch.points[:, :2] - centre).T) > radius * h
    fe = build_frontend(patch.points[keep])
    assert len(fe.boundary_loops) == n_loops
    assert (fe.diagnostics["boundary"].get("loops_from") == "lattice cells") == (sampling == "grid")
    if n_loops == 2:
        hole = fe.points[fe.boundary_loops[1], :2]
        assert np.all(np.hypot(*(hole - centre).T) < (radius + 1.5) * h)
        assert signed_area_2d(hole) * signed_area_2d(fe.points[fe.boundary_loops[0], :2]) < 0  # opposite turns
        assert signed_area_2d(hole) < 0


def test_parameters_are_checked(make_height_patch):
    patch = make_height_patch("plane", 10, "grid")
    idx = np.zeros((len(patch.points), 3), dtype=np.int64)
    coords = np.zeros((len(patch.points), 3, 2))
    normals = np.tile([0.0, 0.0, 1.0], (len(patch.points), 1))
    with pytest.raises(InvalidInputError, match="boundary_angle_deg"):
        find_boundary(patch.points, normals, idx, coords, angle_deg=400)
    with pytest.raises(InvalidInputError, match="boundary_decimate"):
        find_boundary(patch.points, normals, idx, coords, decimate=0)


@pytest.mark.parametrize("name,min_recall", [("real/lilium", 1.0), ("real/bump-domain", 1.0), ("real/camelhead", 0.97),
                                             ("real/meg-helmet", 1.0), ("real/spot-top", 1.0)])
def test_real_scans_one_loop_in_order(name, min_recall):
    """Irregular scan meshes, points only. camelhead: the boundary is sparser than the rest
    (edges 1.7 l) and three of its 56 points, where lips and eyelids nearly touch, have
    gaps under 120 degrees; the walk steps over them and two are put back (double steps
    2.0 and 1.83 times the local step; the third, 1.39, stays out: recall 55/56); a dense
    patch of 13 points forms a small cycle that the perimeter rule drops. spot-top (a plane
    cut of a closed mesh, so its rim runs across triangles): all 64 rim points; the two
    notches of its zigzag rim (open angles under 120 degrees) were missed before the
    notch rule of the put-back."""
    surface = make_surface(name)
    fe = build_frontend(surface.points)
    truth = surface.boundary_loops[0]
    assert len(fe.boundary_loops) == 1
    loop = fe.boundary_loops[0]
    assert np.isin(loop, truth).all()  # precision 1
    assert np.isin(truth, loop).mean() >= min_recall
    # Same cyclic order and direction as the truth, skipping the missed points.
    pos = np.flatnonzero(np.isin(truth, loop))
    expected = truth[pos]
    start = int(np.flatnonzero(expected == loop[0])[0])
    np.testing.assert_array_equal(loop, np.roll(expected, -start))


def test_ragged_boundary_of_a_uniform_random_sample():
    """Uniform random points on a bump over [-1, 1]^2 with no points placed on the border:
    the boundary is ragged at the sampling scale. The first walk does not close; before
    the cycle cover, the retry on 1.6x wider balls did (measured: 11 of 12 seeds/sizes gave
    the outer loop); now the cover of the candidates the walk left off closes it on the
    first balls (seeds 0-3 x 3000/6000 points: one loop each, 7 of 8 from the cover, 97-100 %
    of its points within 0.1 of the border, enclosed area 3.76-3.85 of 4)."""
    rng = np.random.default_rng(0)
    xy = rng.uniform(-1, 1, (3000, 2))
    points = np.c_[xy, 0.5 * np.exp(-(xy**2).sum(axis=1) / 0.18)]
    fe = build_frontend(points)
    outer = fe.boundary_loops[0]
    assert len(fe.boundary_loops) == 1
    assert fe.diagnostics["boundary"]["n_cover_loops"] == 1
    assert not fe.diagnostics["boundary"]["retried_with_wider_balls"]
    assert np.mean(np.abs(xy[outer]).max(axis=1) > 0.9) > 0.95
    assert signed_area_2d(xy[outer]) > 3.0  # counter-clockwise, encloses most of the square


@pytest.mark.parametrize("n,seed", [(2000, 10), (3000, 7)])
def test_the_rim_of_uniform_random_points_on_a_nearly_flat_square(n, seed):
    """As above on a nearly flat square: the cover's loop encloses the surface itself, so
    no empty disk lies inside it, and the empty-disk test alone dropped it (these seeds
    raised NoBoundaryError; 8 of 20 seeds at 10k points). Where the walk keeps no loop,
    a cover loop whose points face out onto empty space is the outer rim."""
    rng = np.random.default_rng(seed)
    xy = rng.uniform(-1, 1, (n, 2))
    fe = build_frontend(np.c_[xy, 0.06 * np.sin(xy[:, 0])])
    assert len(fe.boundary_loops) == 1 and fe.diagnostics["boundary"]["n_cover_loops"] == 1
    outer = fe.boundary_loops[0]
    # 85 % (2k) and 91 % (3k) of the loop lie within 0.1 (4.5 spacings at 2k) of the
    # border: the put-back notches of a ragged rim reach deeper.
    assert np.mean(np.abs(xy[outer]).max(axis=1) > 0.9) > 0.8
    assert abs(signed_area_2d(xy[outer])) > 3.5


def test_is_outer_rim_tells_a_rim_from_a_hole_and_from_a_ring_inside_the_surface():
    x, y = np.meshgrid(np.linspace(-1, 1, 41), np.linspace(-1, 1, 41))
    grid = np.c_[x.ravel(), y.ravel(), np.zeros(x.size)]
    disk = grid[np.hypot(grid[:, 0], grid[:, 1]) <= 1.0]
    angle = np.arctan2(disk[:, 1], disk[:, 0])
    radius = np.hypot(disk[:, 0], disk[:, 1])
    radial = np.c_[np.cos(angle), np.sin(angle), np.zeros(len(disk))]
    rim = np.flatnonzero(radius > 0.96)
    rim = rim[np.argsort(angle[rim])]
    tree = cKDTree(disk)
    assert is_outer_rim(disk, rim, radial, tree)
    assert not is_outer_rim(disk, rim, -radial, tree)  # facing in: a hole's loop, not a rim
    ring = np.flatnonzero(np.abs(radius - 0.5) < 0.03)
    ring = ring[np.argsort(angle[ring])]
    assert not is_outer_rim(disk, ring, radial, tree)  # facing out, but onto points


def test_no_boundary_messages():
    assert "closed surface: cut it open" in str(no_boundary_error(5, 120.0, 8))
    noted = str(no_boundary_error(5, 120.0, 8, note="The points are noisy."))
    assert noted.startswith(str(no_boundary_error(5, 120.0, 8))) and noted.endswith(" The points are noisy.")
    assert "closed surface: cut it open" in str(no_boundary_error(5, 120.0, 8, n_points=2000))
    few = str(no_boundary_error(21, 120.0, 8, n_points=40))
    assert "21 of the 40 points" in few and "sample the surface more densely" in few
    msg = str(no_boundary_error(500, 120.0, 8))
    assert "no boundary loop closes" in msg and "raise k_nn or ball_eps_factor" in msg


@pytest.mark.parametrize("name", ["bump", "cap", "protrusions", "plane"])
def test_random_sampling_has_no_void_loops(name):
    """Uniform random (Poisson) sampling leaves voids of a few spacings; the rings of
    points around them once passed as extra boundary loops (bump at 20k: loops of 9, 9
    and 12 points). Measured now: one loop, recall 1.0, precision 1.0 on all four."""
    surface = make_surface(name, 20000, sampling="random", seed=0)
    fe = build_frontend(surface.points)
    assert len(fe.boundary_loops) == 1, [len(lp) for lp in fe.boundary_loops]
    hit = np.count_nonzero(fe.boundary_mask & surface.boundary_mask)
    assert hit / surface.boundary_mask.sum() >= 0.99
    assert hit / fe.boundary_mask.sum() >= 0.99


def test_void_rings_are_dropped_only_with_local_spacing():
    """The loop-spacing rule is what removes the void rings: without the local spacing
    (the rule's scale) the same call keeps them."""
    from parambench.methods.pointset.frontend import build_frontend as build
    from parambench.methods.pointset import boundary as bnd

    surface = make_surface("bump", 20000, sampling="random", seed=0)
    fe = build(surface.points)
    spy = {}
    original = bnd.find_boundary

    def without_spacing(*args, **kwargs):
        kwargs["local_spacing"] = None
        spy["result"] = original(*args, **kwargs)
        return spy["result"]

    import parambench.methods.pointset.frontend as frontend
    frontend.find_boundary = without_spacing
    try:
        build(surface.points)
    finally:
        frontend.find_boundary = original
    assert len(fe.boundary_loops) == 1
    assert len(spy["result"].loops) > 1


def _circle_loop(n=40, radius=1.0, skip=10):
    """Points on a circle (the loop, walked counter-clockwise, with point ``skip`` left out),
    their outward (radial) directions, and a ball per point holding every point."""
    t = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    points = np.c_[radius * np.cos(t), radius * np.sin(t), np.zeros(n)]
    outward = points / np.linalg.norm(points, axis=1, keepdims=True)
    balls = np.tile(np.arange(n), (n, 1))
    loop = np.delete(np.arange(n), skip)
    return points, outward, balls, loop


def test_put_back_a_stepped_over_point():
    """The walk jumped from point 9 to point 11 (a double step): point 10, with a gap of
    100 degrees opening outwards, goes back between them; nothing else changes."""
    points, outward, balls, loop = _circle_loop()
    gap = np.full(len(points), np.deg2rad(100.0))
    loops, n = put_back_passed_over(points, [loop], balls, gap, outward)
    assert n == 1
    np.testing.assert_array_equal(loops[0], np.arange(40))


@pytest.mark.parametrize("case", ["small gap", "inward gap", "no double step", "no notch", "long detour"])
def test_put_back_refuses(case):
    """No insertion when the point's gap is under 80 degrees, opens the other way, the
    loop made no double step and the point is no notch (every point on the loop, one
    extra point just inside with a gap under 100 degrees, or a detour over 1.4), or the
    detour is longer than 1.5 |ab| (a point well inside the circle)."""
    points, outward, balls, loop = _circle_loop()
    gap = np.full(len(points), np.deg2rad(100.0))
    if case == "small gap":
        gap[10] = np.deg2rad(70.0)
    elif case == "inward gap":
        outward[10] *= -1.0
    elif case in ("no double step", "no notch"):
        # Just inside, below point 10: between 9 and 10 the detour is 1.19, under the
        # notch's 1.4, so it takes a gap under 100 degrees; further in, 1.42.
        points = np.vstack([points, (0.97 if case == "no double step" else 0.94) * points[10]])
        outward = np.vstack([outward, outward[10]])
        gap = np.append(gap, np.deg2rad(95.0 if case == "no double step" else 110.0))
        balls = np.tile(np.arange(41), (41, 1))
        loop = np.arange(40)
    else:
        points[10] *= 0.8  # |am| + |mb| = 1.56 |ab|
    loops, n = put_back_passed_over(points, [loop], balls, gap, outward)
    assert n == 0
    np.testing.assert_array_equal(loops[0], loop)


def test_put_back_a_notch_on_a_single_step():
    """A zigzag rim: tips on the unit circle, one notch just inside between each pair of
    tips (as a plane cut across triangles leaves). The walk went tip to tip, every step
    single; a notch with a gap of 110 degrees and a detour under 1.4 goes back, one with
    a gap of 95 (or a detour of 1.45) does not."""
    t = np.linspace(0.0, 2.0 * np.pi, 40, endpoint=False)
    tips = np.c_[np.cos(t), np.sin(t), np.zeros(40)]
    mid = np.c_[np.cos(t + np.pi / 40), np.sin(t + np.pi / 40), np.zeros(40)]
    depth = np.where(np.arange(40) == 7, 0.915, 0.985)  # detours 1.01, and 1.45 for notch 7
    points = np.vstack([tips, depth[:, None] * mid])
    outward = points / np.linalg.norm(points, axis=1, keepdims=True)
    balls = np.tile(np.arange(80), (80, 1))
    gap = np.full(80, np.deg2rad(110.0))
    gap[40 + 3] = np.deg2rad(95.0)
    loops, n = put_back_passed_over(points, [np.arange(40)], balls, gap, outward)
    expected = np.stack([np.arange(40), 40 + np.arange(40)], axis=1).ravel()
    expected = expected[~np.isin(expected, [43, 47])]
    assert n == 38
    np.testing.assert_array_equal(loops[0], expected)


def test_loop_zigzag_is_the_sagitta_and_ignores_offsets_along_the_normal():
    """On a regular 40-gon each point lies 1 - cos(2 pi / 40) off its neighbours' chord;
    lifting every other point along the normal (noise along it) changes nothing; on a rim
    whose every other point sits 0.05 inside, each edge gets the mean of its tip's and its
    notch's distances (four times the 40-gon's). Points on no loop get NaN."""
    t = np.linspace(0.0, 2.0 * np.pi, 40, endpoint=False)
    circle = np.c_[np.cos(t), np.sin(t), np.zeros(40)]
    points = np.vstack([circle, [[0.0, 0.0, 0.0]]])
    normals = np.tile([0.0, 0.0, 1.0], (41, 1))
    loop = [np.arange(40)]
    zig = loop_zigzag(points, normals, loop)
    np.testing.assert_allclose(zig[:40], 1.0 - np.cos(2.0 * np.pi / 40), rtol=1e-12)
    assert np.isnan(zig[40])
    lifted = points.copy()
    lifted[:40:2, 2] = 0.3
    np.testing.assert_allclose(loop_zigzag(lifted, normals, loop), zig, rtol=1e-12, equal_nan=True)
    notched = points.copy()
    notched[1:40:2, :2] *= 0.95
    step = 2.0 * np.pi / 40
    tip, notch = 1.0 - 0.95 * np.cos(step), np.cos(step) - 0.95  # off their neighbours' chords
    np.testing.assert_allclose(loop_zigzag(notched, normals, loop)[:40], 0.5 * (tip + notch), rtol=1e-12)


def test_loop_zigzag_is_off_where_the_steps_are_irregular():
    """A rim of scattered points is no mesh's zigzag: on a loop whose steps alternate
    between 1 and 2.5 units of angle (spread 0.43 of their mean, over the 0.32 limit),
    every value is 0; with steps alternating 1 and 1.5 (spread 0.2) the rule is on."""
    for ratio, on in ((2.5, False), (1.5, True)):
        steps = np.tile([1.0, ratio], 20)
        t = 2.0 * np.pi * np.concatenate([[0.0], np.cumsum(steps)[:-1]]) / steps.sum()
        points = np.c_[np.cos(t), np.sin(t), np.zeros(40)]
        zig = loop_zigzag(points, np.tile([0.0, 0.0, 1.0], (40, 1)), [np.arange(40)])
        assert np.all(zig > 0) if on else np.all(zig == 0)


def _polygon_and_notch(inset: float, tip10_radius: float = 1.0):
    """A 40-gon loop (zigzag 0.0123) with tip 10 at ``tip10_radius``, and a point ``inset``
    inside the chord of tips 9 and 10, at its middle; ball = everything, gaps 95 degrees."""
    t = np.linspace(0.0, 2.0 * np.pi, 40, endpoint=False)
    tips = np.c_[np.cos(t), np.sin(t), np.zeros(40)]
    tips[10] *= tip10_radius
    middle = 0.5 * (tips[9] + tips[10])
    points = np.vstack([tips, middle - inset * middle / np.linalg.norm(middle)])
    outward = points / np.linalg.norm(points, axis=1, keepdims=True)
    return points, outward, np.tile(np.arange(41), (41, 1)), np.full(41, np.deg2rad(95.0))


@pytest.mark.parametrize("inset,expected", [(0.04, 1), (0.07, 0)])
def test_put_back_a_notch_as_deep_as_the_rims_zigzag(inset, expected):
    """A point between tips 9 and 10 with a gap of 95 degrees (under the notch rule's 100)
    and a detour under 1.4 goes back when it lies 0.04 inside the chord (3.3 times the
    loop's zigzag), not at 0.07 (5.7 times): the first interior row behind a smooth
    boundary lies deeper than the boundary's sagitta. Without normals the rule is off."""
    points, outward, balls, gap = _polygon_and_notch(inset)
    normals = np.tile([0.0, 0.0, 1.0], (41, 1))
    loop = [np.arange(40)]
    zigzag = loop_zigzag(points, normals, loop)
    loops, n = put_back_passed_over(points, loop, balls, gap, outward, normals=normals, zigzag=zigzag)
    assert n == expected
    if expected:
        np.testing.assert_array_equal(loops[0], np.insert(np.arange(40), 10, 40))
    assert put_back_passed_over(points, loop, balls, gap, outward)[1] == 0


def test_put_back_measures_notches_from_the_walked_rim():
    """Tip 10 was put back in an earlier round (no zigzag of its own) and lies at radius
    0.85. A point 0.02 in from the middle of the chord from tip 9 to it (1.1 times the
    zigzag off that chord) lies 7.2 times the zigzag inside the chord of the walk's own
    points 9 and 11, so it stays out:
    rules on put-back points' chords would reach deeper each round. With tip 10 walked,
    it goes back."""
    points, outward, balls, gap = _polygon_and_notch(0.02, tip10_radius=0.85)
    normals = np.tile([0.0, 0.0, 1.0], (41, 1))
    loop = [np.arange(40)]
    zigzag = loop_zigzag(points, normals, loop)
    assert put_back_passed_over(points, loop, balls, gap, outward, normals=normals, zigzag=zigzag)[1] == 1
    zigzag[10] = np.nan
    assert put_back_passed_over(points, loop, balls, gap, outward, normals=normals, zigzag=zigzag)[1] == 0


def test_bridge_reach_per_point():
    """Boundary points on the x axis, outward -y (so the walk runs towards +x), with a
    gap of 3 between x = 4 and x = 7: a reach of 2 leaves x = 4 without a successor; a
    per-point reach of 3.5 there (its own coarse ball) bridges to x = 7, and the other
    points keep their successor at distance 1."""
    x = np.r_[np.arange(5.0), np.arange(7.0, 11.0)]
    points = np.c_[x, np.zeros_like(x), np.zeros_like(x)]
    e1, e2 = tangent_frames(np.tile([0.0, 0.0, 1.0], (x.size, 1)))
    outward = np.tile([0.0, -1.0, 0.0], (x.size, 1))
    bisector = np.c_[np.einsum("ni,ni->n", outward, e1), np.einsum("ni,ni->n", outward, e2)]
    candidates = np.ones(x.size, dtype=bool)
    none = np.full(x.size, -1, dtype=np.int64)
    succ = bridge_successors(points, e1, e2, candidates, outward, bisector, none, 2.0)
    np.testing.assert_array_equal(succ, [1, 2, 3, 4, -1, 6, 7, 8, -1])
    reach = np.full(x.size, 2.0)
    reach[4] = 3.5
    succ = bridge_successors(points, e1, e2, candidates, outward, bisector, none, reach)
    np.testing.assert_array_equal(succ, [1, 2, 3, 4, 5, 6, 7, 8, -1])


@pytest.mark.parametrize("name", ["holes-bumped", "holes"])
def test_small_holes_of_a_graded_sampling(name):
    """Graded, 2k points: the holes have 14-33 points, fewer than the void-ring rules'
    32 for most, and are all kept (their empty disks measure 2.2-5 of their own steps).
    holes-bumped: one hole (19 points) lies where the spacing is 3x the median; two of
    its points fail the angle criterion and the bridge between its candidates (3 steps)
    is longer than two median ball radii. With the reach following the point's own ball
    the hole closes: 4 loops (3 before), recall 0.993."""
    surface = make_surface(name, 2000, sampling="graded", seed=0)
    fe = build_frontend(surface.points)
    assert len(fe.boundary_loops) == len(surface.boundary_loops) == 4
    hits = (fe.boundary_mask & surface.boundary_mask).sum()
    assert hits / surface.boundary_mask.sum() >= 0.97
    assert hits / fe.boundary_mask.sum() >= 0.9


def test_empty_radius_inside_by_hand():
    """A ring of 40 points of radius 1: the empty disk inside has radius 1 (to the grid's
    resolution); with a point at the centre, 0.5; an empty grid cell count gives 0."""
    t = np.linspace(0.0, 2.0 * np.pi, 40, endpoint=False)
    ring = np.c_[np.cos(t), np.sin(t), 0.1 * np.cos(t)]  # slightly bent: fitted plane
    loop = np.arange(40)
    r = empty_radius_inside(ring, loop, cKDTree(ring))
    assert 0.93 <= r <= 1.0
    with_centre = np.vstack([ring, [0.0, 0.0, 0.0]])
    r = empty_radius_inside(with_centre, loop, cKDTree(with_centre))
    assert 0.45 <= r <= 0.52
    far = np.vstack([with_centre, np.random.default_rng(0).uniform(5.0, 9.0, (50, 3))])
    assert empty_radius_inside(far, loop) == r  # its own tree of the points near the loop
    assert empty_radius_inside(ring, loop, cKDTree(ring), grid=1) == 0.0  # one sample, on the box corner


def test_empty_radii_of_many_loops_share_one_tree_and_agree_with_each_loops_own():
    """Rings of 12 points round voids of a jittered grid, more of them than one tree is built
    for: the shared tree of all points gives each loop's own radius (the nearest point of a
    sample inside a loop is near the loop), and a ring with a point at its centre its half."""
    rng = np.random.default_rng(3)
    g = np.stack(np.meshgrid(np.arange(60.0), np.arange(60.0)), -1).reshape(-1, 2)
    pts = np.c_[g + rng.uniform(-0.2, 0.2, g.shape), np.zeros(len(g))]
    t = np.linspace(0.0, 2.0 * np.pi, 12, endpoint=False)
    centres = [(10.0 * i + 5.0, 10.0 * j + 5.0) for i in range(6) for j in range(6)]
    loops = []
    for c in centres:
        pts = pts[np.hypot(pts[:, 0] - c[0], pts[:, 1] - c[1]) > 2.5]  # a void of radius 2.5
    for m, c in enumerate(centres):
        start = len(pts)
        ring = np.c_[c[0] + 2.0 * np.cos(t), c[1] + 2.0 * np.sin(t), np.zeros(12)]
        pts = np.vstack([pts, ring] + ([[c[0], c[1], 0.0]] if m % 2 else []))
        loops.append(np.arange(start, start + 12))
    assert len(loops) > _LOOPS_PER_TREE
    shared = empty_radii_inside(pts, loops)
    assert shared == [empty_radius_inside(pts, c) for c in loops]
    assert all(1.8 <= r <= 2.0 for r in shared[::2]) and all(0.9 <= r <= 1.05 for r in shared[1::2])


def test_void_rings_that_the_spacing_rule_kept_are_dropped():
    """slit, random, 20k points: a ring around a void (13 points, spaced 1.22 local
    spacings along itself: the spacing rule keeps it) came out as a boundary loop. Its
    largest empty disk measures 1.25 of its own steps (holes: 2.2 or more); every loop
    returned now lies on the true boundary (with the rule off: a 13-point loop with no
    true boundary point). (The slot
    itself is still missed: its lips are 2 spacings apart and its empty disks no wider
    than the sampling's own voids.)"""
    surface = make_surface("slit", 20000, sampling="random", seed=0)
    fe = build_frontend(surface.points)
    for loop in fe.boundary_loops:
        assert surface.boundary_mask[loop].mean() >= 0.9, len(loop)


def test_put_back_two_stepped_over_points_in_two_rounds():
    """The walk jumped over points 10 and 11 (a triple step): the first round puts one of
    them back, the second (the remaining edge is now a double step) the other."""
    points, outward, balls, _ = _circle_loop()
    loop = np.delete(np.arange(40), [10, 11])
    gap = np.full(len(points), np.deg2rad(100.0))
    once, n1 = put_back_passed_over(points, [loop], balls, gap, outward)
    twice, n2 = put_back_passed_over(points, once, balls, gap, outward)
    assert (n1, n2) == (1, 1)
    assert once[0].size == 39
    np.testing.assert_array_equal(twice[0], np.arange(40))


def test_bunny_holes_found_are_complete():
    """pymeshlab's bunny10k as bare points (5 holes). Three holes are as narrow as the
    sampling's own gaps (1.55-1.9 mean edges across) and are not found; the two wider
    ones are, and with the stepped-over points put back (four rounds) each found loop
    holds every point of its hole (22 and 19) and little else."""
    surface = make_surface("real/bunny10k")
    fe = build_frontend(surface.points)
    assert len(fe.boundary_loops) >= 2
    for loop in fe.boundary_loops:
        assert surface.boundary_mask[loop].mean() >= 0.9
        overlap = [np.isin(true, loop).mean() for true in surface.boundary_loops]
        assert max(overlap) == 1.0


def test_a_small_hole_as_the_only_opening_is_offered_a_smaller_angle():
    """A sphere without a 15-degree cap (2,949 points): refused as closed, with no hint that helps before."""
    from parambench.methods.pointset.frontend import build_frontend
    from parambench.datasets_gen.errors import NoBoundaryError

    i = np.arange(3000) + 0.5
    phi, th = np.arccos(1 - 2 * i / 3000), np.pi * (1 + 5 ** 0.5) * i
    sphere = np.c_[np.cos(th) * np.sin(phi), np.sin(th) * np.sin(phi), np.cos(phi)]
    points = sphere[sphere[:, 2] < np.cos(np.radians(15))]
    with pytest.raises(NoBoundaryError, match=r"lower boundary_angle_deg \(e\.g\. 100\)"):
        build_frontend(points)
    front = build_frontend(points, boundary_angle_deg=100.0)
    assert len(front.boundary_loops) == 1
    rim = front.boundary_loops[0]
    assert np.all(points[rim, 2] > np.cos(np.radians(15)) - 0.1)  # the loop is the hole's rim
    assert "e.g. 80" in str(no_boundary_error(5, 100.0, 8))


def _plane_with_a_small_hole(radius_spacings: float = 2.0, seed: int = 3):
    """A jittered 60 x 60 grid on [-1, 1]^2 without the points inside a circle of ``radius_spacings``
    grid spacings, the circle itself sampled by 12 points (as a scan rim is)."""
    rng = np.random.default_rng(seed)
    h = 2.0 / 59
    x, y = np.meshgrid(np.linspace(-1, 1, 60), np.linspace(-1, 1, 60))
    xy = np.c_[x.ravel(), y.ravel()] + rng.uniform(-0.15, 0.15, (3600, 2)) * h
    xy = xy[np.hypot(*xy.T) > radius_spacings * h]
    t = np.linspace(0, 2 * np.pi, 12, endpoint=False)
    rim = radius_spacings * h * np.c_[np.cos(t), np.sin(t)]
    return np.c_[np.r_[xy, rim], np.zeros(len(xy) + 12)], len(xy) + np.arange(12)


def test_a_hole_narrower_than_the_balls_is_found():
    """Before: its rim points saw each other across it (gaps under 120 degrees): one loop, and
    every point-set method wrote a map whose triangles covered the hole, exit 0."""
    from parambench.methods.pointset.frontend import build_frontend

    points, rim = _plane_with_a_small_hole()
    front = build_frontend(points)
    assert len(front.boundary_loops) == 2 and front.diagnostics["boundary"]["n_small_holes"] == 1
    hole = front.boundary_loops[1]
    h = 2.0 / 59
    assert np.all(np.hypot(*points[hole, :2].T) < 3.0 * h)  # round the hole, on its rim or beside it
    assert len(set(hole.tolist()) & set(rim.tolist())) >= 10


def test_small_hole_loops_stay_off_irregular_samplings():
    """Irregular samplings: the small balls' gaps are everywhere (uniform random 65-72 % of the
    points, graded 11-16 %), so the pass looks only round voids wider than 2.2 local spacings (at a
    25 % gate ``protrusions`` graded 2k got a void ring as a second loop; with voids 2.2 wide but no
    such width asked of the loop, ``protrusions`` random 2k got one 1.79 wide); the generated
    surfaces' loops are unchanged in number."""
    from parambench.datasets_gen.registry import make_surface
    from parambench.methods.pointset.frontend import build_frontend

    for name, sampling, n in (("bump", "random", 4000), ("holes", "graded", 4000), ("slit", "graded", 4000),
                              ("protrusions", "graded", 2000), ("protrusions", "random", 2000)):
        surface = make_surface(name, n, sampling=sampling, seed=0)
        front = build_frontend(surface.points)
        assert front.diagnostics["boundary"]["n_small_holes"] == 0
        assert len(front.boundary_loops) == len(surface.boundary_loops)


def test_the_map_of_a_small_hole_leaves_it_open(tmp_path):
    from parambench.bench.cli import main
    from parambench.datasets_gen.io import load_surface

    points, _ = _plane_with_a_small_hole()
    src = tmp_path / "hole.xyz"
    np.savetxt(src, points)
    assert main(["flatten", str(src), "-o", str(tmp_path / "uv.obj")]) == 0
    faces = load_surface(tmp_path / "uv.obj").faces
    centroids = points[faces].mean(axis=1)
    assert not np.any(np.hypot(centroids[:, 0], centroids[:, 1]) < 2.0 * 2.0 / 59 * 0.97)  # none inside the hole


@pytest.mark.parametrize("n", [2000, 20000])
def test_a_small_hole_of_a_graded_sampling_is_found(n):
    """A hole 4 nominal spacings across on a graded plane (its rim 20-21 points, an empty disk 2.4-2.5
    local spacings wide): the pass had been skipped on irregular samplings, one loop, exit 0."""
    from parambench.datasets_gen.build import build_surface, nominal_spacing
    from parambench.datasets_gen.domains import Disk, Domain
    from parambench.datasets_gen.shapes.base import unit_square
    from parambench.datasets_gen.shapes.flat import Flat, Plane

    radius = 2.0 * nominal_spacing(Plane(), n)

    class OneHole(Flat):
        name, description = "one-hole", "unit square with a hole 4 spacings across"

        def _setup(self) -> Domain:
            return Domain(unit_square(), (Disk((0.57, 0.43), radius),))

    surface = build_surface(OneHole(), n, "graded", 1, 0.0)
    front = build_frontend(surface.points)
    assert len(front.boundary_loops) == 2 and front.diagnostics["boundary"]["n_small_holes"] == 1
    hole = front.boundary_loops[1]
    assert np.all(np.hypot(*(surface.points[hole, :2] - [0.57, 0.43]).T) < 1.6 * radius)
    assert len(set(hole.tolist()) & set(surface.boundary_loops[1].tolist())) >= 0.9 * len(surface.boundary_loops[1])


def test_a_loop_an_earlier_pruning_round_closed_is_kept_when_a_later_one_breaks_it():
    """The walk's steps are not local: with a small cycle's points dropped, a big cycle of the
    first round can be left with a dead end. With ``keep_broken`` it is returned still, where
    no later cycle took its points."""
    from parambench.methods.pointset.boundary import _pruned_cycles

    def step(active: np.ndarray) -> np.ndarray:
        succ = np.full(active.shape[0], -1, dtype=np.int64)
        succ[:10] = np.roll(np.arange(10), -1)  # a 10-point cycle
        succ[10], succ[11] = 11, 10  # a 2-point cycle, pruned in the first round
        if not active[10]:
            succ[9] = -1  # ... after which the big cycle has a dead end
        succ[12:20] = np.roll(np.arange(12, 20), -1)  # an 8-point cycle every round
        return np.where(active, succ, -1)

    candidates = np.ones(20, dtype=bool)
    plain, n_pruned = _pruned_cycles(step, candidates, 5)
    assert n_pruned == 1 and sorted(c.size for c in plain) == [8]
    kept, _ = _pruned_cycles(step, candidates, 5, keep_broken=True)
    assert sorted(c.size for c in kept) == [8, 10]
    np.testing.assert_array_equal(np.sort(kept[1]), np.arange(10))


@pytest.mark.slow
def test_slot_loop_survives_the_pruning_rounds():
    """slit, uniform random 100k, seed 5: the first walk closed the slot's 390-point loop, every
    later round left it a dead end, and the slot was lost (then the angle retry at 100 degrees
    found two false loops of 48 and 52 points, and ocp's map failed its check)."""
    s = make_surface("slit", 100000, sampling="random", seed=5)
    fe = build_frontend(s.points)
    assert len(fe.boundary_loops) == 2
    hit = (fe.boundary_mask & s.boundary_mask).sum()
    assert hit / s.boundary_mask.sum() >= 0.98 and hit / fe.boundary_mask.sum() >= 0.98
