"""Hostile and malformed input files: every one gives a one-line InputFileError, never a
crash, a hang or silently altered data (issue #12, item 3, its bad-input suite).

Each case is checked twice: in-process (exception type, one line naming the file and,
where the reader can tell, the line or byte offset) and through ``parambench flatten``
called in-process (exit code 2, one line on stderr naming the file, no output left).
"""

from __future__ import annotations

import os
import struct

import numpy as np
import pytest

from parambench.bench.cli import main as cli_main
from parambench.datasets_gen.errors import InputFileError
from parambench.datasets_gen.io import load_surface

# a square of 4 triangles around its centre: 5 vertices
PTS = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.5, 0.5, 0.2]])
TRI = np.array([[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]])

XYZ_OK = "0 0 0\n1 0 0\n1 1 0\n0 1 0\n0.5 0.5 0.2\n"
OBJ_V = "".join(f"v {x:g} {y:g} {z:g}\n" for x, y, z in PTS)
OFF_V = "".join(f"{x:g} {y:g} {z:g}\n" for x, y, z in PTS)
OFF_F = "".join(f"3 {a} {b} {c}\n" for a, b, c in TRI)
PLY_HEAD = ("ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\nproperty float z\n"
            "element face 4\nproperty list uchar int vertex_indices\nend_header\n")


def ply_binary(order="<", n_vertices=None, n_faces=None, cut=0, extra=b"", count_type="uchar",
               faces=TRI, points=PTS, sizes=None):
    """A binary PLY of the square; every argument spoils one part of it."""
    nv = len(points) if n_vertices is None else n_vertices
    nf = len(faces) if n_faces is None else n_faces
    head = (f"ply\nformat binary_{'little' if order == '<' else 'big'}_endian 1.0\nelement vertex {nv}\n"
            "property double x\nproperty double y\nproperty double z\n"
            f"element face {nf}\nproperty list {count_type} int vertex_indices\nend_header\n").encode()
    code = {"uchar": "B", "char": "b", "int": "i"}[count_type]
    body = np.asarray(points, dtype=order + "f8").tobytes()
    for k, f in enumerate(faces):
        n = len(f) if sizes is None else sizes[k]
        body += struct.pack(order + code, n) + np.asarray(f, dtype=order + "i4").tobytes()
    data = head + body + extra
    return data[:len(data) - cut]


def stl_binary(tris, count=None, cut=0):
    n = len(tris) if count is None else count
    body = b"".join(struct.pack("<3f", 0, 0, 1) + np.asarray(t, "<f4").tobytes() + b"\0\0" for t in tris)
    data = b"\0" * 80 + struct.pack("<I", n) + body
    return data[:len(data) - cut]


def stl_ascii(tris, corners=3):
    rows = ["solid s"]
    for t in tris:
        rows += ["facet normal 0 0 1", "outer loop", *(f"vertex {x} {y} {z}" for x, y, z in t[:corners]),
                 "endloop", "endfacet"]
    return "\n".join(rows + ["endsolid s"]) + "\n"


def expe(points=PTS, n_points=None, cut=0, props=(("position", 12), ("normal", 12)), data_line=True, extra=""):
    n = len(points) if n_points is None else n_points
    head = "[Expe/PointSet/Binary/0.1]\n" + "".join(f"property {k} {s}\n" for k, s in props) + extra
    head += f"nofpoints {n}\n" + ("data\n" if data_line else "")
    rec = np.zeros(len(points), dtype=[("p", "<f4", 3), ("n", "<f4", 3)])
    rec["p"], rec["n"] = points, [0, 0, 1]
    data = head.encode() + rec.tobytes()
    return data[:len(data) - cut]


TRIS = PTS[TRI]
NAN_TRIS = TRIS.copy()
NAN_TRIS[2, 1, 0] = np.nan
FLAT_TRIS = TRIS.copy()
FLAT_TRIS[1, 2] = FLAT_TRIS[1, 0]

