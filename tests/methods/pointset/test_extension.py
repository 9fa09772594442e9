"""Thinning a point set, and carrying a subsample's map to every point (``flatten --max-points``)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import Delaunay, cKDTree

from parambench.bench.cli import main
from parambench.bench.metrics import evaluate
from parambench.datasets_gen.errors import InvalidInputError
from parambench.datasets_gen.io import load_surface
from parambench.datasets_gen.registry import make_surface
from parambench.methods.pointset.extension import (LOST_HOLE_OUTLIER, extend_uv, map_through_subsample, thin_indices,
                                                    uncovered_spans)
from parambench.methods.registry import get_method


def _similarity_rms(a: np.ndarray, b: np.ndarray) -> float:
    """RMS distance of ``a`` from ``b`` after the best similarity (reflections allowed), over ``b``'s extent."""
    a0, b0 = a - a.mean(axis=0), b - b.mean(axis=0)
    za, zb = a0[:, 0] + 1j * a0[:, 1], b0[:, 0] + 1j * b0[:, 1]
    best = np.inf
    for target in (zb, zb.conj()):
        scale = (za.conj() @ target) / (za.conj() @ za)
        best = min(best, float(np.sqrt(np.mean(np.abs(scale * za - target) ** 2))))
    return best / float(np.ptp(b, axis=0).max())


@pytest.mark.parametrize("n,m", [(20000, 2000), (5000, 4000), (3000, 3000)])
def test_thinning_keeps_at_most_m_well_spread_points(n, m):
    rng = np.random.default_rng(1)
    pts = np.c_[rng.uniform(0.0, 1.0, (n, 2)), rng.uniform(0.0, 1e-3, n)]
    keep = thin_indices(pts, m)
    assert np.array_equal(keep, np.unique(keep)) and keep.size <= m
    if n == m:
        assert keep.size == n
        return
    assert keep.size >= 0.85 * m
    # spread: every input point lies within about two voxel cells of a kept one
    cell = 1.0 / np.sqrt(keep.size)
    assert cKDTree(pts[keep]).query(pts)[0].max() < 2.0 * cell
    assert np.array_equal(thin_indices(pts, m), keep)  # deterministic


def test_thinning_to_very_few_points():
    pts = np.random.default_rng(2).uniform(0.0, 1.0, (1000, 3))
    assert 1 <= thin_indices(pts, 3).size <= 3


def test_thinning_refuses_too_few():
    with pytest.raises(InvalidInputError, match="at least 3"):
        thin_indices(np.zeros((10, 3)), 2)


def test_a_map_linear_on_the_subsample_is_carried_exactly():
    """A tilted plane, its subsample mapped by a similarity of x, y (the exact conformal map):
    every point, inside the subsample's hull or beyond it, gets that map."""
    rng = np.random.default_rng(0)
    xy = rng.uniform(0.0, 1.0, (50000, 2))
    pts = np.c_[xy, 0.3 * xy[:, 0] + 0.1 * xy[:, 1]]
    exact = 2.0 * xy @ np.array([[0.8, -0.6], [0.6, 0.8]])
    keep = thin_indices(pts, 2000)
    faces = Delaunay(exact[keep]).simplices
    uv, facts = extend_uv(pts, keep, exact[keep], faces)
    assert np.abs(uv - exact).max() < 1e-6 * np.ptp(exact)
    assert np.array_equal(uv[keep], exact[keep])
    assert facts["offset_spacings"]["max"] < 1e-9 and facts["n_untriangulated"] == 0
    assert 0 < facts["n_outside"] < 0.1 * len(pts)  # the strip between the subsample's hull and the square's edge


def test_points_nearest_a_subsample_point_in_no_triangle_take_its_uv():
    """A unit square as two triangles, and a fifth subsample point far off in no triangle: the
    points near it take its uv and are counted (with it); the others are carried linearly."""
    sub_pts = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [5, 5, 0]], dtype=float)
    sub_uv = np.array([[0, 0], [2, 0], [2, 2], [0, 2], [9, -9]], dtype=float)
    pts = np.vstack([sub_pts, [[0.25, 0.5, 0.0], [5.1, 5.0, 0.0], [4.9, 5.1, 0.0]]])
    uv, facts = extend_uv(pts, np.arange(5), sub_uv, np.array([[0, 1, 2], [0, 2, 3]]))
    assert np.allclose(uv[5], [0.5, 1.0]) and np.allclose(uv[6:], [[9, -9], [9, -9]])
    assert facts["n_untriangulated"] == 3 and facts["n_outside"] == 0  # the lone point itself, and the two near it


def test_extend_uv_checks_its_inputs():
    with pytest.raises(InvalidInputError):
        extend_uv(np.zeros((5, 3)), np.arange(3), np.zeros((2, 2)), np.array([[0, 1, 2]]))
    with pytest.raises(InvalidInputError):
        extend_uv(np.zeros((5, 3)), np.arange(3), np.zeros((3, 2)), np.zeros((0, 3), dtype=np.int64))


