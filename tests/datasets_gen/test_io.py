"""The file loader: formats, vertex order, normals, errors."""

from __future__ import annotations

import numpy as np
import pytest

from parambench.datasets_gen.errors import InputFileError
from parambench.datasets_gen.io import SUPPORTED_EXTENSIONS, load_surface
from parambench.datasets_gen.real import pymeshlab_samples_dir, real_data_dir

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


# --- every format round-trips exactly, including files other tools wrote -------------------------

QUAD_FACES = np.array([[0, 1, 5], [1, 3, 4, 5], [4, 0, 5]], dtype=object)  # one quad
QUAD_TRIS = np.array([[0, 1, 5], [1, 3, 4], [1, 4, 5], [4, 0, 5]])  # its fan


def _ply_binary(path, order, normals=True):
    """Binary PLY with mixed property types, an extra element and a quad face."""
    head = [f"ply\nformat binary_{'little' if order == '<' else 'big'}_endian 1.0", "comment made by hand",
            f"element vertex {len(POINTS)}", "property double x", "property float32 nx", "property double y",
            "property uchar red", "property double z", "property float ny", "property float nz",
            "element edge 1", "property int vertex1", "property int vertex2",
            f"element face {len(QUAD_FACES)}", "property list uchar uint vertex_index", "property uchar flags",
            "end_header"]
    rec = np.zeros(len(POINTS), dtype=[("x", order + "f8"), ("nx", order + "f4"), ("y", order + "f8"),
                                       ("red", "u1"), ("z", order + "f8"), ("ny", order + "f4"), ("nz", order + "f4")])
    for k, c in enumerate("xyz"):
        rec[c] = POINTS[:, k]
        rec["n" + c] = NORMALS[:, k]
    body = rec.tobytes() + np.array([2, 3], dtype=order + "i4").tobytes()
    for f in QUAD_FACES:
        body += bytes([len(f)]) + np.array(f, dtype=order + "u4").tobytes() + b"\x07"
    if not normals:
        head = [h for h in head if " n" not in h]
        rec = rec[["x", "y", "red", "z"]]
    path.write_bytes(("\n".join(head) + "\n").encode() + body)
    return path


@pytest.mark.parametrize("order", ["<", ">"])
def test_binary_ply_both_endians_polygons_and_extra_properties(tmp_path, order):
    s = load_surface(_ply_binary(tmp_path / "b.ply", order))
    assert np.array_equal(s.points, POINTS)
    assert np.array_equal(s.faces, QUAD_TRIS)  # quad split as a fan from its first corner
    assert np.allclose(s.normals, NORMALS / np.linalg.norm(NORMALS, axis=1)[:, None], atol=1e-7)


def test_ascii_ply_mixed_record_and_vertex_index_name(tmp_path):
    head = ["ply", "format ascii 1.0", f"element vertex {len(POINTS)}", "property double x", "property double y",
            "property double z", "property uchar red", f"element face {len(QUAD_FACES)}",
            "property uchar flags", "property list uchar int vertex_index", "end_header"]
    rows = [f"{_fmt(p)} 200" for p in POINTS] + [f"1 {len(f)} {' '.join(map(str, f))}" for f in QUAD_FACES]
    s = load_surface(_write(tmp_path / "m.ply", "\n".join(head + rows) + "\n"))
    assert np.array_equal(s.points, POINTS) and np.array_equal(s.faces, QUAD_TRIS) and s.normals is None


def test_obj_corner_forms_negative_indices_polygons_and_other_records(tmp_path):
    lines = ["# comment", "mtllib x.mtl", "o thing", *(f"v {_fmt(p)}" for p in POINTS[:3]), "vt 0 0", "vt 1 0",
             "vn 0 0 1", *(f"v {_fmt(p)} 0.5 0.5 0.5" for p in POINTS[3:]), "usemtl m", "s off", "g group",
             "f 1/1 2/2/1 6//1",  # v/vt, v/vt/vn, v//vn
             "f -5 -3 -2 -1",  # relative: vertices 2, 4, 5, 6 (1-based) -> 1, 3, 4, 5
             "f 5/1/1 1 6 # trailing comment", "l 1 2"]
    s = load_surface(_write(tmp_path / "m.obj", "\n".join(lines) + "\n"))
    assert np.array_equal(s.points, POINTS)
    assert np.array_equal(s.faces, QUAD_TRIS)
    assert s.normals is None  # one vn for six v: not per-vertex data


