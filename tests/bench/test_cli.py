"""The command line: flatten, list, inspect, run, and one-line errors with exit code 2."""

from __future__ import annotations

import numpy as np
import pytest

from parambench.bench.cli import main
from parambench.bench.metrics import count_foldovers, jacobian_singular_values


def _read_obj(path):
    v, vt, f = [], [], []
    for line in path.read_text().splitlines():
        tag, *rest = line.split()
        if tag == "v":
            v.append([float(x) for x in rest])
        elif tag == "vt":
            vt.append([float(x) for x in rest])
        elif tag == "f":
            f.append([int(c.split("/")[0]) - 1 for c in rest])
    return np.array(v), np.array(vt), np.array(f, dtype=np.int64)


def _grid_mesh(n=12, z=lambda x, y: 0.2 * x * y):
    x, y = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n))
    pts = np.c_[x.ravel(), y.ravel(), z(x.ravel(), y.ravel())]
    idx = np.arange(n * n).reshape(n, n)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    faces = np.r_[np.c_[a, b, c], np.c_[a, c, d]]
    return pts, faces


def test_flatten_camelhead_obj(real_dir, tmp_path):
    out = tmp_path / "out.obj"
    assert main(["flatten", str(real_dir / "camelhead.off"), "-o", str(out)]) == 0
    v, vt, f = _read_obj(out)
    assert len(vt) == 11381 and len(v) == 11381 and len(f) == 22704
    *_, signed, _ = jacobian_singular_values(v, f, vt)
    assert count_foldovers(signed) == 0


def test_flatten_csv_in_input_order(tmp_path, write_obj):
    pts, faces = _grid_mesh()
    src = write_obj(tmp_path / "in.obj", pts, faces)
    out = tmp_path / "uv.csv"
    assert main(["flatten", str(src), "--method", "lscm-igl", "-o", str(out)]) == 0
    lines = out.read_text().splitlines()
    assert lines[0] == "u,v" and len(lines) == 1 + len(pts)
    uv = np.loadtxt(out, delimiter=",", skiprows=1)
    # The gently curved grid flattens to a near-square: uv keeps the grid's neighbour structure.
    d_uv = np.linalg.norm(uv[1] - uv[0])
    d_diag = np.linalg.norm(uv[len(pts) - 1] - uv[0])
    assert d_diag / d_uv == pytest.approx(np.sqrt(2) * 11, rel=0.05)


def test_list_shows_methods_and_datasets(capsys):
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    assert "scp-igl" in out and "lscm-igl" in out and "saddle" in out and "real/camelhead" in out


def _closed_tetra():
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    faces = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]])
    return pts, faces


def _two_components():
    pts, faces = _grid_mesh(5)
    return np.vstack([pts, pts + [5, 0, 0]]), np.vstack([faces, faces + len(pts)])


BAD_CASES = {
    "missing-file": (None, ["flatten", "{tmp}/nope.obj", "-o", "{tmp}/o.obj"], "InputFileError"),
    "unknown-method": ("grid", ["flatten", "{src}", "--method", "magic", "-o", "{tmp}/o.obj"], "UnknownNameError"),
    "unknown-param": ("grid", ["flatten", "{src}", "--method", "scp-igl", "--param", "zz=1", "-o", "{tmp}/o.obj"],
                      "UnknownNameError"),
    "bad-output": ("grid", ["flatten", "{src}", "-o", "{tmp}/o.png"], "InputFileError"),
    "output-over-input": ("grid", ["flatten", "{src}", "-o", "{src}"], "InputFileError"),
    "output-folder-missing": ("grid", ["flatten", "{src}", "-o", "{tmp}/no/o.obj"], "InputFileError"),
    "inspect-folder-missing": ("grid", ["inspect", "{src}", "-o", "{tmp}/no/o.json"], "InputFileError"),
    "points-only-mesh-method": ("grid", ["flatten", "{src}", "--points-only", "--method", "scp-igl",
                                         "-o", "{tmp}/o.obj"], "MissingFacesError"),
    "closed": ("tetra", ["flatten", "{src}", "--method", "scp-igl", "-o", "{tmp}/o.obj"], "NotADiskError"),
    "components": ("two", ["flatten", "{src}", "--method", "scp-igl", "-o", "{tmp}/o.obj"], "DisconnectedError"),
    "unknown-dataset": (None, ["run", "--datasets", "nowhere", "--out", "{tmp}/r"], "UnknownNameError"),
    "unknown-suite": (None, ["run", "--suite", "huge", "--out", "{tmp}/r"], "UnknownNameError"),
}


