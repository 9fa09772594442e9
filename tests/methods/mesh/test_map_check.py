"""The check of mesh maps: flipped and collapsed triangles are failures, a mirror image is not."""

from __future__ import annotations

import numpy as np
import pytest

from parambench.bench.cli import main
from parambench.bench.metrics import evaluate
from parambench.datasets_gen.io import load_surface
from parambench.datasets_gen.real import real_data_dir
from parambench.datasets_gen.surface import Surface
from parambench.methods import get_method
from parambench.methods.mesh.map_check import check_mesh_map


def real_mesh_path(name: str):
    return real_data_dir() / f"{name}.obj"


def _grid(n: int = 6):
    x, y = np.meshgrid(np.arange(n, dtype=float), np.arange(n, dtype=float))
    pts = np.c_[x.ravel(), y.ravel(), np.zeros(n * n)]
    i = np.arange(n * n).reshape(n, n)[:-1, :-1].ravel()
    return pts, np.r_[np.c_[i, i + 1, i + n + 1], np.c_[i, i + n + 1, i + n]]


def test_the_identity_and_its_mirror_pass():
    pts, faces = _grid()
    for uv in (pts[:, :2], pts[:, :2] * [-1.0, 1.0]):
        check = check_mesh_map(pts, faces, uv)
        assert check["passed"] and check["n_flipped"] == 0 and check["n_degenerate"] == 0


def test_a_vertex_pushed_across_its_neighbours_flips_their_triangles():
    pts, faces = _grid()
    uv = pts[:, :2].copy()
    uv[14] += [1.6, 0.0]  # interior vertex (2, 2) pushed past its right neighbour
    check = check_mesh_map(pts, faces, uv)
    d1, d2 = uv[faces[:, 1]] - uv[faces[:, 0]], uv[faces[:, 2]] - uv[faces[:, 0]]
    flipped = np.flatnonzero(d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0] < 0)
    assert not check["passed"] and check["failed"] == ["flipped"]
    assert check["n_flipped"] == flipped.size > 0
    assert check["flipped_faces"] == flipped[:3].tolist()
    assert check["n_folded_3d"] == 0  # the mesh is flat: the fold is the map's


def test_collapsed_and_non_finite_uv_are_degenerate():
    pts, faces = _grid()
    uv = pts[:, :2].copy()
    uv[7] = uv[8]  # two vertices of shared triangles on one uv point
    check = check_mesh_map(pts, faces, uv)
    assert "degenerate" in check["failed"] and check["n_degenerate"] == 2
    uv = pts[:, :2].copy()
    uv[3] = np.nan
    check = check_mesh_map(pts, faces, uv)
    assert check["n_nonfinite"] == 1 and check["n_degenerate"] == int(np.isin(faces, 3).any(axis=1).sum())
    assert "non-finite" in check["reason"]


def test_a_fold_of_the_mesh_itself_is_named():
    pts, faces = _grid()
    # Vertex (2, 2) lifted far above the plane and beyond its neighbours: its triangles turn over in 3D.
    pts = pts.copy()
    pts[14] = [4.6, 2.0, 0.3]
    uv = pts[:, :2]
    check = check_mesh_map(pts, faces, uv)
    assert check["n_flipped"] > 0 and check["n_folded_3d"] == check["n_flipped"]


@pytest.mark.parametrize("method", ["scp", "dncp-opt", "scp-igl"])
def test_a_real_mesh_folded_in_3d_fails_its_check_as_the_evaluation_counts(method):
    """``real/cortex-lh`` holds a triangle folded back against its neighbour: every method flips
    it in uv. The check's count agrees with the evaluation's own foldover count."""
    cortex = load_surface(real_mesh_path("cortex-lh"))
    result = get_method(method)(Surface(cortex.points, cortex.faces, name="cortex-lh"))
    check = result.diagnostics["selfcheck"]
    assert check["kind"] == "mesh" and not check["passed"]
    assert check["n_flipped"] == evaluate(cortex.points, cortex.faces, result.uv)["foldovers"] >= 1
    assert check["n_folded_3d"] >= 1