def test_flatten_max_points_maps_every_point_near_the_full_map(tmp_path, capsys):
    """bump, 20k random points, mapped through a subsample of at most 5,000: one uv row per input
    point, within 3e-3 of the diameter of scp-igl's map of the true mesh, QC within 0.5 % of its
    QC and no folded triangle; the .obj's faces are the subsample's (rows of the input)."""
    s = make_surface("bump", 20000, sampling="random", seed=0)
    src = tmp_path / "cloud.xyz"
    np.savetxt(src, s.points)
    assert main(["flatten", str(src), "--max-points", "5000", "-o", str(tmp_path / "uv.csv")]) == 0
    out, err = capsys.readouterr()
    assert "(a subsample of" in out and "--max-points" in out and "take the uv of their place" in err
    uv = np.loadtxt(tmp_path / "uv.csv", delimiter=",", skiprows=1)
    assert uv.shape == (s.n_points, 2)
    reference = get_method("scp-igl")(s).uv
    assert _similarity_rms(uv, reference) < 3e-3
    ours, theirs = evaluate(s.points, s.faces, uv), evaluate(s.points, s.faces, reference)
    assert ours["foldovers"] == 0 and ours["qc_mean"] <= 1.005 * theirs["qc_mean"]
    assert main(["flatten", str(src), "--max-points", "5000", "-o", str(tmp_path / "uv.obj")]) == 0
    lines = (tmp_path / "uv.obj").read_text().splitlines()
    assert sum(line.startswith("vt ") for line in lines) == s.n_points
    face_rows = np.array([[int(v.split("/")[0]) - 1 for v in line.split()[1:]] for line in lines if line.startswith("f ")])
    assert len(np.unique(face_rows)) <= 5000


def test_max_points_is_for_point_sets_and_at_least_three(tmp_path, capsys):
    mesh = make_surface("bump", 500, seed=0)
    src = tmp_path / "mesh.obj"
    src.write_text("".join(f"v {x} {y} {z}\n" for x, y, z in mesh.points)
                   + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in mesh.faces))
    assert main(["flatten", str(src), "--max-points", "100", "-o", str(tmp_path / "uv.obj")]) == 2
    assert "--max-points thins a point set" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:
        main(["flatten", str(src), "--points-only", "--max-points", "2", "-o", str(tmp_path / "uv.obj")])
    assert exc.value.code == 2 and "at least 3" in capsys.readouterr().err


def _plane_with_hole(radius_steps: float, n: int = 20000, seed: int = 0):
    """A jittered grid of about ``n`` points on a gently curved sheet, less a disk of ``radius_steps`` grid steps."""
    rng = np.random.default_rng(seed)
    h = 1.0 / np.sqrt(n)
    xy = np.stack(np.meshgrid(np.arange(0.0, 1.0, h), np.arange(0.0, 1.0, h)), -1).reshape(-1, 2)
    xy = xy + rng.uniform(-0.3, 0.3, xy.shape) * h
    xy = xy[np.linalg.norm(xy - 0.5, axis=1) > radius_steps * h]
    return np.c_[xy, 0.1 * np.sin(3.0 * xy[:, 0]) * np.cos(2.0 * xy[:, 1])], radius_steps * h


def _delaunay_inside(xy: np.ndarray) -> np.ndarray:
    """Delaunay triangles of ``xy`` in the unit square less the convex hull's slivers along its
    rim (an edge over 2.5 times the median, near the square's sides): the triangles a map's
    self-check keeps inside the outer loop."""
    faces = Delaunay(xy).simplices
    longest = np.linalg.norm(xy[faces] - xy[np.roll(faces, 1, axis=1)], axis=2).max(axis=1)
    centre = xy[faces].mean(axis=1)
    near_rim = np.minimum(centre, 1.0 - centre).min(axis=1) < 0.05
    return faces[~(near_rim & (longest > 2.5 * np.median(longest)))]