def test_off_variants_colours_comments_counts_on_keyword_line(tmp_path):
    rows = [f"{_fmt(p)} {_fmt(n)} 0.1 0.2 0.3 1" for p, n in zip(POINTS, NORMALS)]
    faces = [f"{len(f)} {' '.join(map(str, f))} 255 0 0" for f in QUAD_FACES]
    text = "\n".join(["CNOFF 6 3 0  # counts on the keyword line", *rows, "", *faces]) + "\n"
    s = load_surface(_write(tmp_path / "c.off", text))
    assert np.array_equal(s.points, POINTS) and np.array_equal(s.faces, QUAD_TRIS)
    assert np.allclose(s.normals, NORMALS / np.linalg.norm(NORMALS, axis=1)[:, None])
    coff = "\n".join(["COFF", "6 3 0", *(f"{_fmt(p)} 10 20 30" for p in POINTS), *faces]) + "\n"
    s = load_surface(_write(tmp_path / "d.off", coff))
    assert np.array_equal(s.points, POINTS) and s.normals is None


def test_binary_stl_keeps_first_appearance_order(tmp_path):
    tri = POINTS[FACES].astype(np.float32)
    rec = np.zeros(len(tri), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
    rec["v"] = tri
    # a binary file whose header starts with "solid" must still be read as binary
    (tmp_path / "b.stl").write_bytes(b"solid but binary".ljust(80, b" ") + np.uint32(len(tri)).tobytes()
                                     + rec.tobytes())
    s = load_surface(tmp_path / "b.stl")
    order = [0, 1, 5, 3, 4]  # corners in order of first appearance along the faces
    assert np.array_equal(s.points, POINTS[order].astype(np.float32))
    new_index = np.full(len(POINTS), -1)
    new_index[order] = np.arange(len(order))
    assert np.array_equal(s.faces, new_index[FACES])


def test_xyz_commas_comments_blank_lines_and_extra_columns(tmp_path):
    rows = [", ".join(repr(float(v)) for v in np.concatenate([p, n, [0.5]])) for p, n in zip(POINTS, NORMALS)]
    s = load_surface(_write(tmp_path / "c.xyz", "# x, y, z, nx, ny, nz, w\n\n" + "\n\n".join(rows) + "\n"))
    assert np.array_equal(s.points, POINTS)
    assert np.allclose(s.normals, NORMALS / np.linalg.norm(NORMALS, axis=1)[:, None])


def test_text_pts_with_a_point_count_and_intensity_and_colour_columns(tmp_path):
    """Leica's PTS: the count on the first line, then x y z intensity r g b."""
    rows = "\n".join(f"{p[0]} {p[1]} {p[2]} {-1000 + 7 * i} {i} {200 - i} 17" for i, p in enumerate(POINTS))
    s = load_surface(_write(tmp_path / "scan.pts", f"{len(POINTS)}\n{rows}\n"))
    assert np.array_equal(s.points, POINTS) and s.normals is None
    with pytest.raises(InputFileError, match=f"line 1: a point count of {len(POINTS) + 1} but {len(POINTS)} rows"):
        load_surface(_write(tmp_path / "bad.pts", f"{len(POINTS) + 1}\n{rows}\n"))
    # the same columns without the count (a text export): intensities and colours are no normals either
    s = load_surface(_write(tmp_path / "scan.xyz", rows + "\n"))
    assert np.array_equal(s.points, POINTS) and s.normals is None


@pytest.mark.parametrize("colour", ["int", "float"])
def test_colour_columns_are_not_read_as_normals(tmp_path, colour):
    rgb = np.random.default_rng(0).integers(0, 256, (len(POINTS), 3))
    rgb = rgb if colour == "int" else rgb / 255.0
    rows = [", ".join(map(str, np.concatenate([p, c]))) for p, c in zip(POINTS, rgb)]
    # CloudCompare's ASCII export: a "//" header naming the columns
    s = load_surface(_write(tmp_path / "cc.xyz", "//X,Y,Z,R,G,B\n" + "\n".join(rows) + "\n"))
    assert np.array_equal(s.points, POINTS) and s.normals is None
    # colours first, normals after them: the normals are found
    rows = [" ".join(map(str, np.concatenate([p, c, n]))) for p, c, n in zip(POINTS, rgb, NORMALS)]
    s = load_surface(_write(tmp_path / "ccn.xyz", "\n".join(rows) + "\n"))
    assert np.allclose(s.normals, NORMALS / np.linalg.norm(NORMALS, axis=1)[:, None])


def test_binary_expe_pts_round_trip(tmp_path):
    head = "[Expe/PointSet/Binary/0.1]\nproperty position 12\nproperty radius 4\nproperty normal 12\n" \
           f"property color 4\nnofpoints {len(POINTS)}\ndata\n"
    rec = np.zeros(len(POINTS), dtype=[("p", "<f4", 3), ("r", "<f4"), ("n", "<f4", 3), ("c", "u1", 4)])
    rec["p"], rec["n"], rec["r"] = POINTS, NORMALS, 1.0
    (tmp_path / "e.pts").write_bytes(head.encode() + rec.tobytes())
    s = load_surface(tmp_path / "e.pts")
    assert np.array_equal(s.points, POINTS.astype(np.float32))
    assert np.allclose(s.normals, NORMALS / np.linalg.norm(NORMALS, axis=1)[:, None], atol=1e-6)


@pytest.mark.parametrize("ext", ["ply", "obj", "off", "stl", "xyz"])
def test_files_written_by_pymeshlab(tmp_path, ext):
    import pymeshlab

    keep = [0, 1, 3, 4, 5]  # no unreferenced vertex, so pymeshlab's stored normals are all usable
    points, faces = POINTS[keep], np.searchsorted(keep, FACES)
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(points, faces))
    path = tmp_path / f"pml.{ext}"
    ms.save_current_mesh(str(path))
    s = load_surface(path)
    if ext == "stl":  # float32 corners
        assert np.array_equal(s.points[s.faces], points[faces].astype(np.float32))
        return
    tol = 1e-5 if ext in ("off", "xyz") else 0  # pymeshlab prints OFF/XYZ with 6 digits
    assert np.allclose(s.points, points, rtol=0, atol=tol)
    if ext != "xyz":
        assert np.array_equal(s.faces, faces)
    if ext in ("obj", "off", "xyz"):  # these writers store normals (OFF as NCOFF, colour first)
        stored = ms.current_mesh().vertex_normal_matrix()
        assert np.allclose(s.normals, stored / np.linalg.norm(stored, axis=1)[:, None], atol=1e-5)
    else:
        assert s.normals is None


