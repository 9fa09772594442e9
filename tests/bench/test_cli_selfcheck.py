"""flatten and inspect report the point-set self-check; failing maps are not written silently."""

from __future__ import annotations

import json

import numpy as np
import pytest

from parambench.bench.cli import EXIT_SELFCHECK, main


@pytest.fixture(scope="module")
def bump_xyz(tmp_path_factory):
    from parambench.datasets_gen.registry import make_surface

    surface = make_surface("bump", 900, sampling="jittered", seed=0)
    path = tmp_path_factory.mktemp("in") / "bump.xyz"
    np.savetxt(path, surface.points, fmt="%.17g")
    return path, surface.points


def test_failing_map_exits_3_with_one_line_and_no_file(bump_xyz, tmp_path, capsys):
    src, _ = bump_xyz
    out = tmp_path / "spin.obj"
    assert main(["flatten", str(src), "--method", "scp-tan", "-o", str(out)]) == EXIT_SELFCHECK == 3
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert len(err) == 1 and "self-check" in err[0] and "turns" in err[0]
    assert "--param k=10" in err[0]  # a parameter scp-tan has
    assert not out.exists()
    assert "self-check FAILED" in captured.out and len(captured.out.strip().splitlines()) == 1


def test_suggested_parameter_fixes_the_map(bump_xyz, tmp_path):
    src, _ = bump_xyz
    out = tmp_path / "fixed.csv"
    assert main(["flatten", str(src), "--method", "scp-tan", "--param", "k=10", "-o", str(out)]) == 0
    assert out.exists()


