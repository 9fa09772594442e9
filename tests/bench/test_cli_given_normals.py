"""A point set's own normals that the front end refuses: the error offers --repair, which fixes them."""

from __future__ import annotations

import numpy as np
import pytest

from parambench.bench.cli import main


@pytest.fixture(scope="module")
def bump():
    from parambench.datasets_gen.registry import make_surface

    return make_surface("bump", 3000, sampling="jittered", seed=0)


def _write(path, points, normals):
    np.savetxt(path, np.hstack([points, normals]), fmt="%.17g")
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
    normals near 0): refused with --repair offered, which estimates normals instead."""
    tangent = np.cross(bump.normals, np.random.default_rng(2).normal(size=bump.normals.shape))
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    src, out = _write(tmp_path / "tangents.xyz", bump.points, tangent), tmp_path / "tangents.obj"
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
