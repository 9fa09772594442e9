"""Points filling a point set's holes (methods/pointset/hole_filling.py)."""

from __future__ import annotations

import numpy as np
from matplotlib.path import Path
from scipy.spatial import cKDTree

from parambench.datasets_gen.surface import MethodInput
from parambench.methods.pointset.hole_filling import fill_point_holes, hole_fill_points

H = 0.05  # lattice spacing of the synthetic samples
R_HOLE = 0.3


def _saddle_with_hole():
    """z = x^2 - y^2 sampled on a square lattice outside a disk, the disk's rim as the loop."""
    g = np.arange(-1.0, 1.0 + 1e-9, H)
    x, y = (a.ravel() for a in np.meshgrid(g, g))
    keep = np.hypot(x, y) > R_HOLE + 0.6 * H
    t = np.linspace(0.0, 2.0 * np.pi, int(2 * np.pi * R_HOLE / H), endpoint=False)[::-1]  # clockwise: a hole
    xs = np.concatenate([x[keep], R_HOLE * np.cos(t)])
    ys = np.concatenate([y[keep], R_HOLE * np.sin(t)])
    pts = np.column_stack([xs, ys, xs**2 - ys**2])
    nrm = np.column_stack([-2 * xs, 2 * ys, np.ones_like(xs)])
    nrm /= np.linalg.norm(nrm, axis=1)[:, None]
    loop = np.arange(int(keep.sum()), len(xs))
    return pts, nrm, loop


def test_fill_points_lie_inside_the_hole_on_the_quadratic_through_its_loop():
    pts, nrm, loop = _saddle_with_hole()
    fill = hole_fill_points(pts, nrm, loop, H)
    # The loop lies on a quadratic graph over a plane close to z = 0: the fit recovers it.
    assert np.allclose(fill[:, 2], fill[:, 0] ** 2 - fill[:, 1] ** 2, atol=1e-9)
    assert np.hypot(fill[:, 0], fill[:, 1]).max() < R_HOLE
    assert cKDTree(pts).query(fill)[0].min() >= 0.5 * H - 1e-12
    # A hexagonal lattice at spacing H holds area / (sqrt(3)/2 H^2) points; the clearance
    # from the rim takes a band of about half a spacing.
    expected = np.pi * (R_HOLE - 0.5 * H) ** 2 / (np.sqrt(3) / 2 * H**2)
    assert 0.7 * expected <= len(fill) <= 1.3 * expected


def test_a_hole_narrower_than_the_lattice_gets_the_finer_one():
    # A slot 1.2 spacings wide: the coarse lattice leaves no point clear of both lips.
    xs = np.arange(-0.5, 0.5 + 1e-9, H)
    lips = [np.column_stack([xs, np.full_like(xs, y), np.zeros_like(xs)]) for y in (-0.6 * H, 0.6 * H)]
    pts = np.vstack([lips[0], lips[1][::-1]])
    loop = np.arange(len(pts))
    fill = hole_fill_points(pts, np.tile([0.0, 0.0, 1.0], (len(pts), 1)), loop, H)
    assert len(fill) > 0
    assert np.abs(fill[:, 1]).max() < 0.6 * H and np.abs(fill[:, 2]).max() < 1e-12
    assert cKDTree(pts).query(fill)[0].min() >= 0.3 * H - 1e-12


def test_a_loop_whose_projection_is_not_a_simple_turn_gets_no_points():
    t = np.linspace(0.0, 2.0 * np.pi, 40, endpoint=False)
    figure8 = np.column_stack([np.sin(t), np.sin(t) * np.cos(t), np.zeros_like(t)])
    fill = hole_fill_points(figure8, np.tile([0.0, 0.0, 1.0], (40, 1)), np.arange(40), 0.05)
    assert fill.shape == (0, 3)


def test_fill_point_holes_keeps_the_original_rows_first_and_skips_the_outer_loop():
    pts, nrm, loop = _saddle_with_hole()
    outer = np.flatnonzero(np.maximum(np.abs(pts[:, 0]), np.abs(pts[:, 1])) > 1.0 - 1e-9)
    surface = MethodInput(pts, normals=nrm, name="saddle with a hole")
    filled, n = fill_point_holes(surface, nrm, [outer, loop], np.full(len(pts), H))
    assert n == 1 and filled.n_points > surface.n_points
    assert np.array_equal(filled.points[: surface.n_points], pts)
    added = filled.points[surface.n_points:]
    assert Path(pts[loop, :2]).contains_points(added[:, :2]).all()
    assert np.allclose(np.linalg.norm(filled.normals, axis=1), 1.0)
    # Only the outer loop: nothing to fill, the same object back.
    same, none = fill_point_holes(surface, nrm, [outer], np.full(len(pts), H))
    assert same is surface and none == 0


def test_loop_width_of_a_slot_and_a_disc():
    from parambench.methods.pointset.hole_filling import loop_width
    # A 10 x 1 rectangle, sampled every 0.1 along its sides, tilted out of the xy plane.
    t = np.arange(0.0, 10.0, 0.1)
    s = np.arange(0.0, 1.0, 0.1)
    xy = np.vstack([np.column_stack([t, np.zeros_like(t)]), np.column_stack([np.full_like(s, 10.0), s]),
                    np.column_stack([10.0 - t, np.ones_like(t)]), np.column_stack([np.zeros_like(s), 1.0 - s])])
    rot = np.array([[1.0, 0.0, 0.0], [0.0, np.cos(0.7), np.sin(0.7)], [0.0, -np.sin(0.7), np.cos(0.7)]])
    pts = np.column_stack([xy, np.zeros(len(xy))]) @ rot.T
    normals = np.tile(rot @ np.array([0.0, 0.0, 1.0]), (len(pts), 1))
    loop = np.arange(len(pts))
    assert abs(loop_width(pts, normals, loop) - 2 * 10.0 / 22.0) < 1e-9
    assert abs(loop_width(pts, normals, loop[::-1]) - 2 * 10.0 / 22.0) < 1e-9  # orientation does not matter
    a = np.linspace(0.0, 2 * np.pi, 400, endpoint=False)
    circle = np.column_stack([3.0 * np.cos(a), 3.0 * np.sin(a), np.zeros_like(a)])
    assert abs(loop_width(circle, np.tile([0.0, 0.0, 1.0], (400, 1)), np.arange(400)) - 3.0) < 1e-3


def test_is_slot_needs_narrow_and_long():
    from parambench.methods.pointset.hole_filling import is_slot
    a = np.linspace(0.0, 2 * np.pi, 200, endpoint=False)
    up = np.tile([0.0, 0.0, 1.0], (200, 1))
    disc = np.column_stack([np.cos(a), np.sin(a), np.zeros_like(a)])  # width 1
    slot = np.column_stack([20.0 * np.cos(a), 0.5 * np.sin(a), np.zeros_like(a)])  # about 1 wide, 80 around
    loop = np.arange(200)
    assert not is_slot(disc, up, loop, 1.0)  # narrow, but round
    assert is_slot(slot, up, loop, 1.0)
    assert not is_slot(slot, up, loop, 0.2)  # 5 spacings wide: not narrow
