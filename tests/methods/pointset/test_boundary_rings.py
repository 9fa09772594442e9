"""The rings boundary detector (tangent-plane Delaunay one-rings, alpha test) on hand-made
and generated point sets, against known boundaries."""

from __future__ import annotations

import numpy as np
import pytest

from parambench.datasets_gen.errors import InvalidInputError, NoBoundaryError
from parambench.datasets_gen.registry import make_surface
from parambench.datasets_gen.surface import Surface
from parambench.methods import get_method
from parambench.methods.geometry2d import signed_area_2d
from parambench.methods.pointset.frontend import build_frontend
from parambench.methods.pointset.plugin_support import FRONTEND_DEFAULTS


def _grid(n: int = 40) -> np.ndarray:
    x, y = np.meshgrid(np.arange(n, dtype=float), np.arange(n, dtype=float))
    rng = np.random.default_rng(0)
    pts = np.column_stack([x.ravel(), y.ravel(), np.zeros(n * n)])
    pts[:, :2] += rng.uniform(-0.1, 0.1, (n * n, 2))  # breaks the grid's cocircular ties
    return pts


def _outer_ids(points: np.ndarray, n: int) -> np.ndarray:
    ij = np.rint(points[:, :2]).astype(int)
    return np.flatnonzero((ij == 0).any(axis=1) | (ij == n - 1).any(axis=1))


def test_slot_two_spacings_wide_is_a_hole():
    """A grid with a slot (rows 19-20 removed for x in 8..31, so its lips are 3 rows apart,
    2 empty rows): the slot is a second, clockwise loop holding every lip point; the
    angle detector's balls (2.5 spacings) reach across it."""
    n = 40
    pts = _grid(n)
    ij = np.rint(pts[:, :2]).astype(int)
    slot = (ij[:, 1] >= 19) & (ij[:, 1] <= 20) & (ij[:, 0] >= 8) & (ij[:, 0] <= 31)
    pts, ij = pts[~slot], ij[~slot]
    lips = np.flatnonzero(((ij[:, 1] == 18) | (ij[:, 1] == 21)) & (ij[:, 0] >= 8) & (ij[:, 0] <= 31))
    fe = build_frontend(pts, boundary_method="rings")
    assert len(fe.boundary_loops) == 2
    outer, hole = fe.boundary_loops
    assert np.isin(_outer_ids(pts, n), outer).all()
    assert np.isin(lips, hole).all()
    assert signed_area_2d(pts[outer, :2]) > 0 > signed_area_2d(pts[hole, :2])


def test_one_missing_point_is_not_a_hole():
    """A single missing grid point leaves a void one spacing across, which the detector
    treats as a void of the sampling (a loop must enclose 8 squared spacings): the only
    loop is the outer one, complete and counter-clockwise."""
    n = 30
    pts = _grid(n)
    ij = np.rint(pts[:, :2]).astype(int)
    pts = pts[~((ij[:, 0] == 15) & (ij[:, 1] == 15))]
    fe = build_frontend(pts, boundary_method="rings")
    assert len(fe.boundary_loops) == 1
    assert set(fe.boundary_loops[0].tolist()) == set(_outer_ids(pts, n).tolist())
    assert signed_area_2d(pts[fe.boundary_loops[0], :2]) > 0


@pytest.mark.parametrize("seed", [0, 1])
def test_random_sample_without_holes_has_one_loop(seed):
    """Uniform random points in a disc plus 100 points on its rim: one loop, the rim."""
    rng = np.random.default_rng(seed)
    r = np.sqrt(rng.random(2500)) * 0.96
    t = rng.random(2500) * 2 * np.pi
    rim_t = np.linspace(0, 2 * np.pi, 100, endpoint=False)
    xy = np.concatenate([np.column_stack([r * np.cos(t), r * np.sin(t)]),
                         np.column_stack([np.cos(rim_t), np.sin(rim_t)])])
    pts = np.column_stack([xy, np.zeros(len(xy))])
    fe = build_frontend(pts, boundary_method="rings")
    assert len(fe.boundary_loops) == 1
    loop = fe.boundary_loops[0]
    rim = np.arange(2500, 2600)
    assert np.isin(rim, loop).mean() >= 0.97
    assert np.isin(loop, rim).mean() >= 0.9


# Cases measured to meet the targets (correct loop count, recall >= 0.97,
# precision >= 0.9), a sample of those that do (every noise-free random and graded
# surface but holes-bumped at 2k graded, slit and fold); the slot of ``slit`` is found
# on jittered samplings, where the angle detector loses it.
MEASURED = ["slit:2000:jittered", "slit:20000:jittered", "holes:2000:random", "holes:20000:graded",
            "holes-bumped:2000:random", "cap:2000:random", "bump:2000:graded", "gnome-strip:20000:random",
            "real/lilium:0:-", "real/bump-domain:0:-"]


@pytest.mark.parametrize("spec", MEASURED)
def test_measured_surfaces_meet_targets(spec):
    name, n, sampling = spec.split(":")
    surface = (make_surface(name, 0) if name.startswith("real/")
               else make_surface(name, int(n), sampling=sampling, seed=0))
    fe = build_frontend(surface.points, boundary_method="rings")
    truth = surface.boundary_mask
    found = fe.boundary_mask
    assert len(fe.boundary_loops) == len(surface.boundary_loops)
    assert (found & truth).sum() / truth.sum() >= 0.97
    assert (found & truth).sum() / found.sum() >= 0.9


def test_option_is_a_frontend_parameter_and_checked():
    assert FRONTEND_DEFAULTS["boundary_method"] == "angle"
    with pytest.raises(InvalidInputError, match="boundary_method"):
        build_frontend(_grid(12), boundary_method="alpha")


def test_point_set_method_accepts_the_option():
    """ocp takes boundary_method like any front-end parameter and passes it on: its
    diagnostics name the detector, and on a plain random patch both detectors give the
    same loop, so the same map."""
    surface = make_surface("bump", 2000, sampling="random", seed=0)
    inp = Surface(points=surface.points, name="bump")
    ocp = get_method("ocp")
    rings = ocp(inp, boundary_method="rings")
    angle = ocp(inp)
    assert rings.diagnostics["boundary_method"] == "rings"
    assert angle.diagnostics["boundary_method"] == "angle"
    np.testing.assert_allclose(rings.uv, angle.uv, atol=1e-8 * np.ptp(angle.uv))


def test_closed_surface_raises_with_a_rings_message():
    """A closed sphere sample has no boundary: NoBoundaryError naming the option to try."""
    rng = np.random.default_rng(0)
    v = rng.normal(size=(1500, 3))
    pts = v / np.linalg.norm(v, axis=1, keepdims=True)
    with pytest.raises(NoBoundaryError, match="boundary_method='angle'"):
        build_frontend(pts, boundary_method="rings")