@pytest.mark.parametrize("writer", ["writePLY", "writeOBJ", "writeOFF", "writeSTL-ascii", "writeSTL-binary"])
def test_files_written_by_igl(tmp_path, writer):
    import igl

    ext = writer[5:8].lower()
    path = tmp_path / f"igl.{ext}"
    if writer.startswith("writeSTL"):
        igl.writeSTL(str(path), POINTS, FACES, writer.endswith("binary"))
    else:
        getattr(igl, writer)(str(path), POINTS, FACES)
    s = load_surface(path)
    if ext == "stl":
        assert np.allclose(s.points[s.faces], POINTS[FACES], atol=1e-6)
    else:
        assert np.allclose(s.points, POINTS, atol=1e-12) and np.array_equal(s.faces, FACES)


def _sample_files():
    names = ["airplane.obj", "bone.ply", "bunny.obj", "cow.obj", "cube.obj", "colored_airplane.ply",
             "bunny10k_textured.obj", "chameleon.pts"]
    return [pymeshlab_samples_dir() / n for n in names] + [real_data_dir() / n for n in
                                                              ("camelhead.off", "lilium.obj", "bump-domain.obj")]


@pytest.mark.parametrize("path", _sample_files(), ids=lambda p: p.name)
def test_our_readers_agree_with_pymeshlab_on_well_formed_files(path):
    import pymeshlab

    from parambench.datasets_gen.formats import read_file

    if not path.is_file():
        pytest.skip(f"{path} is not installed")
    ours = read_file(path)
    ms = pymeshlab.MeshSet()
    ms.load_new_mesh(str(path))
    theirs = ms.current_mesh()
    assert np.allclose(ours.points, theirs.vertex_matrix(), rtol=0, atol=1e-6)  # pymeshlab keeps float32 here
    if theirs.face_number():
        assert np.array_equal(ours.faces, theirs.face_matrix())
    else:
        assert ours.faces is None


@pytest.mark.parametrize("writer", [_obj, _off, _ply], ids=lambda w: w.__name__[1:])
def test_windows_line_endings(tmp_path, writer):
    path = writer(tmp_path / f"w.{writer.__name__[1:]}", normals=True)
    path.write_bytes(path.read_bytes().replace(b"\n", b"\r\n"))
    s = load_surface(path)
    assert np.array_equal(s.points, POINTS) and np.array_equal(s.faces, FACES)
    assert np.allclose(s.normals, NORMALS / np.linalg.norm(NORMALS, axis=1)[:, None])


@pytest.mark.parametrize("fmt", ["ascii", "binary_little_endian"])
def test_ply_with_zero_faces_is_a_point_cloud(tmp_path, fmt):
    head = (f"ply\nformat {fmt} 1.0\nelement vertex {len(POINTS)}\nproperty double x\nproperty double y\n"
            "property double z\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n")
    body = ("\n".join(_fmt(p) for p in POINTS) + "\n").encode() if fmt == "ascii" else POINTS.astype("<f8").tobytes()
    (tmp_path / "c.ply").write_bytes(head.encode() + body)
    s = load_surface(tmp_path / "c.ply")
    assert s.faces is None and np.array_equal(s.points, POINTS)
