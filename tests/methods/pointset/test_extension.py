"""Thinning a point set, and carrying a subsample's map to every point (``flatten --max-points``)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import Delaunay, cKDTree

from parambench.bench.cli import main
from parambench.bench.metrics import evaluate
from parambench.datasets_gen.errors import InvalidInputError
from parambench.datasets_gen.registry import make_surface
from parambench.methods.pointset.extension import extend_uv, thin_indices
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