@pytest.mark.parametrize("case", sorted(BAD_CASES))
def test_bad_input_one_line_exit_2(case, tmp_path, capsys, write_obj):
    kind, argv, error = BAD_CASES[case]
    src = tmp_path / "in.obj"
    if kind == "grid":
        write_obj(src, *_grid_mesh(6))
    elif kind == "tetra":
        write_obj(src, *_closed_tetra())
    elif kind == "two":
        write_obj(src, *_two_components())
    argv = [a.format(tmp=tmp_path, src=src) for a in argv]
    before = src.read_bytes() if src.exists() else None
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and error in err and "Traceback" not in err
    if before is not None:
        assert src.read_bytes() == before  # the input is never written over


def test_a_point_set_failure_from_a_mesh_file_points_back_to_its_faces(tmp_path, capsys, write_obj):
    # pymeshlab's range scan face000 with --points-only fails on its points (exit 2) while
    # its own mesh maps through scp: the error says so. A 3 x 3 grid is too small for the
    # points' boundary; its faces are a disk. A bare .xyz has no faces to point to.
    src = tmp_path / "grid.obj"
    write_obj(src, *_grid_mesh(3))
    assert main(["flatten", str(src), "--points-only", "-o", str(tmp_path / "o.csv")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "NoBoundaryError" in err
    assert f"flatten the file's {len(_grid_mesh(3)[1])} faces instead: leave out --points-only" in err
    assert main(["flatten", str(src), "-o", str(tmp_path / "o.csv")]) == 0  # and they do map
    capsys.readouterr()
    xyz = tmp_path / "grid.xyz"
    np.savetxt(xyz, _grid_mesh(3)[0])
    assert main(["flatten", str(xyz), "-o", str(tmp_path / "p.csv")]) == 2
    err = capsys.readouterr().err
    assert "NoBoundaryError" in err and "--points-only" not in err


def test_a_closed_mesh_file_s_point_set_failure_says_a_cut_is_needed_not_to_use_its_faces(tmp_path, capsys, write_obj):
    # The npm package snowden's bust (genus 5) with --points-only failed its self-check and
    # was told to flatten its faces instead, which fails too: the faces say it is closed.
    from scipy.spatial import ConvexHull

    i = np.arange(2000) + 0.5
    z, phi = 1.0 - i / 1000.0, np.pi * (1.0 + 5.0**0.5) * i
    points = np.c_[np.sqrt(1.0 - z**2) * np.cos(phi), np.sqrt(1.0 - z**2) * np.sin(phi), z]
    src = tmp_path / "sphere.obj"
    write_obj(src, points, ConvexHull(points).simplices)
    assert main(["flatten", str(src), "--points-only", "-o", str(tmp_path / "o.obj")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "NoBoundaryError" in err
    assert "faces mesh a closed surface, which no method lays flat without a cut" in err
    assert "faces instead" not in err


def test_nan_coordinates_in_file(tmp_path, capsys):
    pts, faces = _grid_mesh(5)
    src = tmp_path / "nan.obj"
    src.write_text("\n".join(f"v {x} {y} {z}" for x, y, z in pts).replace("v 0.0 0.0 0.0", "v nan 0.0 0.0", 1)
                   + "\n" + "\n".join(f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces) + "\n")
    assert main(["flatten", str(src), "-o", str(tmp_path / "o.obj")]) == 2
    assert "NaN" in capsys.readouterr().err


def test_argparse_errors_are_one_line(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["flatten"])
    assert exc.value.code == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1


def test_inspect_writes_frontend_json(real_dir, tmp_path):
    import json

    out = tmp_path / "lilium.json"
    assert main(["inspect", str(real_dir / "lilium.obj"), "--points-only", "-o", str(out)]) == 0
    report = json.loads(out.read_text())
    assert report["n_points"] == 3389 and report["mean_spacing"] > 0
    loops = report["boundary_loops"]
    assert len(loops) == 1 and len(set(loops[0])) == len(loops[0]) > 20
    assert set(report["negative_weight_fraction"]) >= {"interior", "boundary"}
    assert report["reconstruction_error"]["max"] >= report["reconstruction_error"]["mean"] >= 0


def test_inspect_takes_every_frontend_option(real_dir, tmp_path, capsys):
    """``inspect --param`` accepts the fields of FrontEndParams, also those that are no method's parameter."""
    import json

    out = tmp_path / "lilium.json"
    assert main(["inspect", str(real_dir / "lilium.obj"), "--points-only", "-o", str(out),
                 "--param", "smooth_normals=False", "min_loop_size=10", "k_nn=9"]) == 0
    params = json.loads(out.read_text())["params"]
    assert params["smooth_normals"] is False and params["min_loop_size"] == 10 and params["k_nn"] == 9
    assert main(["inspect", str(real_dir / "lilium.obj"), "-o", str(out), "--param", "k_search=line"]) == 2
    err = capsys.readouterr().err
    assert "unknown front-end parameter(s) k_search" in err and "smooth_normals" in err


def test_flatten_point_cloud_with_ocp(tmp_path, write_obj):
    from parambench.datasets_gen.registry import make_surface

    surface = make_surface("bump", 1500, sampling="jittered", seed=0)
    src = write_obj(tmp_path / "bump.obj", surface.points, surface.faces)
    out = tmp_path / "bump_uv.obj"
    assert main(["flatten", str(src), "--points-only", "--param", "k_search=line", "k_nn=8", "-o", str(out)]) == 0
    v, vt, f = _read_obj(out)
    # A point set: faces from the self-check's uv triangulation, so viewers can open it.
    assert len(vt) == surface.n_points and len(f) > surface.n_points
    *_, signed, _ = jacobian_singular_values(surface.points, surface.faces, vt)
    assert count_foldovers(signed) == 0


# Each bad ``run`` option: exit 2, one line naming the option and what is allowed, no folder left.
RUN_CASES = {
    "negative-seed": (["--seeds", "-1"], "--seeds", ">= 0"),
    "zero-size": (["--sizes", "0"], "--sizes", "at least 100"),
    "negative-size": (["--sizes", "-5"], "--sizes", "at least 100"),
    "size-below-minimum": (["--sizes", "99"], "--sizes", "at least 100"),
    "unknown-sampling": (["--samplings", "poisson"], "--samplings", "blue-noise"),
    "negative-noise": (["--noise", "-0.5"], "--noise", ">= 0"),
    "nan-noise": (["--noise", "nan"], "--noise", "finite"),
    "zero-workers": (["--workers", "0"], "--workers", ">= 1"),
    "unknown-method": (["--methods", "scp", "magic"], "--methods", "scp-igl"),
    "unknown-dataset": (["--datasets", "nowhere"], "--datasets", "real/lilium"),
    "unknown-suite": (["--suite", "huge"], "--suite", "quick"),
    "missing-benchmark-json": (["--benchmark-json", "{tmp}/none.json"], "--benchmark-json", "pytest"),
    "out-under-a-file": (["--out", "{tmp}/file.txt/r"], "--out", "folder"),
    # The second sweep tester's: each ran every cell and then failed with a traceback, or
    # failed with a traceback after creating the folder.
    "huge-noise": (["--noise", "1e308"], "--noise", "at most 10"),
    "huge-size": (["--sizes", "100000000000"], "--sizes", "at most 20,000,000"),
    "huge-seed": (["--seeds", "99999999999999999999"], "--seeds", "64-bit"),
    "scheduler-not-an-address": (["--scheduler", "garbage"], "--scheduler", "host:port"),
    "workers-and-scheduler": (["--workers", "2", "--scheduler", "tcp://127.0.0.1:8786"], "--workers", "one of"),
    "isolate-and-workers": (["--workers", "2", "--isolate"], "--isolate", "does not combine"),
    "benchmark-json-not-json": (["--benchmark-json", "{tmp}/file.txt"], "--benchmark-json", "not readable JSON"),
}


@pytest.mark.parametrize("case", sorted(RUN_CASES))
def test_bad_run_options_refused_before_any_folder(case, tmp_path, capsys):
    extra, option, allowed = RUN_CASES[case]
    (tmp_path / "file.txt").write_text("x")
    argv = ["run", "--datasets", "plane", "--sizes", "500", "--methods", "scp", "--out", str(tmp_path / "r"),
            "--no-report", "--no-progress"] + [a.format(tmp=tmp_path) for a in extra]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    assert f"{option}:" in err and allowed in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file.txt"]  # nothing created


def test_run_option_that_is_not_a_number_is_one_line(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["run", "--sizes", "1e3", "--out", str(tmp_path / "r")])
    err = capsys.readouterr().err.strip()
    assert exc.value.code == 2 and len(err.splitlines()) == 1 and "--sizes" in err and "whole number" in err
    assert not (tmp_path / "r").exists()


def test_run_retries_failed_cells_and_refuses_a_busy_folder(tmp_path, capsys):
    from parambench.bench.folder_lock import hold_folder
    from parambench.bench.run_cell import failed_row
    from parambench.bench.storage import ResultStore
    from parambench.bench.suites import Suite, expand_cells

    out = tmp_path / "r"
    argv = ["run", "--datasets", "plane", "--sizes", "500", "--methods", "scp", "--out", str(out),
            "--no-report", "--no-progress"]
    (cell,) = expand_cells(Suite("x", ("plane",), (500,), ("jittered",), (0,), ("scp",)))
    ResultStore(out).write_row(failed_row(cell, "InputFileError", "no data"))

    assert main(argv + ["--keep-failed"]) == 0
    captured = capsys.readouterr()
    assert "0 done, 0 to run (0 new), 1 failed before and kept" in captured.err
    assert "0 ok, 1 failed of 1 cells" in captured.out and "--keep-failed skips them" in captured.out

    with hold_folder(out):
        assert main(argv) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and "ResultsInUseError" in err and "--wait" in err

    assert main(argv) == 0
    captured = capsys.readouterr()
    assert "0 done, 1 to run (0 new, 1 failed before and retried)" in captured.err
    assert "1 ok, 0 failed of 1 cells" in captured.out


def test_command_line_flatten_ends_the_process_after_its_exit_handlers(tmp_path, write_obj):
    # Run as the command line (no argv), flatten ends the process itself (cli._exit_now):
    # same file and output as the in-process call, the exit code kept, atexit handlers run.
    import os
    import subprocess
    import sys

    pts, faces = _grid_mesh()
    src = write_obj(tmp_path / "in.obj", pts, faces)
    assert main(["flatten", str(src), "--method", "lscm-igl", "-o", str(tmp_path / "ref.obj")]) == 0

    def command_line(*argv):
        code = ("import atexit, sys; atexit.register(lambda: print('exit handler ran', flush=True)); "
                f"sys.argv = ['parambench', *{list(argv)!r}]; "
                "from parambench.bench.cli import main; main(); print('not reached')")
        return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300,
                              env=dict(os.environ), cwd=tmp_path)

    done = command_line("flatten", str(src), "--method", "lscm-igl", "-o", str(tmp_path / "cli.obj"))
    assert done.returncode == 0, done.stderr
    assert "points flattened" in done.stdout and "exit handler ran" in done.stdout
    assert "not reached" not in done.stdout
    assert (tmp_path / "cli.obj").read_text() == (tmp_path / "ref.obj").read_text()
    bad = command_line("flatten", str(tmp_path / "missing.obj"), "-o", str(tmp_path / "o.obj"))
    assert bad.returncode == 2 and "InputFileError" in bad.stderr and "exit handler ran" in bad.stdout


def test_ocp_start_up_leaves_plotting_and_tables_unimported():
    # flatten's start-up budget (issue #14: a 10k cloud in under 2 s) has no room for
    # matplotlib (~80 ms) or pandas; they load only where a map needs them.
    import subprocess
    import sys

    code = ("import sys, parambench.bench.cli; from parambench.methods.registry import get_method; "
            "get_method('ocp'); print(sorted(m for m in ('matplotlib', 'pandas') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_report_out_that_is_a_file_and_filesystem_errors_are_one_line(tmp_path, capsys, monkeypatch):
    """``report --out FILE`` rendered the whole report, then died with FileExistsError; an
    OSError no check foresaw (``--out /proc/x`` as root) was a traceback too."""
    (tmp_path / "file.txt").write_text("x")
    assert main(["report", str(tmp_path), "--out", str(tmp_path / "file.txt")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--out" in err and "is a file" in err

    import parambench.bench.sweep as sweep

    def refused(*args, **kwargs):
        raise PermissionError(13, "Permission denied", "/sys/x")

    monkeypatch.setattr(sweep, "run_sweep", refused)
    argv = ["run", "--datasets", "plane", "--sizes", "500", "--methods", "scp", "--out", str(tmp_path / "r"),
            "--no-report", "--no-progress"]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "PermissionError" in err and "/sys/x" in err


def test_small_command_line_traps(tmp_path, capsys, real_dir):
    """From a tester's run: ``polish_spread=null`` (documented "null = never") was refused as not a
    float; ``inspect -o mesh.obj`` replaced a mesh with JSON, exit 0; ``--points-only`` with a mesh
    method said the user gave a point set."""
    from parambench.datasets_gen.registry import make_surface

    src = tmp_path / "bump.xyz"
    np.savetxt(src, make_surface("bump", 1500, sampling="jittered", seed=0).points)
    assert main(["flatten", str(src), "--param", "polish_spread=null", "-o", str(tmp_path / "a.csv")]) == 0
    assert main(["flatten", str(src), "--param", "k_nn=null", "-o", str(tmp_path / "b.csv")]) == 2
    assert "k_nn expects a int, got 'null'" in capsys.readouterr().err
    mesh = tmp_path / "mesh.obj"
    mesh.write_text("keep me\n")
    assert main(["inspect", str(src), "-o", str(mesh)]) == 2
    assert "its output must end in .json" in capsys.readouterr().err and mesh.read_text() == "keep me\n"
    assert main(["flatten", str(real_dir / "lilium.obj"), "--points-only", "--method", "scp",
                 "-o", str(tmp_path / "c.obj")]) == 2
    assert "--points-only drops the faces, and method 'scp' needs them" in capsys.readouterr().err


def test_an_unreachable_scheduler_is_refused_before_the_folder_is_made(tmp_path, capsys, monkeypatch):
    """It failed 30 s into the sweep, after the results folder was created, with "check the path and
    its permissions"."""
    import parambench.bench.dask_backend as backend

    monkeypatch.setattr(backend, "SCHEDULER_TIMEOUT", 1.0)
    out = tmp_path / "sweep"
    assert main(["run", "--scheduler", "tcp://127.0.0.1:1", "--datasets", "plane", "--methods", "scp",
                 "--sizes", "500", "--seeds", "0", "--out", str(out), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "no Dask scheduler answered at tcp://127.0.0.1:1 within 1 s" in err and "permissions" not in err
    assert not out.exists()


def test_a_reader_that_leaves_the_pipe_gets_no_error_message():
    """Before: `parambench list | head` printed "BrokenPipeError ...; check the path and its permissions"."""
    import subprocess
    import sys

    # PYTHONPATH leads to the source tree (tests/source_tree.py).
    script = "import sys, time; time.sleep(1.0); from parambench.bench.cli import main; sys.exit(main(['list']))"
    proc = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    proc.stdout.close()  # the reader is gone before the first line is written
    err = proc.stderr.read().decode()
    proc.stderr.close()
    assert proc.wait(timeout=120) == 141 and "error" not in err


def test_inspect_names_points_far_from_all_others(tmp_path, capsys):
    """Before: a UTM patch with one `0 0 0` row was reported with "mean spacing 2015" (the points are
    0.003 apart), "loop coverage ok" and exit 0, where flatten exits 3 naming the far point."""
    from parambench.datasets_gen.registry import make_surface

    points = make_surface("bump", 1500, sampling="jittered", seed=0).points * 0.1 + [5e5, 4e6, 100.0]
    src = tmp_path / "utm.xyz"
    np.savetxt(src, np.vstack([points, [0.0, 0.0, 0.0]]), fmt="%.6f")
    assert main(["inspect", str(src), "-o", str(tmp_path / "d.json")]) == 3
    assert "1 point(s) lie far from all others" in capsys.readouterr().err
    assert main(["inspect", str(src), "--repair", "-o", str(tmp_path / "d.json")]) == 0
    import json
    report = json.loads((tmp_path / "d.json").read_text())
    assert report["selfcheck"]["n_isolated"] == 0 and report["mean_spacing"] < 0.01