# (file name, contents, expected location in the message or None)
CASES = [
    # --- XYZ / text PTS
    ("nan.xyz", "0 0 0\nnan 1 2\n1 1 0\n0 1 0\n0.5 0.5 0.2\n", "line 2"),
    ("inf.xyz", XYZ_OK + "inf 0 0\n", "line 6"),
    ("neginf.xyz", "0 0 0\n1 0 0\n1 -inf 0\n0 1 0\n0.5 0.5 0.2\n", "line 3"),
    ("header.xyz", "points: 5\n" + XYZ_OK, "line 1"),  # a header of names ("x y z") is read, not this
    ("header_count.xyz", "x y z w\n" + XYZ_OK, "line 1"),
    ("header_order.xyz", "y x z\n" + XYZ_OK, "line 1"),
    ("ragged_short.xyz", "0 0 0\n1 0\n1 1 0\n0 1 0\n0.5 0.5 0.2\n", "line 2"),
    ("ragged_long.xyz", "0 0 0\n1 0 0 5\n1 1 0\n0 1 0\n0.5 0.5 0.2\n", "line 2"),
    ("word.xyz", "0 0 0\n1 0 0\n1 1 abc\n0 1 0\n0.5 0.5 0.2\n", "line 3"),
    ("comments_only.xyz", "# nothing here\n# at all\n", None),
    ("empty.xyz", "", None),
    ("blank.xyz", "  \n\n\t\n", None),
    ("two_columns.xyz", "0 0\n1 0\n1 1\n0 1\n", "line 1"),
    ("double_dot.xyz", "0 0 0\n1 0 0\n1 1 0\n0 1 0\n0.5 0.5.2 0.2\n", "line 5"),
    ("huge_token.xyz", XYZ_OK + "1" * 5000 + " 0 0\n", "line 6"),
    ("garbage.xyz", bytes(range(256)) * 4, None),
    ("nan.pts", "0 0 0 0 0 1\n1 0 0 0 0 1\nnan 1 0 0 0 1\n0 1 0 0 0 1\n", "line 3"),
    ("variant.pts", "[Foo/PointSet/Ascii]\n0 0 0\n", "line 1"),
    ("expe_truncated.pts", expe(cut=7), "byte"),
    ("expe_count_lies.pts", expe(n_points=500), "byte"),
    ("expe_no_position.pts", expe(props=(("normal", 12),)), None),
    ("expe_no_data.pts", expe(data_line=False), None),
    ("expe_no_count.pts", expe().replace(b"nofpoints 5\n", b""), None),
    ("expe_bad_header.pts", expe(extra="hello world\n"), "line 4"),
    ("expe_nan.pts", expe(points=np.where(np.arange(15).reshape(5, 3) == 7, np.nan, PTS)), "byte"),
    # --- OBJ
    ("index0.obj", OBJ_V + "f 0 1 2\n", "line 6"),
    ("out_of_range.obj", OBJ_V + "f 1 2 5\nf 1 2 9\n", "line 7"),
    ("negative_out.obj", OBJ_V + "f -1 -2 -9\n", "line 6"),
    ("repeated.obj", OBJ_V + "f 1 2 5\nf 2 2 3\n", "line 7"),
    ("repeated_quad.obj", OBJ_V + "f 1 2 1 3\n", "line 6"),
    ("two_corners.obj", OBJ_V + "f 1 2\n", "line 6"),
    ("word_coord.obj", "v 0 0 0\nv 1 zero 0\n" + OBJ_V + "f 1 3 4\n", "line 2"),
    ("short_v.obj", "v 0 0\n" + OBJ_V, "line 1"),
    ("nan_v.obj", OBJ_V + "v nan 0 0\n", "line 6"),
    ("inf_v.obj", "v 0 0 inf\n" + OBJ_V, "line 1"),
    ("faces_only.obj", "f 1 2 3\n", None),
    ("float_index.obj", OBJ_V + "f 1.5 2 3\n", "line 6"),
    ("word_index.obj", OBJ_V + "f a/b/c 2 3\n", "line 6"),
    ("empty_corner.obj", OBJ_V + "f /1/2 2 3\n", "line 6"),
    ("overflow_index.obj", OBJ_V + "f 1 2 99999999999999999999999\n", "line 6"),
    ("empty.obj", "", None),
    ("comment_only.obj", "# v 1 2 3\n", None),
    ("word_vn.obj", OBJ_V + "vn 0 0 x\n", "line 6"),
    # --- OFF
    ("no_keyword.off", "5 4 0\n" + OFF_V + OFF_F, "line 1"),
    ("four_d.off", "4OFF\n5 4 0\n" + OFF_V + OFF_F, "line 1"),
    ("no_counts.off", "OFF\n", None),
    ("counts_lie.off", "OFF\n50 4 0\n" + OFF_V + OFF_F, "line 2"),
    ("negative_counts.off", "OFF\n-5 4 0\n" + OFF_V + OFF_F, "line 2"),
    ("huge_counts.off", "OFF\n1000000000000 1 0\n" + OFF_V + OFF_F, "line 2"),
    ("extra_lines.off", "OFF\n5 4 0\n" + OFF_V + OFF_F + "3 0 1 2\n", "line 12"),
    ("short_vertex.off", "OFF\n5 4 0\n" + OFF_V.replace("0 0 0", "0 0") + OFF_F, "line 3"),
    ("face_range.off", "OFF\n5 4 0\n" + OFF_V + "3 0 1 5\n" + OFF_F[8:], "line 8"),
    ("face_repeat.off", "OFF\n5 4 0\n" + OFF_V + OFF_F[:-8] + "3 3 3 4\n", "line 11"),
    ("face_short.off", "OFF\n5 4 0\n" + OFF_V + "3 0 1\n" + OFF_F[8:], "line 8"),
    ("face_two.off", "OFF\n5 4 0\n" + OFF_V + "2 0 1\n" + OFF_F[8:], "line 8"),
    ("nan_vertex.off", "OFF\n5 4 0\n" + OFF_V.replace("1 1 0", "1 nan 0") + OFF_F, "line 5"),
    ("binary.off", "OFF BINARY\n5 4 0\n", "line 1"),
    ("word_counts.off", "OFF\na b c\n" + OFF_V + OFF_F, "line 2"),
    ("noff_short.off", "NOFF\n5 4 0\n" + OFF_V + OFF_F, "line 3"),
    ("float_face.off", "OFF\n5 4 0\n" + OFF_V + "3 0 1 4.5\n" + OFF_F[8:], "line 8"),
    ("comment_only.off", "# OFF\n", None),
    # --- PLY header
    ("no_number.ply", PLY_HEAD.replace("element vertex 5", "element vertex"), "line 3"),
    ("negative.ply", PLY_HEAD.replace("element vertex 5", "element vertex -5"), "line 3"),
    ("word_count.ply", PLY_HEAD.replace("element face 4", "element face four"), "line 7"),
    ("no_end_header.ply", PLY_HEAD.replace("end_header\n", ""), None),
    ("bad_magic.ply", PLY_HEAD.replace("ply", "plx", 1) + OFF_V + OFF_F, "line 1"),
    ("unknown_type.ply", PLY_HEAD.replace("float y", "float128 y") + OFF_V + OFF_F, "line 5"),
    ("unknown_list_type.ply", PLY_HEAD.replace("uchar int", "uchar int128") + OFF_V + OFF_F, "line 8"),
    ("bad_format.ply", PLY_HEAD.replace("ascii", "binary_middle_endian") + OFF_V + OFF_F, "line 2"),
    ("no_format.ply", PLY_HEAD.replace("format ascii 1.0\n", "") + OFF_V + OFF_F, "line 2"),
    ("property_first.ply", "ply\nformat ascii 1.0\nproperty float x\n" + PLY_HEAD[26:] + OFF_V + OFF_F, "line 3"),
    ("bad_list.ply", PLY_HEAD.replace("list uchar int vertex_indices", "list uchar vertex_indices")
     + OFF_V + OFF_F, "line 8"),
    ("float_list_count.ply", PLY_HEAD.replace("list uchar int", "list float int") + OFF_V + OFF_F, "line 8"),
    ("float_indices.ply", PLY_HEAD.replace("list uchar int", "list uchar float") + OFF_V + OFF_F, "line 7"),
    ("no_xyz.ply", PLY_HEAD.replace("float x", "float a") + OFF_V + OFF_F, "line 3"),
    ("no_vertex.ply", PLY_HEAD.replace("element vertex 5", "element point 5") + OFF_V + OFF_F, None),
    ("no_indices.ply", PLY_HEAD.replace("vertex_indices", "corners") + OFF_V + OFF_F, "line 7"),
    ("junk_header_line.ply", PLY_HEAD.replace("end_header", "hello\nend_header"), "line 9"),
    # --- PLY ascii body
    ("few_lines.ply", PLY_HEAD + OFF_V + OFF_F[:-8], None),
    ("more_lines.ply", PLY_HEAD + OFF_V + OFF_F + "3 0 1 2\n", "line 19"),
    ("nan.ply", PLY_HEAD + OFF_V.replace("1 1 0", "nan 1 0") + OFF_F, "line 12"),
    ("word.ply", PLY_HEAD + OFF_V.replace("1 1 0", "1 one 0") + OFF_F, "line 12"),
    ("ascii_range.ply", PLY_HEAD + OFF_V + OFF_F.replace("3 2 3 4", "3 2 3 7"), "line 17"),
    ("ascii_repeat.ply", PLY_HEAD + OFF_V + OFF_F.replace("3 2 3 4", "3 2 2 4"), "line 17"),
    ("ascii_list_lies.ply", PLY_HEAD + OFF_V + OFF_F.replace("3 2 3 4", "4 2 3 4"), "line 17"),
    ("ascii_short_vertex.ply", PLY_HEAD + OFF_V.replace("1 1 0", "1 1") + OFF_F, "line 12"),
    # --- PLY binary body
    ("le_truncated_vertices.ply", ply_binary("<", cut=4 * 13 + 10), "byte"),
    ("be_truncated_faces.ply", ply_binary(">", cut=3), "byte"),
    ("huge_count.ply", ply_binary("<", n_vertices=10 ** 12), "byte"),
    ("huge_faces.ply", ply_binary("<", n_faces=4 * 10 ** 9), "byte"),
    ("bin_range.ply", ply_binary("<", faces=np.array([[0, 1, 4], [1, 2, 70000], [2, 3, 4]])), "byte"),
    ("bin_negative_index.ply", ply_binary(">", faces=np.array([[0, 1, 4], [1, 2, -1]])), "byte"),
    ("bin_repeat.ply", ply_binary(">", faces=np.array([[0, 1, 4], [1, 1, 4]])), "byte"),
    ("bin_nan.ply", ply_binary("<", points=np.where(PTS == 0.2, np.nan, PTS)), "byte"),
    ("bin_trailing.ply", ply_binary("<", extra=b"\x01\x02garbage"), "byte"),
    ("bin_negative_list.ply", ply_binary("<", count_type="char", sizes=[3, -3, 3, 3]), "byte"),
    ("bin_list_lies.ply", ply_binary("<", sizes=[3, 200, 3, 3]), "byte"),
    ("ascii_huge_list.ply", PLY_HEAD + OFF_V + OFF_F.replace("3 2 3 4", "4000000000 2 3 4"), "line 17"),
    ("bin_huge_list.ply", ply_binary("<", count_type="int", sizes=[2 ** 31 - 1, 3, 3, 3]), "byte"),
    # --- more OFF / OBJ
    ("huge_face_size.off", "OFF\n5 4 0\n" + OFF_V + "4000000000 0 1 2\n" + OFF_F[8:], "line 8"),
    ("negative_face_size.off", "OFF\n5 4 0\n" + OFF_V + "-3 0 1 2\n" + OFF_F[8:], "line 8"),
    ("continuation.obj", OBJ_V + "f 1 2 \\\n 5\nf 1 2 9\n", "line 8"),  # the joined face is read
    ("crossing_polygon.obj", "v 0 0 0\nv 1 1 0\nv 1 0 0\nv 0 1 0\nv 0.5 2 0\nf 1 2 3 4 5\n", "line 6"),
    ("flat_polygon.off", "OFF\n4 1 0\n0 0 0\n1 0 0\n2 0 0\n3 0 0\n4 0 1 2 3\n", "line 7"),
    ("pinched_polygon.ply", PLY_HEAD.replace("face 4", "face 1") + OFF_V.replace("0.5 0.5 0.2", "1 1 0")
     + "5 0 1 2 4 3\n", "line 15"),
    ("strips_elsewhere.ply", PLY_HEAD.replace("element face", "element polygon") + OFF_V + OFF_F, "line 7"),
    ("strips_out_of_range.ply", PLY_HEAD.replace("face 4", "tristrips 1").replace("uchar int", "int int")
     + OFF_V + "5 0 1 3 2 7\n", "line 15"),
    # --- STL
    ("count_more.stl", stl_binary(TRIS, count=5), "byte 80"),
    ("count_less.stl", stl_binary(TRIS, count=2), "byte 80"),
    ("count_max.stl", stl_binary(TRIS, count=2 ** 32 - 1), "byte 80"),
    ("truncated.stl", stl_binary(TRIS, cut=10), "byte 80"),
    ("one_triangle_more.stl", stl_binary(TRIS) + b"\0" * 50, "byte 80"),
    ("short.stl", b"\x07" * 50, None),
    ("ascii_truncated.stl", stl_ascii(TRIS)[:-len("endsolid s\n")], "line"),
    ("ascii_word.stl", stl_ascii(TRIS).replace("vertex 1.0 1.0 0.0", "vertex 1.0 one 0.0", 1), "line"),
    ("ascii_nan.stl", stl_ascii(NAN_TRIS), "line 19"),
    ("ascii_two_corners.stl", stl_ascii(TRIS, corners=2), "line 6"),
    ("ascii_empty.stl", "solid s\nendsolid s\n", None),
    ("bin_nan.stl", stl_binary(NAN_TRIS), "byte 184"),
    ("bin_flat.stl", stl_binary(FLAT_TRIS), "byte 134"),
    ("ascii_flat.stl", stl_ascii(FLAT_TRIS), "line 9"),
]


