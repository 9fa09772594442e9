"""A point set's own normals that the front end refuses: the error offers --repair, which fixes them."""

from __future__ import annotations

import numpy as np
import pytest

from parambench.bench.cli import main


@pytest.fixture(scope="module")
def bump():
    from parambench.datasets_gen.registry import make_surface

    return make_surface("bump", 3000, sampling="jittered", seed=0)


def _write(path, points, normals, header=""):
    np.savetxt(path, np.hstack([points, normals]), fmt="%.17g", header=header, comments="")
    return str(path)


def test_misoriented_normals_are_flipped_by_repair(bump, tmp_path, capsys):
    """60 of the exact normals turned over, as a scanner's merged views leave them: the
    error counts them and offers --repair, which flips exactly that many back; the map
    then passes its self-check."""
    normals = bump.normals.copy()
    flipped = np.random.default_rng(1).choice(bump.n_points, 60, replace=False)
    normals[flipped] *= -1.0
    src, out = _write(tmp_path / "scan.xyz", bump.points, normals), tmp_path / "scan.obj"
    assert main(["flatten", src, "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"60 of {bump.n_points} given normals point to the other side" in err and "or pass --repair to flip them." in err
    assert not out.exists()
    assert main(["flatten", src, "--repair", "-o", str(out)]) == 0
    captured = capsys.readouterr()
    assert "flipped 60 given normal(s) to agree with their neighbours" in captured.err
    assert "self-check ok" in captured.out and out.exists()


def test_normals_off_the_surface_are_dropped_by_repair(bump, tmp_path, capsys):
    """Unit vectors in the tangent plane instead of normals (median |cos| to the fitted
    normals near 0), in columns a header names as normals: refused with --repair offered,
    which estimates normals instead. (Without the header the columns are only guessed to be
    normals, and are ignored with a warning.)"""
    tangent = np.cross(bump.normals, np.random.default_rng(2).normal(size=bump.normals.shape))
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    src = _write(tmp_path / "tangents.xyz", bump.points, tangent, header="x y z nx ny nz")
    out = tmp_path / "tangents.obj"
    assert main(["flatten", src, "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "far from perpendicular to the point set" in err and "or pass --repair to estimate normals instead." in err
    assert main(["flatten", src, "--repair", "-o", str(out)]) == 0
    captured = capsys.readouterr()
    assert "dropped the given normals" in captured.err and "self-check ok" in captured.out


def test_consistent_normals_pass_repair_unchanged(bump, tmp_path, capsys):
    """The exact normals: --repair says nothing about them, and the map is the one without it (to 1e-5 of
    its size of 2: the repaired copy's normals are renormalised, 1e-16 apart, which moves the map by
    about 1.5e-6)."""
    src = _write(tmp_path / "good.xyz", bump.points, bump.normals)
    plain, repaired = tmp_path / "plain.csv", tmp_path / "repaired.csv"
    assert main(["flatten", src, "-o", str(plain)]) == 0
    assert main(["flatten", src, "--repair", "-o", str(repaired)]) == 0
    assert "normal" not in capsys.readouterr().err
    np.testing.assert_allclose(np.loadtxt(repaired, delimiter=",", skiprows=1),
                               np.loadtxt(plain, delimiter=",", skiprows=1), rtol=0, atol=1e-5)


@pytest.mark.parametrize("columns", ["colours", "scalars"])
def test_columns_only_guessed_to_be_normals_are_ignored_when_they_do_not_fit(bump, tmp_path, capsys, columns):
    """x y z and three more columns with no header: colours written as floats ((1, 0, 0), ...)
    are unit vectors, and signed scalar fields look like unnormalised normals, so both were
    taken for normals and refused ("far from perpendicular", "point to the other side")."""
    rng = np.random.default_rng(0)
    if columns == "colours":
        extra = np.eye(3)[rng.integers(0, 3, len(bump.points))]
    else:
        extra = rng.normal(size=(len(bump.points), 3))
    src = _write(tmp_path / "scan.xyz", bump.points, extra)
    assert main(["flatten", src, "-o", str(tmp_path / "out.obj")]) == 0
    assert "were taken for normals but do not fit the points" in capsys.readouterr().err


def test_guessed_normals_that_fit_are_kept_even_under_noise():
    """The exact normals of a noisy sampling (0.5 spacings: 8-neighbour fits tilt, 24-neighbour
    ones do not) and of a clean one stay the data's normals."""
    from parambench.bench.point_repair import screened_guessed_normals
    from parambench.datasets_gen.registry import make_surface
    from parambench.datasets_gen.surface import Surface

    for noise in (0.0, 0.5):
        truth = make_surface("fold", 3000, sampling="random", seed=0, noise=noise)
        given = Surface(points=truth.points, normals=truth.normals, name="fold", params={"normals_guessed": True})
        assert screened_guessed_normals(given, 8).normals is not None
