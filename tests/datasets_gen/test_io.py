"""The file loader: formats, vertex order, normals, errors."""

from __future__ import annotations

import numpy as np
import pytest

from datasets_gen.errors import InputFileError
from datasets_gen.io import SUPPORTED_EXTENSIONS, load_surface
from datasets_gen.real import pymeshlab_samples_dir, real_data_dir

# A square of 4 triangles around a raised centre, plus one unreferenced vertex in the middle
# of the list: the loader must keep it, in place.
POINTS = np.array([[0, 0, 0], [1, 0, 0], [7, 7, 7], [1, 1, 0], [0, 1, 0], [0.5, 0.5, 0.25]], float)
FACES = np.array([[0, 1, 5], [1, 3, 5], [3, 4, 5], [4, 0, 5]])
NORMALS = np.array([[0, 0, 1], [0, 0.6, 0.8], [1, 0, 0], [0, 0, 1], [0, 0, 2], [0.6, 0, 0.8]], float)


def _fmt(values) -> str:
    return " ".join(repr(float(v)) for v in values)


def _write(path, text):
    path.write_text(text)
    return path


def _obj(path, normals=False):
    lines = [f"v {_fmt(p)}" for p in POINTS]
    if normals:
        lines += [f"vn {_fmt(n)}" for n in NORMALS]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in FACES]
    return _write(path, "\n".join(lines) + "\n")


def _off(path, normals=False):
    rows = [_fmt(np.concatenate([p, n]) if normals else p) for p, n in zip(POINTS, NORMALS)]
    head = "NOFF" if normals else "OFF"
    return _write(path, "\n".join([head, f"{len(POINTS)} {len(FACES)} 0", *rows,
                                   *(f"3 {a} {b} {c}" for a, b, c in FACES)]) + "\n")


def _ply(path, normals=False, faces=True):
    props = ["property double x", "property double y", "property double z"]
    if normals:
        props += ["property double nx", "property double ny", "property double nz"]
    head = ["ply", "format ascii 1.0", f"element vertex {len(POINTS)}", *props]
    if faces:
        head += [f"element face {len(FACES)}", "property list uchar int vertex_indices"]
    rows = [_fmt(np.concatenate([p, n]) if normals else p) for p, n in zip(POINTS, NORMALS)]
    body = rows + ([f"3 {a} {b} {c}" for a, b, c in FACES] if faces else [])
    return _write(path, "\n".join(head + ["end_header"] + body) + "\n")


@pytest.mark.parametrize("writer", [_obj, _off, _ply])
def test_round_trip_keeps_vertex_order_and_faces(tmp_path, writer):
    path = writer(tmp_path / f"square.{writer.__name__[1:]}")
    s = load_surface(path)
    assert np.array_equal(s.points, POINTS)  # row i == vertex i, unreferenced vertex 2 included
    assert np.array_equal(s.faces, FACES)
    assert s.normals is None  # the file has none; computed normals are not passed off as data
    assert s.name == "square" and s.params["format"] == writer.__name__[1:]
    assert [sorted(lp.tolist()) for lp in s.boundary_loops] == [[0, 1, 3, 4]]
    assert s.boundary_mask.tolist() == [True, True, False, True, True, False]
    # the loop follows the faces (counter-clockwise seen from +z, the faces' side)
    loop = s.boundary_loops[0]
    x, y = POINTS[loop, 0], POINTS[loop, 1]
    assert np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) > 0


@pytest.mark.parametrize("writer", [_obj, _off, _ply])
def test_file_normals_are_kept_and_normalised(tmp_path, writer):
    s = load_surface(writer(tmp_path / f"n.{writer.__name__[1:]}", normals=True))
    assert np.allclose(s.normals, NORMALS / np.linalg.norm(NORMALS, axis=1)[:, None])


def test_point_clouds(tmp_path):
    ply = load_surface(_ply(tmp_path / "cloud.ply", normals=True, faces=False))
    assert ply.faces is None and ply.boundary_loops is None and np.array_equal(ply.points, POINTS)
    assert np.allclose(ply.normals[1], [0, 0.6, 0.8])
    rows = "\n".join(_fmt(np.concatenate([p, n])) for p, n in zip(POINTS, NORMALS))
    for ext in ("xyz", "pts"):
        s = load_surface(_write(tmp_path / f"cloud.{ext}", rows + "\n"))
        assert s.faces is None and np.array_equal(s.points, POINTS)
        assert np.allclose(s.normals[4], [0, 0, 1])
        bare = load_surface(_write(tmp_path / f"bare.{ext}", "\n".join(_fmt(p) for p in POINTS)))
        assert bare.normals is None and np.array_equal(bare.points, POINTS)


def test_points_only_and_name(tmp_path):
    s = load_surface(_obj(tmp_path / "a.obj"), points_only=True, name="mine")
    assert s.faces is None and s.name == "mine" and np.array_equal(s.points, POINTS)


def test_stl_mesh(tmp_path):
    tri = POINTS[FACES]
    lines = ["solid t"]
    for a, b, c in tri:
        lines += ["facet normal 0 0 1", "outer loop", *(f"vertex {_fmt(v)}" for v in (a, b, c)),
                  "endloop", "endfacet"]
    s = load_surface(_write(tmp_path / "t.stl", "\n".join(lines + ["endsolid t"]) + "\n"))
    assert s.n_points == 5 and len(s.faces) == 4  # shared corners merged, unreferenced vertex gone
    assert np.allclose(s.points[s.faces], tri, atol=1e-6)  # STL stores float32


def test_errors(tmp_path):
    with pytest.raises(InputFileError, match="no such file"):
        load_surface(tmp_path / "missing.obj")
    with pytest.raises(InputFileError, match=r"\.ply") as info:
        load_surface(_write(tmp_path / "mesh.vtk", "x"))
    assert all(ext in str(info.value) for ext in SUPPORTED_EXTENSIONS)
    with pytest.raises(InputFileError, match="broken.off"):
        load_surface(_write(tmp_path / "broken.off", "OFF\n10 3 0\n1 2\n"))
    dup = POINTS.copy()
    dup[2] = dup[0]
    _write(tmp_path / "dup.xyz", "\n".join(_fmt(p) for p in dup))
    # coincident points are kept row for row (point-set methods merge them, one uv per row)
    np.testing.assert_allclose(load_surface(tmp_path / "dup.xyz").points, dup, atol=1e-6)


def test_camelhead_loads_with_its_counts():
    s = load_surface(real_data_dir() / "camelhead.off")
    assert s.n_points == 11381 and s.faces.shape == (22704, 3)
    assert len(s.boundary_loops) == 1


def test_chameleon_loads_as_points_with_normals():
    s = load_surface(pymeshlab_samples_dir() / "chameleon.pts")
    assert s.faces is None and s.n_points == 4594
    assert s.normals is not None and np.allclose(np.linalg.norm(s.normals, axis=1), 1)