def test_force_writes_the_failing_map_with_a_warning(bump_xyz, tmp_path, capsys):
    src, points = bump_xyz
    out = tmp_path / "spin.obj"
    assert main(["flatten", str(src), "--method", "scp-tan", "--force", "-o", str(out)]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("parambench: warning:")
    assert out.exists() and sum(line.startswith("vt ") for line in out.read_text().splitlines()) == len(points)


@pytest.fixture(scope="module")
def sdp_outputs(bump_xyz, tmp_path_factory):
    """flatten --points-only with sdp to .obj and .ply, and the map itself."""
    from parambench.datasets_gen.surface import Surface
    from parambench.methods import get_method
    from parambench.methods.pointset.selfcheck import pointset_faces

    src, points = bump_xyz
    root = tmp_path_factory.mktemp("out")
    for ext in ("obj", "ply"):
        assert main(["flatten", str(src), "--points-only", "--method", "sdp", "-o", str(root / f"m.{ext}")]) == 0
    result = get_method("sdp")(Surface(points=points, name="bump"))
    faces = pointset_faces(points, result.uv, result.diagnostics["boundary_loops"])
    return root, points, result.uv, faces


def _same_faces(a, b):
    canon = lambda f: np.unique(np.sort(f, axis=1), axis=0)  # noqa: E731 - rotation-free comparison
    return a.shape == b.shape and np.array_equal(canon(a), canon(b))


def test_obj_of_a_point_set_opens_as_a_textured_mesh(sdp_outputs):
    import igl

    root, points, uv, faces = sdp_outputs
    v, tc, _, f, ftc, _ = igl.readOBJ(str(root / "m.obj"))
    assert v.shape == points.shape and np.allclose(v, points, rtol=0, atol=1e-12)  # input order
    assert tc.shape == uv.shape and np.allclose(tc, uv, rtol=0, atol=1e-12)
    assert np.array_equal(f, ftc)  # f i/i: the same index for v and vt
    assert _same_faces(f, faces) and len(f) > len(points)
    assert np.setdiff1d(np.arange(len(points)), f.ravel()).size == 0  # every point is in a face


def test_ply_of_a_point_set_has_xyz_texture_uv_and_faces(sdp_outputs):
    import pymeshlab

    root, points, uv, faces = sdp_outputs
    ms = pymeshlab.MeshSet()
    ms.load_new_mesh(str(root / "m.ply"))
    mesh = ms.current_mesh()
    assert mesh.vertex_number() == len(points) and mesh.face_number() == len(faces)
    assert np.allclose(mesh.vertex_matrix(), points, atol=1e-6)
    assert mesh.has_vertex_tex_coord()
    assert np.allclose(mesh.vertex_tex_coord_matrix(), uv, atol=1e-5 * np.abs(uv).max())
    assert _same_faces(mesh.face_matrix().astype(np.int64), faces)


def test_inspect_writes_loop_coverage(bump_xyz, tmp_path, capsys):
    src, points = bump_xyz
    out = tmp_path / "front.json"
    assert main(["inspect", str(src), "-o", str(out)]) == 0
    cov = json.loads(out.read_text())["selfcheck"]["coverage"]
    assert cov["passed"] and 0 < cov["n_candidates"] < len(points) and cov["n_uncovered"] < cov["n_candidates"]
    text = capsys.readouterr().out
    assert "loop coverage ok" in text and "does not resolve" not in text
    assert json.loads(out.read_text())["selfcheck"]["n_unresolved"] == 0


def test_inspect_names_the_points_the_sampling_does_not_resolve(tmp_path, capsys):
    # protrusions' fingertips are thinner than 2k points sample: neighbours' normals turn away.
    from parambench.datasets_gen.registry import make_surface

    src = tmp_path / "protrusions.xyz"
    np.savetxt(src, make_surface("protrusions", 2000, sampling="jittered", seed=1).points)
    out = tmp_path / "front.json"
    assert main(["inspect", str(src), "-o", str(out)]) == 0
    n = json.loads(out.read_text())["selfcheck"]["n_unresolved"]
    assert 20 < n < 400
    assert f", {n} point(s) where the sampling does not resolve the surface" in capsys.readouterr().out


def test_flatten_summary_names_uncertain_flips_only_when_there_are_some():
    from parambench.bench.cli import _selfcheck_summary

    check = {"passed": True, "n_triangles": 3900, "n_flipped": 0, "n_degenerate": 0, "normal_tol_deg": 10.0}
    assert _selfcheck_summary(check) == "; self-check ok: 0 flipped, 0 degenerate of 3900 triangles"
    text = _selfcheck_summary(dict(check, n_flipped_uncertain=2))
    assert "0 flipped (+2 within the normals' error of 10 deg), 0 degenerate" in text
    text = _selfcheck_summary(dict(check, passed=False, n_ring_flipped=1))
    assert text.startswith("; self-check FAILED: 0 flipped, 1 triangle(s) of neighbouring points reversed, "
                           "0 degenerate")
    text = _selfcheck_summary(dict(check, n_unresolved=46))
    assert text.endswith("of 3900 triangles, 46 point(s) where the sampling does not resolve the surface (neighbouring "
                         "normals over 60 deg apart): a fold there may go unseen")


def test_the_summary_says_when_the_map_is_a_retry():
    from parambench.bench.cli import _selfcheck_summary

    check = {"passed": True, "n_triangles": 10, "n_flipped": 0, "n_degenerate": 0,
             "retry": {"params": {"k_nn": 12}, "passed": True, "first_reason": "1 flipped triangle(s) of 10"}}
    assert "second run with k_nn=12: the first failed, 1 flipped" in _selfcheck_summary(check)
    check = dict(check, passed=False, retry={"params": {"k_nn": 12}, "passed": False, "first_reason": "x",
                                             "error": "NoBoundaryError: none"})
    assert _selfcheck_summary(check).endswith("(a second run with k_nn=12 failed too: NoBoundaryError: none)")
    assert "second run" not in _selfcheck_summary({"passed": True, "n_triangles": 10})


def test_the_summary_says_when_the_map_is_a_second_run_after_an_error():
    from parambench.bench.cli import _selfcheck_summary

    check = {"passed": True, "n_triangles": 10, "n_flipped": 0, "n_degenerate": 0,
             "after_error": {"params": {"k_nn": 12}, "error": "ConvergenceError: no regular scp map found"}}
    assert _selfcheck_summary(check).endswith("(the map of a second run with k_nn=12: the first raised ConvergenceError)")


def test_the_summary_says_which_failed_run_the_map_kept_is():
    from parambench.bench.cli import _selfcheck_summary

    retry = {"params": {"neighbours": "pruned"}, "passed": False, "first_reason": "8 flipped",
             "earlier": [{"params": {"k_nn": 12}, "passed": False, "first_reason": "8 flipped"}]}
    check = {"passed": False, "n_flipped": 3, "n_triangles": 100, "retry": retry,
             "kept": {"params": {"k_nn": 12}, "first_reason": "8 flipped"}}
    assert _selfcheck_summary(check).endswith(
        "(2 retries failed too: with k_nn=12; with neighbours=pruned); the map kept is the least doubtful of them, "
        "the run with k_nn=12")
    assert "kept" not in _selfcheck_summary(dict(check, kept=None))


def test_the_summary_names_every_retry_and_the_energy_fallback():
    from parambench.bench.cli import _energy_summary, _retry_summary

    earlier = [{"params": {"k_nn": 12}, "passed": False, "first_reason": "x"}]
    passed = {"params": {"energy": "paper"}, "passed": True, "first_reason": "2 flipped", "earlier": earlier}
    assert _retry_summary(passed) == (" (the map of retry 2 of 2, with energy=paper: the first failed, 2 flipped; "
                                      "retries with k_nn=12 failed)")
    failed = dict(passed, passed=False)
    assert _retry_summary(failed) == " (2 retries failed too: with k_nn=12; with energy=paper)"
    assert _energy_summary({"energy_error": "ConvergenceError: no regular map"}) == (
        " (with the paper's energy: the Neumann energy's k search found no regular map)")
    assert _energy_summary({"energy_used": "neumann"}) == ""
    assert "sdp map triangulates" in _energy_summary({"energy_used": "mesh", "energy_error": "ConvergenceError: x",
                                                      "refined": {"first_map": "sdp", "n_faces": 9}})
    assert "the map of its unrolled boundary triangulates" in _energy_summary(
        {"energy_used": "mesh", "refined": {"first_map": "unrolled boundary", "n_faces": 9}})
    assert "the map of its unrolled boundary with the holes filled triangulates" in _energy_summary(
        {"energy_used": "mesh", "refined": {"first_map": "unrolled boundary, holes filled", "n_faces": 9}})
    assert _energy_summary({"energy_used": "paper", "energy_error": "ConvergenceError: x",
                            "refined": {"first_map": "ocp (paper energy)", "n_faces": 9}}) == (
        " (refined by cotangent SCP on its own uv mesh, 9 triangles)")
    assert _energy_summary({"refined": {"first_map": "ocp", "error": "NotADiskError: fans"}}) == (
        " (not refined: its uv mesh failed, NotADiskError)")


def test_the_summary_says_when_holes_were_filled():
    from parambench.bench.cli import _holes_summary

    assert _holes_summary({"holes_filled": 0, "n_fill_points": 0}) == ""
    assert _holes_summary({}) == ""
    assert _holes_summary({"holes_filled": 2, "n_fill_points": 31}) == (
        " (2 hole(s) filled with 31 points: with free holes the map failed)")
    # Before: holes=filled was said to have failed free, a map never tried.
    assert _holes_summary({"holes_filled": 3, "n_fill_points": 235}, {"holes": "filled"}) == (
        " (3 hole(s) filled with 235 points: as holes=filled asks)")
    assert _holes_summary({"holes_filled": 1, "thin_holes_filled": 1, "n_fill_points": 9}, {"holes": "auto"}) == (
        " (1 hole(s) filled with 9 points: narrow holes (slots) are filled before the solve)")


def _xyz(tmp_path, name, sampling):
    from parambench.datasets_gen.registry import make_surface

    path = tmp_path / f"{name}-{sampling}.xyz"
    np.savetxt(path, make_surface(name, 2000, sampling=sampling, seed=0).points, fmt="%.17g")
    return path


def test_inspect_exits_3_when_the_loops_miss_boundary_candidates(tmp_path, capsys):
    """Loops of fewer than 40 points dropped: the three holes of ``holes`` at 2k points
    (27-34 points each) are missed; the JSON is still written, the exit code says so."""
    src, out = _xyz(tmp_path, "holes", "jittered"), tmp_path / "front.json"
    assert main(["inspect", str(src), "-o", str(out)]) == 0
    assert "loop coverage ok" in capsys.readouterr().out
    assert main(["inspect", str(src), "-o", str(out), "--param", "min_loop_size=40"]) == EXIT_SELFCHECK
    captured = capsys.readouterr()
    report = json.loads(out.read_text())
    assert len(report["boundary_loops"]) == 1 and not report["selfcheck"]["coverage"]["passed"]
    assert "loop coverage FAILED" in captured.out
    err = captured.err.strip().splitlines()
    assert len(err) == 1 and "on no detected loop" in err[0] and "--param boundary_angle_deg=100" in err[0]


def test_inspect_says_when_coverage_cannot_be_judged(tmp_path, capsys):
    """A uniform random sample: its voids look like small holes, so coverage is not judged
    (and the run is not failed for it)."""
    src, out = _xyz(tmp_path, "plane", "random"), tmp_path / "front.json"
    assert main(["inspect", str(src), "-o", str(out)]) == 0
    cov = json.loads(out.read_text())["selfcheck"]["coverage"]
    assert not cov["applicable"] and cov["passed"] and cov["n_scattered"] > 0.02 * 2000
    assert "loop coverage not judged" in capsys.readouterr().out


def test_outliers_are_named_and_repair_drops_them(tmp_path, capsys):
    from parambench.datasets_gen.registry import make_surface

    from scipy.spatial import cKDTree

    surface = make_surface("bump", 3000, sampling="jittered", seed=0)
    rng = np.random.default_rng(0)
    spacing = cKDTree(surface.points).query(surface.points, 9)[0][:, 1:].mean()
    # 4 points 3 spacings above the surface points nearest them, as a scanner's spurious returns
    outliers = surface.points[rng.choice(len(surface.points), 4, replace=False)].copy()
    outliers[:, 2] += 3 * spacing
    src = tmp_path / "scan.xyz"
    np.savetxt(src, np.vstack([surface.points, outliers]), fmt="%.17g")
    out = tmp_path / "scan.obj"
    assert main(["flatten", str(src), "-o", str(out)]) == EXIT_SELFCHECK
    err = capsys.readouterr().err
    assert "stray point(s) in all" in err and "--repair drops the stray points" in err and not out.exists()
    assert main(["flatten", str(src), "--repair", "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert "dropped 4 stray point(s) off the surface" in err
    kept = np.array([line.split()[1:] for line in out.read_text().splitlines() if line.startswith("v ")], float)
    assert len(kept) == len(surface.points) and np.allclose(np.sort(kept, axis=0), np.sort(surface.points, axis=0))


def test_coverage_not_judged_on_irregular_samplings_says_so(bump_xyz, tmp_path, capsys):
    """Random points leave voids that look like holes, so the loop-coverage count is not judged there:
    the summary line says so beside the count; on a jittered sampling it is judged and says nothing more."""
    from parambench.datasets_gen.registry import make_surface

    src = tmp_path / "random.xyz"
    np.savetxt(src, make_surface("bump", 3000, sampling="random", seed=3).points, fmt="%.17g")
    assert main(["flatten", str(src), "-o", str(tmp_path / "random.csv")]) == 0
    out = capsys.readouterr().out
    assert "boundary candidates off the loops (not judged: on an irregular sampling" in out
    assert main(["flatten", str(bump_xyz[0]), "-o", str(tmp_path / "jittered.csv")]) == 0
    out = capsys.readouterr().out
    assert "boundary candidates off the loops" in out and "not judged" not in out


def test_the_summary_names_a_stretched_map_and_points_outside_the_loops():
    from parambench.bench.cli import _selfcheck_summary

    check = {"passed": False, "n_flipped": 0, "n_degenerate": 0, "n_triangles": 3900,
             "failed": ["distorted", "outside"], "coherent_beltrami": 0.097, "n_outside": 4}
    text = _selfcheck_summary(check)
    assert "stretched (coherent Beltrami coefficient 0.10)" in text and "4 point(s) outside the loops" in text
    assert "outside the loops" not in _selfcheck_summary(dict(check, failed=["distorted"]))


@pytest.mark.parametrize("junk", [[0.0, 0.0, 0.0], "in-plane"])
def test_a_junk_row_far_from_the_scan_fails_the_check_and_repair_drops_it(tmp_path, capsys, junk):
    """A georeferenced patch (UTM-sized coordinates) with one ``0 0 0`` row, or a unit patch
    with a point far off in its own plane (no tangent-plane offset sees it): before, exit 0
    with a uv for that point inside the patch's."""
    from parambench.datasets_gen.registry import make_surface

    patch = make_surface("bump", 2000, sampling="jittered", seed=0).points
    if junk == "in-plane":
        rows = np.vstack([patch, [1e4, 0.0, 0.0]])
    else:
        rows = np.vstack([patch * 10.0 + [500000.0, 5400000.0, 120.0], junk])
    src, out = tmp_path / "scan.xyz", tmp_path / "scan.obj"
    np.savetxt(src, rows, fmt="%.17g")
    assert main(["flatten", str(src), "-o", str(out)]) == EXIT_SELFCHECK
    captured = capsys.readouterr()
    assert "1 point(s) far from all others" in captured.out and not out.exists()
    assert "lie far from all the others" in captured.err and "--repair drops the stray points" in captured.err
    assert main(["flatten", str(src), "--repair", "-o", str(out)]) == 0
    assert "dropped 1 stray point(s)" in capsys.readouterr().err
    kept = np.array([line.split()[1:] for line in out.read_text().splitlines() if line.startswith("v ")], float)
    assert len(kept) == len(patch)


def test_a_repaired_point_set_csv_keeps_one_row_per_input_row(tmp_path, capsys):
    """A ``.csv`` holds no coordinates, so after ``--repair`` dropped a junk row its rows could not be
    matched to the input any more (1500 rows for a 1501-row file): each input row now keeps its
    row, the dropped one ``nan,nan``, and the rest are the map of the clean file."""
    from parambench.datasets_gen.registry import make_surface

    patch = make_surface("bump", 1500, sampling="jittered", seed=0).points
    rows = np.vstack([patch[:700], [0.0, 0.0, 50.0], patch[700:]])
    src, clean = tmp_path / "scan.xyz", tmp_path / "clean.xyz"
    np.savetxt(src, rows, fmt="%.17g")
    np.savetxt(clean, patch, fmt="%.17g")
    assert main(["flatten", str(src), "--repair", "-o", str(tmp_path / "scan.csv")]) == 0
    assert "the .csv has one row per input row, the 1 dropped ones nan,nan" in capsys.readouterr().err
    assert main(["flatten", str(clean), "-o", str(tmp_path / "clean.csv")]) == 0
    uv = np.loadtxt(tmp_path / "scan.csv", delimiter=",", skiprows=1)
    assert uv.shape == (len(rows), 2) and np.isnan(uv[700]).all() and np.isfinite(np.delete(uv, 700, 0)).all()
    np.testing.assert_allclose(np.delete(uv, 700, 0), np.loadtxt(tmp_path / "clean.csv", delimiter=",", skiprows=1),
                               rtol=0, atol=1e-9)
    assert main(["flatten", str(src), "--repair", "-o", str(tmp_path / "scan.obj")]) == 0
    assert "the output holds these vertices" in capsys.readouterr().err


def test_a_stretched_map_of_a_method_not_judged_for_it_is_named(tmp_path, capsys):
    """Before: lem's map of a plane, QC 2.2 and 4.9 % of the diameter off a similarity, printed "self-check ok" alone."""
    from parambench.datasets_gen.registry import make_surface

    pts = make_surface("plane", 1500, sampling="jittered", seed=0).points
    src = tmp_path / "plane.xyz"
    np.savetxt(src, pts)
    assert main(["flatten", str(src), "--method", "lem", "-o", str(tmp_path / "lem.csv")]) == 0
    captured = capsys.readouterr()
    assert "not conformal (coherent Beltrami coefficient" in captured.out
    assert "lem's check does not judge conformality, ocp's does" in captured.err
    uv = np.loadtxt(tmp_path / "lem.csv", delimiter=",", skiprows=1)
    # The note is right: the map is measurably not a similarity of the plane.
    a, b = uv[:, 0] + 1j * uv[:, 1], pts[:, 0] + 1j * pts[:, 1]
    a, b = a - a.mean(), b - b.mean()
    fit = min(np.linalg.norm((np.conj(z) @ b) / (np.conj(z) @ z) * z - b) for z in (a, np.conj(a)))
    assert fit / np.linalg.norm(b) > 0.01
    # ocp's map of the same points passes without the note.
    assert main(["flatten", str(src), "-o", str(tmp_path / "ocp.csv")]) == 0
    captured = capsys.readouterr()
    assert "not conformal" not in captured.out and "note" not in captured.err