def test_triangles_across_a_hole_the_thinning_closed_are_found():
    """A hole 4 grid steps in radius, thinned to a quarter: triangles of the subsample spanning it
    are found, at the hole; triangles that leave the hole open, and a sheet with no hole, are not."""
    pts, radius = _plane_with_hole(4.0)
    keep = thin_indices(pts, pts.shape[0] // 4)
    faces = _delaunay_inside(pts[keep, :2])
    spans = uncovered_spans(pts, keep, faces)
    assert spans["lost_hole"] and spans["n_spanning_faces"] >= 1
    assert spans["gap_spacings"]["max"] >= LOST_HOLE_OUTLIER * spans["gap_spacings"]["typical"]
    assert np.linalg.norm(np.array(spans["where"][:2]) - 0.5) < radius
    # the same subsample triangulated with the hole kept open
    centroids = pts[keep][faces].mean(axis=1)[:, :2]
    open_faces = faces[np.linalg.norm(centroids - 0.5, axis=1) > radius]
    assert not uncovered_spans(pts, keep, open_faces)["lost_hole"]
    # no hole at all
    sheet, _ = _plane_with_hole(0.0)
    keep = thin_indices(sheet, sheet.shape[0] // 4)
    intact = uncovered_spans(sheet, keep, _delaunay_inside(sheet[keep, :2]))
    assert not intact["lost_hole"] and intact["n_spanning_faces"] == 0 and intact["gap_spacings"]["max"] < 1.0


def test_a_random_samplings_own_voids_are_no_lost_hole():
    """Uniform random points have voids up to about two local spacings wide; a subsample's
    triangles over them are not a lost hole."""
    rng = np.random.default_rng(3)
    xy = rng.uniform(0.0, 1.0, (40000, 2))
    pts = np.c_[xy, 0.05 * np.sin(4.0 * xy[:, 0])]
    keep = thin_indices(pts, 10000)
    spans = uncovered_spans(pts, keep, _delaunay_inside(pts[keep, :2]))
    assert not spans["lost_hole"] and spans["gap_spacings"]["typical"] > 1.0


def test_flatten_max_points_refuses_a_map_that_lost_a_hole(tmp_path, capsys):
    """The LiDAR ground returns (rim and one small hole) thinned to about a third: the subsample's
    map closes the hole and passes its own check; the full points show it (exit 3, nothing
    written, the place named); --force writes it with a warning; at half the hole is kept."""
    s = make_surface("real/lidar-ground")
    src = tmp_path / "ground.xyz"
    np.savetxt(src, s.points)
    out = tmp_path / "uv.obj"
    assert main(["flatten", str(src), "--max-points", "3400", "-o", str(out)]) == 3
    captured = capsys.readouterr()
    assert "leave empty" in captured.err and "raise --max-points" in captured.err and "nothing written" in captured.out
    assert not out.exists()
    assert main(["flatten", str(src), "--max-points", "3400", "--force", "-o", str(out)]) == 0
    assert "written anyway: --force" in capsys.readouterr().err and out.exists()
    # ... without the triangles across the hole: the written faces leave it open
    written = load_surface(out)
    assert written.n_points == s.n_points
    assert not uncovered_spans(s.points, np.arange(s.n_points), written.faces)["lost_hole"]
    assert main(["flatten", str(src), "--max-points", "4800", "-o", str(tmp_path / "half.obj")]) == 0
    err = capsys.readouterr().err
    assert "leave empty" not in err and "the input covers them" in err


def test_an_error_on_the_subsample_says_it_is_the_subsample(tmp_path, capsys):
    """bunny10k's scan (5 holes) thinned to under 3,000 points: the subsample's rims are too sparse
    for a loop to close. The error (exit 2) says it came from the --max-points subsample and
    to raise --max-points, not only to cut a closed surface open."""
    src = tmp_path / "bunny.xyz"
    np.savetxt(src, make_surface("real/bunny10k").points)
    assert main(["flatten", str(src), "--max-points", "3000", "-o", str(tmp_path / "uv.obj")]) == 2
    err = capsys.readouterr().err
    assert "NoBoundaryError" in err and "--max-points subsample (2,926 of the 5,051 points)" in err
    assert err.rstrip().endswith("raise --max-points.")


def test_mapping_through_a_subsample_from_python():
    """``map_through_subsample`` does what ``flatten --max-points`` does: the LiDAR ground at about a
    third loses its hole (not passed, the lost hole reported, every point's uv still there); at
    about half it keeps it (passed, faces over the subsample's points only, the subsample's own
    uv unchanged); not thinned when the points fit; a mesh method refused."""
    points = make_surface("real/lidar-ground").points
    lost = map_through_subsample("ocp", points, 3400)
    assert lost.result.diagnostics["selfcheck"]["passed"] and lost.carried.spans["lost_hole"] and not lost.passed
    kept = map_through_subsample("ocp", points, 4800)
    assert kept.passed and kept.uv.shape == (points.shape[0], 2) and np.isfinite(kept.uv).all()
    assert np.isin(kept.carried.faces, kept.subsample).all()
    assert np.array_equal(kept.uv[kept.subsample], kept.result.uv)
    small = make_surface("bump", 600, seed=0).points
    whole = map_through_subsample("ocp", small, 1000)
    assert whole.carried is None and whole.subsample.size == small.shape[0] and whole.uv is whole.result.uv
    with pytest.raises(InvalidInputError, match="needs faces"):
        map_through_subsample("scp-igl", small, 100)