def _write(tmp_path, name, contents):
    path = tmp_path / name
    path.write_bytes(contents if isinstance(contents, bytes) else contents.encode())
    return path


def _check_message(message, path, where):
    assert "\n" not in message and "\r" not in message
    assert str(path) in message
    if where is not None:
        assert where in message


@pytest.mark.parametrize("name, contents, where", CASES, ids=[c[0] for c in CASES])
def test_hostile_file_raises_input_file_error(tmp_path, name, contents, where):
    path = _write(tmp_path, name, contents)
    with pytest.raises(InputFileError) as info:
        load_surface(path)
    _check_message(str(info.value), path, where)


@pytest.mark.parametrize("name, contents, where", CASES, ids=[c[0] for c in CASES])
def test_hostile_file_cli_exit_2_one_line_no_output(tmp_path, capsys, name, contents, where):
    path = _write(tmp_path, name, contents)
    out = tmp_path / "out.csv"
    assert cli_main(["flatten", str(path), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "InputFileError" in err and str(path) in err
    assert not out.exists()


def test_directory_is_not_called_missing(tmp_path):
    folder = tmp_path / "mesh.obj"
    folder.mkdir()
    with pytest.raises(InputFileError, match="is a directory"):
        load_surface(folder)


def test_missing_file(tmp_path):
    with pytest.raises(InputFileError, match="no such file"):
        load_surface(tmp_path / "absent.ply")


def test_broken_symlink_is_missing(tmp_path):
    link = tmp_path / "link.xyz"
    link.symlink_to(tmp_path / "nowhere.xyz")
    with pytest.raises(InputFileError, match="no such file"):
        load_surface(link)


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs")
def test_fifo_is_refused_without_blocking(tmp_path):
    fifo = tmp_path / "pipe.xyz"
    os.mkfifo(fifo)  # opening it for reading would block forever: it must not be opened
    with pytest.raises(InputFileError, match="not a regular file"):
        load_surface(fifo)


@pytest.mark.skipif(hasattr(os, "geteuid") and os.geteuid() == 0, reason="root reads any file")
def test_unreadable_file(tmp_path):
    path = _write(tmp_path, "secret.xyz", XYZ_OK)
    path.chmod(0)
    try:
        with pytest.raises(InputFileError, match="cannot read"):
            load_surface(path)
    finally:
        path.chmod(0o644)


def test_unsupported_extension_cli(tmp_path, capsys):
    path = _write(tmp_path, "mesh.vtk", "x")
    assert cli_main(["flatten", str(path), "-o", str(tmp_path / "o.obj")]) == 2
    assert capsys.readouterr().err.count("\n") == 1


def test_directory_cli(tmp_path, capsys):
    folder = tmp_path / "cloud.xyz"
    folder.mkdir()
    assert cli_main(["flatten", str(folder), "-o", str(tmp_path / "o.csv")]) == 2
    err = capsys.readouterr().err
    assert "is a directory" in err and err.count("\n") == 1