def test_flatten_refuses_a_flipped_mesh_map_unless_forced(tmp_path, capsys):
    src = real_mesh_path("cortex-lh")
    out = tmp_path / "uv.obj"
    assert main(["flatten", str(src), "-o", str(out)]) == 3
    captured = capsys.readouterr()
    assert not out.exists() and "self-check FAILED: 1 flipped" in captured.out
    assert "the mesh folds back on itself at those faces" in captured.err and "--force" in captured.err
    assert main(["flatten", str(src), "--force", "-o", str(out)]) == 0
    assert out.exists() and "written anyway" in capsys.readouterr().err


def test_a_clean_mesh_map_passes_and_flatten_says_so(tmp_path, capsys):
    out = tmp_path / "uv.obj"
    assert main(["flatten", str(real_mesh_path("lilium")), "-o", str(out)]) == 0
    assert "self-check ok: 0 flipped, 0 degenerate" in capsys.readouterr().out


def test_the_advice_follows_what_failed():
    from parambench.methods.pointset.selfcheck_advice import mesh_advice

    flips = {"n_flipped": 2, "n_folded_3d": 0, "n_nonfinite": 0}
    assert mesh_advice(flips, {"weights": "uniform"}, "scp") == "try --param weights=hybrid"
    assert mesh_advice(flips, {}, "lscm-igl") == "try --method scp --param weights=hybrid"
    assert "remesh" in mesh_advice(flips, {"weights": "hybrid"}, "scp")
    assert "folds back on itself" in mesh_advice({**flips, "n_folded_3d": 2}, {"weights": "uniform"}, "scp")
    shrunk = {"n_flipped": 0, "n_folded_3d": 0, "n_nonfinite": 0, "n_degenerate": 40}
    assert "protrusion" in mesh_advice(shrunk, {"weights": "cotangent"}, "scp")
    assert "no uv" in mesh_advice({**shrunk, "n_nonfinite": 1}, {}, "scp-igl")


def _helical_ribbon(turns: float = 1.5, n_along: int = 300, n_across: int = 8):
    """A ribbon winding ``turns`` times round a helix (radius 1, width 0.3, pitch 0.6): a disk, no self-contact."""
    t = np.linspace(0.0, 2 * np.pi * turns, n_along)[:, None]
    s = np.linspace(-0.15, 0.15, n_across)[None, :]
    pts = np.stack([(1 + s) * np.cos(t), (1 + s) * np.sin(t), 0.6 * t / (2 * np.pi) + 0 * s], axis=-1).reshape(-1, 3)
    i = np.arange(n_along * n_across).reshape(n_along, n_across)[:-1, :-1].ravel()
    faces = np.r_[np.c_[i, i + n_across, i + n_across + 1], np.c_[i, i + n_across + 1, i + 1]]
    return pts, faces


@pytest.mark.parametrize("method", ["scp", "scp-igl", "lscm-igl"])
def test_a_map_that_winds_over_itself_fails_without_a_flip(method):
    """Before: a helical ribbon of 1.5 turns mapped round 1.5 times with 0 flips, "self-check ok", exit 0."""
    pts, faces = _helical_ribbon()
    check = get_method(method)(Surface(pts, faces, name="ribbon")).diagnostics["selfcheck"]
    assert check["n_flipped"] == 0 and check["n_boundary_crossings"] > 0
    assert check["n_crossings_of_holes"] == 0  # its one loop, apart on the surface: no hole drifted
    assert not check["passed"] and check["failed"] == ["boundary-crossing"]
    assert "crosses itself" in check["reason"]
    # Less than one turn lies flat: the same strip of 0.8 turns passes.
    pts, faces = _helical_ribbon(turns=0.8)
    check = get_method(method)(Surface(pts, faces, name="ribbon")).diagnostics["selfcheck"]
    assert check["passed"] and check["n_boundary_crossings"] == 0


def test_flatten_refuses_the_overlapping_ribbon_with_advice(tmp_path, capsys):
    import igl
    pts, faces = _helical_ribbon()
    src = tmp_path / "ribbon.obj"
    igl.write_triangle_mesh(str(src), pts, faces)
    assert main(["flatten", str(src), "-o", str(tmp_path / "uv.obj")]) == 3
    err = capsys.readouterr().err
    assert "crosses itself" in err and "winds round" in err and not (tmp_path / "uv.obj").exists()
