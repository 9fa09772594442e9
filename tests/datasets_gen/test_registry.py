"""The registry: names, descriptions, errors that list the valid choices, real datasets."""

from __future__ import annotations

import numpy as np
import pytest

from parambench.datasets_gen.errors import InputFileError, InvalidInputError, TooFewPointsError, UnknownNameError
from parambench.datasets_gen.registry import SAMPLINGS, dataset_info, dataset_names, make_surface

PROCEDURAL = ["plane", "saddle", "bump", "holes", "holes-bumped", "cap", "cylinder", "protrusions", "gnome-strip",
              "slit", "fold"]
REAL = ["real/camelhead", "real/lilium", "real/bump-domain", "real/bunny10k", "real/chameleon"]


def test_names_and_info():
    assert SAMPLINGS == ("grid", "jittered", "random", "blue-noise", "graded")
    assert dataset_names() == PROCEDURAL + REAL
    info = dataset_info()
    assert list(info) == dataset_names()
    assert all(isinstance(v, str) and v and "\n" not in v for v in info.values())


def test_unknown_names_list_the_valid_ones():
    with pytest.raises(UnknownNameError) as err:
        make_surface("torus")
    assert "saddle" in str(err.value) and "real/camelhead" in str(err.value)
    with pytest.raises(UnknownNameError) as err:
        make_surface("plane", 500, sampling="hexagonal")
    assert all(s in str(err.value) for s in SAMPLINGS)
    with pytest.raises(UnknownNameError) as err:
        make_surface("bump", 500, height=3)
    assert "h, s" in str(err.value)
    with pytest.raises(UnknownNameError):
        make_surface("real/lilium", scale=2)


def test_bad_values():
    with pytest.raises(TooFewPointsError):
        make_surface("plane", 50)
    for count in (500.5, "500", None):
        with pytest.raises(InvalidInputError):
            make_surface("plane", count)
    assert make_surface("plane", np.int64(500)).params["n_points"] == 500
    with pytest.raises(InvalidInputError):
        make_surface("plane", 500, noise=-0.1)
    with pytest.raises(InvalidInputError):
        make_surface("bump", 500, s=0.0)
    with pytest.raises(InvalidInputError):
        make_surface("protrusions", 500, radius=0.6)


@pytest.mark.parametrize("name,n,loops", [("real/camelhead", 11381, 1), ("real/lilium", 3389, 1),
                                          ("real/bump-domain", 4172, 1), ("real/bunny10k", 5051, 5)])
def test_real_meshes(name, n, loops):
    s = make_surface(name, 999, sampling="grid", seed=4)
    assert s.name == name and s.n_points == n and len(s.boundary_loops) == loops
    assert s.params["n_points"] == n and s.params["sampling"] is None
    assert s.params["ignored"] == {"n_points": 999, "sampling": "grid"}
    assert s.exact_uv is None
    # mesh normals agree with the faces' orientation
    p = s.points[s.faces]
    fn = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    assert np.mean(np.einsum("ij,ij->i", fn, s.normals[s.faces].sum(axis=1)) > 0) > 0.99


def test_camelhead_counts_and_noise():
    s = make_surface("real/camelhead")
    assert s.faces.shape == (22704, 3)
    noisy = make_surface("real/camelhead", seed=1, noise=0.3)
    d = noisy.points - s.points
    assert np.allclose(d, np.einsum("ij,ij->i", d, s.normals)[:, None] * s.normals, atol=1e-12)
    assert np.array_equal(make_surface("real/camelhead", seed=1, noise=0.3).points, noisy.points)


def test_chameleon_is_points_only():
    s = make_surface("real/chameleon")
    assert s.faces is None and s.n_points == 4594 and s.params["normals"] == "file"


def test_missing_real_data_says_where_it_looked(tmp_path, monkeypatch):
    monkeypatch.setenv("PARAMBENCH_REAL_DATA", str(tmp_path))
    with pytest.raises(InputFileError) as err:
        make_surface("real/lilium")
    assert str(tmp_path) in str(err.value) and "lilium.obj" in str(err.value)


def test_env_var_points_to_another_folder(tmp_path, monkeypatch):
    (tmp_path / "lilium.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0.5\nf 1 2 3\nf 2 4 3\n")
    monkeypatch.setenv("PARAMBENCH_REAL_DATA", str(tmp_path))
    assert make_surface("real/lilium").n_points == 4
