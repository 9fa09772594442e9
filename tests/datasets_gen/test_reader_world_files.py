"""Files as other tools write them: byte-order marks, old-Mac line breaks, OBJ line
continuation, concave and straight-cornered polygons, upper-case and padded STL, STL
corners that differ by rounding, PLY triangle strips, XYZ headers, semicolons and the
extensions other tools give XYZ text.

Every test here failed on the readers before they handled that case (the file was refused,
or worse, read wrongly: OBJ dropped its first vertex after a BOM, PLY strips became a point
cloud, a concave polygon became overlapping triangles).
"""

from __future__ import annotations

import struct
import warnings

import numpy as np
import pytest

from parambench.datasets_gen.errors import InputFileError
from parambench.datasets_gen.formats import READERS, read_file
from parambench.datasets_gen.formats._common import polygons_to_triangles
from parambench.datasets_gen.io import SUPPORTED_EXTENSIONS, load_surface

BOM = b"\xef\xbb\xbf"

# a square of 4 triangles around a raised centre
PTS = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.5, 0.5, 0.25]])
TRI = np.array([[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]])


def _rows(points):
    return "".join(f"{x!r} {y!r} {z!r}\n" for x, y, z in points.tolist())


def _obj():
    return "".join(f"v {r}" for r in _rows(PTS).splitlines(True)) + "".join(f"f {a + 1} {b + 1} {c + 1}\n"
                                                                         for a, b, c in TRI)


def _off():
    return f"OFF\n{len(PTS)} {len(TRI)} 0\n" + _rows(PTS) + "".join(f"3 {a} {b} {c}\n" for a, b, c in TRI)


def _ply():
    return ("ply\nformat ascii 1.0\nelement vertex 5\nproperty double x\nproperty double y\nproperty double z\n"
            "element face 4\nproperty list uchar int vertex_indices\nend_header\n" + _rows(PTS)
            + "".join(f"3 {a} {b} {c}\n" for a, b, c in TRI))


def _stl(upper=False):
    rows = ["solid s"]
    for t in PTS[TRI].tolist():
        rows += ["facet normal 0 0 1", "outer loop", *(f"vertex {x!r} {y!r} {z!r}" for x, y, z in t),
                 "endloop", "endfacet"]
    text = "\n".join(rows + ["endsolid s"]) + "\n"
    return text.upper() if upper else text


def _stl_binary(tris, header=b"", extra=b""):
    body = b"".join(struct.pack("<3f", 0, 0, 1) + np.asarray(t, "<f4").tobytes() + b"\0\0" for t in tris)
    return header.ljust(80, b" ") + struct.pack("<I", len(tris)) + body + extra


TEXT_FILES = {"obj": _obj, "off": _off, "ply": _ply, "stl": _stl, "xyz": lambda: _rows(PTS),
              "pts": lambda: f"{len(PTS)}\n" + _rows(PTS)}


def _write(tmp_path, name, contents):
    path = tmp_path / name
    path.write_bytes(contents if isinstance(contents, bytes) else contents.encode())
    return path


def _same(a, b):
    assert np.array_equal(a.points, b.points)
    assert (a.faces is None and b.faces is None) or np.array_equal(a.faces, b.faces)


# --- 1. UTF-8 byte-order mark ------------------------------------------------------------------------

@pytest.mark.parametrize("ext", sorted(TEXT_FILES))
def test_utf8_bom_is_ignored_by_every_text_reader(tmp_path, ext):
    text = TEXT_FILES[ext]().encode()
    plain = read_file(_write(tmp_path, f"plain.{ext}", text))
    marked = read_file(_write(tmp_path, f"bom.{ext}", BOM + text))
    _same(marked, plain)
    assert len(marked.points) == len(PTS)  # OBJ used to lose its first vertex


def test_bom_does_not_shift_line_numbers(tmp_path):
    path = _write(tmp_path, "bad.obj", BOM + (_obj() + "f 1 2 9\n").encode())
    with pytest.raises(InputFileError, match="line 10: face index 9"):
        read_file(path)


def test_binary_payloads_are_never_treated_as_text(tmp_path):
    # a binary STL whose 80-byte header happens to start with the BOM bytes and "solid"
    tris = PTS[TRI].astype(np.float32)
    s = read_file(_write(tmp_path, "b.stl", _stl_binary(tris, header=BOM + b"solid")))
    assert np.array_equal(s.points[s.faces], tris)
    # a binary PLY with a BOM before its header: the body is read, byte offsets are the file's
    head = ("ply\nformat binary_little_endian 1.0\nelement vertex 5\nproperty double x\nproperty double y\n"
            "property double z\nelement face 4\nproperty list uchar int vertex_indices\nend_header\n").encode()
    body = PTS.astype("<f8").tobytes() + b"".join(bytes([3]) + np.asarray(f, "<i4").tobytes() for f in TRI)
    s = read_file(_write(tmp_path, "b.ply", BOM + head + body))
    assert np.array_equal(s.points, PTS) and np.array_equal(s.faces, TRI)
    bad = body[:-4] + np.asarray([9], "<i4").tobytes()
    with pytest.raises(InputFileError, match=f"byte {3 + len(head) + 5 * 24 + 3 * 13}"):
        read_file(_write(tmp_path, "c.ply", BOM + head + bad))


# --- 2. old-Mac line breaks (CR only) ----------------------------------------------------------------

@pytest.mark.parametrize("ext", sorted(TEXT_FILES))
def test_cr_only_line_breaks(tmp_path, ext):
    text = TEXT_FILES[ext]().encode()
    plain = read_file(_write(tmp_path, f"plain.{ext}", text))
    _same(read_file(_write(tmp_path, f"mac.{ext}", text.replace(b"\n", b"\r"))), plain)
    _same(read_file(_write(tmp_path, f"dos.{ext}", text.replace(b"\n", b"\r\n"))), plain)


@pytest.mark.parametrize("newline", [b"\r", b"\r\n"])
def test_cr_and_crlf_files_name_the_right_line(tmp_path, newline):
    text = (_obj().replace("v 1.0 1.0 0.0", "v 1.0 one 0.0") + "# end\n").encode().replace(b"\n", newline)
    with pytest.raises(InputFileError, match="line 3: vertex coordinate 'one'"):
        read_file(_write(tmp_path, "bad.obj", text))
    text = ("OFF\n5 2 0\n" + _rows(PTS) + "3 0 1 4\n3 1 2 7\n").encode().replace(b"\n", newline)
    with pytest.raises(InputFileError, match="line 9"):
        read_file(_write(tmp_path, "bad.off", text))


def test_cr_only_binary_ply_header_keeps_its_payload(tmp_path):
    head = ("ply\rformat binary_little_endian 1.0\relement vertex 5\rproperty double x\rproperty double y\r"
            "property double z\relement face 4\rproperty list uchar int vertex_indices\rend_header\r").encode()
    points = PTS.copy()  # coordinates whose bytes hold CRs and LFs
    points[4, 1:] = struct.unpack("<2d", b"\r" * 7 + b"\x3f" + b"\n" * 7 + b"\x3f")
    body = points.astype("<f8").tobytes() + b"".join(bytes([3]) + np.asarray(f, "<i4").tobytes() for f in TRI)
    s = read_file(_write(tmp_path, "mac.ply", head + body))
    assert np.array_equal(s.points, points) and np.array_equal(s.faces, TRI)


# --- 3. OBJ line continuation ------------------------------------------------------------------------

def test_obj_line_continuation(tmp_path):
    lines = _obj().splitlines()
    lines[1] = "v 1.0 \\\n0.0 \\\n  0.0"  # one vertex over three lines
    lines[-1] = "f 4 \\\r\n1 5"  # a face over two (with a CRLF)
    text = "\n".join(lines) + "\nf 1 2 9\n"
    with pytest.raises(InputFileError, match="line 13: face index 9"):  # lines after keep their numbers
        read_file(_write(tmp_path, "bad.obj", text))
    s = read_file(_write(tmp_path, "c.obj", "\n".join(lines) + "\n"))
    assert np.array_equal(s.points, PTS) and np.array_equal(s.faces, TRI)
    # a comment ends at its line: its backslash continues nothing
    s = read_file(_write(tmp_path, "d.obj", "# a comment \\\n" + _obj()))
    assert np.array_equal(s.points, PTS)


# --- 4. polygons: fan when convex, ear clipping otherwise -------------------------------------------

L_HEXAGON = np.array([[2, 0, 0], [2, 1, 0], [1, 1, 0], [1, 2, 0], [0, 2, 0], [0, 0, 0]], float)


def _inside_l(p):
    x, y = p[..., 0], p[..., 1]
    tol = 1e-12
    return (x >= -tol) & (y >= -tol) & (((x <= 2 + tol) & (y <= 1 + tol)) | ((x <= 1 + tol) & (y <= 2 + tol)))


def _triangulate(points, polygon):
    return polygons_to_triangles(np.asarray(polygon, dtype=np.int64), np.array([len(polygon)]), points,
                                 lambda f: "line 1", "poly.obj")


def _signed_areas(points, tris):
    p = points[tris]
    return 0.5 * np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])[:, 2]


@pytest.mark.parametrize("start", range(6))
@pytest.mark.parametrize("reverse", [False, True])
def test_l_hexagon_covers_its_area_once_from_any_corner(start, reverse):
    polygon = np.roll(np.arange(6), -start)
    if reverse:
        polygon = polygon[::-1]
    tris = _triangulate(L_HEXAGON, polygon)
    assert tris.shape == (4, 3)
    areas = _signed_areas(L_HEXAGON, tris) * (-1 if reverse else 1)
    assert np.all(areas > 0)  # every triangle wound like the polygon, none flat
    assert np.isclose(areas.sum(), 3.0)  # the L's area, so no two triangles overlap...
    p = L_HEXAGON[tris]
    midpoints = (p + np.roll(p, -1, axis=1)) / 2
    assert _inside_l(p.mean(axis=1)).all() and _inside_l(midpoints).all()  # ...and none covers the notch


def test_l_octagon_with_mid_edge_corners_gives_no_zero_area_triangle():
    # the L of 3 unit cells with the corners (1, 0) and (0, 1) in the middle of its long edges
    points = np.array([[2, 0, 0], [2, 1, 0], [1, 1, 0], [1, 2, 0], [0, 2, 0], [0, 1, 0], [0, 0, 0], [1, 0, 0]], float)
    for start in range(8):
        tris = _triangulate(points, np.roll(np.arange(8), -start))
        areas = _signed_areas(points, tris)
        assert len(tris) == 6 and np.all(areas > 0.1) and np.isclose(areas.sum(), 3.0)


def test_convex_polygons_keep_the_fan():
    square = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0.1], [0, 1, 0]], float)
    assert _triangulate(square, [2, 3, 0, 1]).tolist() == [[2, 3, 0], [2, 0, 1]]
    angles = np.linspace(0, 2 * np.pi, 6)[:-1]
    pentagon = np.stack([np.cos(angles), np.sin(angles), 0 * angles], axis=1) + [1e6, -2e6, 5.0]
    assert _triangulate(pentagon, [4, 0, 1, 2, 3]).tolist() == [[4, 0, 1], [4, 1, 2], [4, 2, 3]]
    assert _triangulate(pentagon, [3, 2, 1, 0, 4]).tolist() == [[3, 2, 1], [3, 1, 0], [3, 0, 4]]  # clockwise


def test_polygon_that_crosses_itself_is_refused_with_its_line(tmp_path):
    star = [[float(np.cos(a)), float(np.sin(a)), 0.0] for a in np.pi / 2 + 4 * np.pi / 5 * np.arange(5)]  # pentagram
    text = "".join(f"v {x!r} {y!r} {z!r}\n" for x, y, z in star) + "f 1 2 3\nf 1 2 3 4 5\n"
    with pytest.raises(InputFileError, match="line 7: a polygon of 5 corners crosses or touches itself"):
        read_file(_write(tmp_path, "star.obj", text))
    flat = "v 0 0 0\nv 1 0 0\nv 2 0 0\nv 3 0 0\nf 1 2 3 4\n"
    with pytest.raises(InputFileError, match="line 5: a polygon of 4 corners has no area"):
        read_file(_write(tmp_path, "flat.obj", flat))
    pinched = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4 5\n"
    with pytest.raises(InputFileError, match="line 6: corners 3 and 4 of a polygon of 5 corners are at the same"):
        read_file(_write(tmp_path, "pinched.obj", pinched))


@pytest.mark.parametrize("ext", ["obj", "off", "ply"])
def test_concave_polygons_in_every_mesh_reader(tmp_path, ext):
    rows = _rows(L_HEXAGON)
    text = {"obj": "".join("v " + r for r in rows.splitlines(True)) + "f 1 2 3 4 5 6\n",
            "off": "OFF\n6 1 0\n" + rows + "6 0 1 2 3 4 5\n",
            "ply": ("ply\nformat ascii 1.0\nelement vertex 6\nproperty double x\nproperty double y\n"
                    "property double z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
                    + rows + "6 0 1 2 3 4 5\n")}[ext]
    s = load_surface(_write(tmp_path, f"l.{ext}", text))
    areas = _signed_areas(s.points, s.faces)
    assert np.all(areas > 0) and np.isclose(areas.sum(), 3.0)


def test_grid_of_l_octagons_loads(tmp_path):
    """Blender-style n-gons: 2x2 cells with one cell cut off, mid-edge corners included."""
    n = 5
    x, y = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n))
    points = np.stack([x.ravel(), y.ravel(), 0 * x.ravel()], axis=1)
    idx = np.arange(n * n).reshape(n, n)
    faces = []
    for r in range(0, n - 1, 2):
        for c in range(0, n - 1, 2):
            faces.append([idx[r, c + 2], idx[r + 1, c + 2], idx[r + 1, c + 1], idx[r + 2, c + 1], idx[r + 2, c],
                          idx[r + 1, c], idx[r, c], idx[r, c + 1]])
            faces.append([idx[r + 1, c + 1], idx[r + 1, c + 2], idx[r + 2, c + 2], idx[r + 2, c + 1]])
    text = "".join("v " + r for r in _rows(points).splitlines(True))
    text += "".join("f " + " ".join(str(i + 1) for i in f) + "\n" for f in faces)
    s = load_surface(_write(tmp_path, "grid.obj", text))  # was refused: zero-area fan triangles
    areas = _signed_areas(s.points, s.faces)
    assert np.all(areas > 0) and np.isclose(areas.sum(), 1.0)


# --- 5. STL: upper-case keywords, padded binary -------------------------------------------------------

def test_upper_case_ascii_stl(tmp_path):
    plain = read_file(_write(tmp_path, "a.stl", _stl()))
    _same(read_file(_write(tmp_path, "A.stl", _stl(upper=True))), plain)
    _same(read_file(_write(tmp_path, "B.stl", _stl().replace("facet", "Facet").replace("endsolid", "EndSolid"))),
          plain)


def test_binary_stl_with_padding_is_read_with_a_warning(tmp_path):
    tris = PTS[TRI].astype(np.float32)
    exact = read_file(_write(tmp_path, "exact.stl", _stl_binary(tris)))
    for extra in (b"\0", b"\0\0", b"\x07" * 49):
        path = _write(tmp_path, "pad.stl", _stl_binary(tris, extra=extra))
        with pytest.warns(UserWarning, match=f"{len(extra)} byte.* no triangle is lost"):
            _same(read_file(path), exact)
    with pytest.raises(InputFileError, match="byte 80"):  # a whole triangle more than the count: refused
        read_file(_write(tmp_path, "more.stl", _stl_binary(tris, extra=b"\0" * 50)))
    with pytest.raises(InputFileError, match="byte 80"):  # shorter than the count says: refused
        read_file(_write(tmp_path, "short.stl", _stl_binary(tris)[:-1]))


# --- 6. STL corners that differ by rounding ------------------------------------------------------------

def _soup(points, faces, jitter, seed=0):
    rng = np.random.default_rng(seed)
    rows = ["solid s"]
    for f in faces:
        corners = points[f] * (1 + rng.normal(0, jitter, (3, 3)))
        rows += ["facet normal 0 0 1", "outer loop", *(f"vertex {x!r} {y!r} {z!r}" for x, y, z in corners.tolist()),
                 "endloop", "endfacet"]
    return "\n".join(rows + ["endsolid s"]) + "\n"


def test_stl_corners_within_rounding_are_one_vertex(tmp_path):
    n = 6
    x, y = np.meshgrid(np.linspace(-1, 1, n), np.linspace(-1, 1, n))
    points = np.stack([x.ravel(), y.ravel(), 0.3 * np.exp(-(x.ravel() ** 2 + y.ravel() ** 2))], axis=1)
    idx = np.arange(n * n).reshape(n, n)
    q = np.stack([idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()], axis=1)
    faces = np.concatenate([q[:, [0, 1, 2]], q[:, [0, 2, 3]]])
    # a stray triangle far away must not make the tolerance coarse (a box-relative one would be)
    stray = np.array([[1e5, 0, 0], [1e5 + 1, 0, 0], [1e5, 1, 0]])
    text = _soup(points, faces, 1e-12)[:-len("endsolid s\n")] + _soup(stray, [[0, 1, 2]], 0)[len("solid s\n"):]
    s = load_surface(_write(tmp_path, "soup.stl", text))
    assert s.n_points == n * n + 3 and len(s.faces) == len(faces) + 1
    first = np.unique(faces.ravel(), return_index=True)[1]
    order = faces.ravel()[np.sort(first)]  # grid vertices in order of first appearance
    assert np.allclose(s.points[:n * n], points[order], rtol=1e-9, atol=0)
    # two really distinct corners closer than the tolerance of the old box rule (1e-9 of 1e5) stay apart
    near = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1e-5, 0, 0], [0, -1, 0], [1, 0, 0]], float)
    s = read_file(_write(tmp_path, "near.stl", _soup(near, [[0, 1, 2], [3, 4, 5]], 0)))
    assert len(s.points) == 5


# --- 7. PLY triangle strips ---------------------------------------------------------------------------

def _strip_grid(n=4):
    x, y = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n))
    points = np.stack([x.ravel(), y.ravel(), 0 * x.ravel()], axis=1)
    idx = np.arange(n * n).reshape(n, n)
    strips = []
    for r in range(n - 1):
        strips += [v for c in range(n) for v in (idx[r + 1, c], idx[r, c])] + [-1]
    return points, strips


def _strip_ply(points, strips, fmt="ascii", element="tristrips", records=None):
    records = records or [strips]
    head = (f"ply\nformat {fmt} 1.0\nelement vertex {len(points)}\nproperty double x\nproperty double y\n"
            f"property double z\nelement {element} {len(records)}\nproperty list int int vertex_indices\n"
            "end_header\n").encode()
    if fmt == "ascii":
        return head + (_rows(points) + "".join(f"{len(r)} {' '.join(map(str, r))}\n" for r in records)).encode()
    body = points.astype("<f8").tobytes()
    return head + body + b"".join(np.asarray([len(r), *r], "<i4").tobytes() for r in records)


@pytest.mark.parametrize("fmt", ["ascii", "binary_little_endian"])
def test_ply_tristrips_become_triangles(tmp_path, fmt):
    points, strips = _strip_grid()
    s = load_surface(_write(tmp_path, "strips.ply", _strip_ply(points, strips, fmt)))
    assert len(s.faces) == 2 * 3 * 3
    areas = _signed_areas(s.points, s.faces)
    assert np.all(areas > 0) and np.isclose(areas.sum(), 1.0)  # one winding: odd triangles swapped
    # one strip stitched with repeated indices (degenerate triangles, skipped), split over two records
    stitched = strips[:8] + [strips[7], strips[9]] + strips[9:17]
    s2 = read_file(_write(tmp_path, "stitched.ply", _strip_ply(points, stitched, fmt, records=[stitched, strips[18:]])))
    assert sorted(map(tuple, np.sort(s2.faces, axis=1))) == sorted(map(tuple, np.sort(s.faces, axis=1)))
    assert np.all(_signed_areas(s2.points, s2.faces) > 0)


def test_ply_strip_index_out_of_range_and_unknown_connectivity(tmp_path):
    points, strips = _strip_grid()
    with pytest.raises(InputFileError, match="strip index 99 is out of range"):
        read_file(_write(tmp_path, "bad.ply", _strip_ply(points, strips[:-1] + [99])))
    with pytest.raises(InputFileError, match="'polygons'.*'face' element") as info:
        read_file(_write(tmp_path, "poly.ply", _strip_ply(points, strips, element="polygons")))
    assert "line 7" in str(info.value)


# --- 8. XYZ text: headers, semicolons, decimal commas, other extensions --------------------------------

XYZ_PTS = np.array([[0.5, 0.25, 1.0], [1.5, 0.75, -2.0], [2.0, 3.0, 0.125], [-1.0, 0.0, 4.0]])
UNIT = np.array([[0, 0, 1], [0, 1, 0], [1, 0, 0], [0.6, 0.8, 0]])


def _table(values, sep=" "):
    return "".join(sep.join(repr(float(v)) for v in row) + "\n" for row in values)


@pytest.mark.parametrize("header, sep", [("x y z", " "), ("X,Y,Z", ","), ("x;y;z", ";"), ("X\tY\tZ", "\t"),
                                         ("pos_x pos_y pos_z", " ")])
def test_xyz_header_of_column_names(tmp_path, header, sep):
    s = read_file(_write(tmp_path, "h.xyz", header + "\n" + _table(XYZ_PTS, sep)))
    assert np.array_equal(s.points, XYZ_PTS) and s.normals is None


def test_xyz_header_names_the_normals(tmp_path):
    values = np.hstack([XYZ_PTS, UNIT * 2])  # not unit length: no normals by guessing
    s = read_file(_write(tmp_path, "n.xyz", "x y z nx ny nz\n" + _table(values)))
    assert np.array_equal(s.points, XYZ_PTS) and np.array_equal(s.normals, UNIT * 2)
    values = np.hstack([XYZ_PTS, [[200, 10, 10]] * 4, UNIT])
    s = read_file(_write(tmp_path, "m.csv", "X,Y,Z,R,G,B,Normal_X,Normal_Y,Normal_Z\n" + _table(values, ",")))
    assert np.array_equal(s.normals, UNIT)
    # a header that names no normals: unit-vector columns are something else (here colours in [0, 1])
    values = np.hstack([XYZ_PTS, UNIT])
    s = read_file(_write(tmp_path, "c.xyz", "X Y Z R G B\n" + _table(values)))
    assert np.array_equal(s.points, XYZ_PTS) and s.normals is None
    s = read_file(_write(tmp_path, "g.xyz", _table(values)))  # without the header, as before: normals
    assert np.array_equal(s.normals, UNIT)
    # CloudCompare's "//" header names the columns too
    s = read_file(_write(tmp_path, "cc.xyz", "//X,Y,Z,R,G,B\n" + _table(values, ",")))
    assert s.normals is None


def test_xyz_semicolons_and_decimal_commas(tmp_path):
    s = read_file(_write(tmp_path, "s.xyz", _table(XYZ_PTS, ";")))
    assert np.array_equal(s.points, XYZ_PTS)
    text = "X;Y;Z\n" + _table(XYZ_PTS, ";").replace(".", ",")  # European CSV: 0,5;0,25;1,0
    s = read_file(_write(tmp_path, "d.csv", text))
    assert np.array_equal(s.points, XYZ_PTS)


@pytest.mark.parametrize("ext", [".txt", ".csv", ".asc", ".TXT"])
def test_other_extensions_of_xyz_text(tmp_path, ext):
    s = load_surface(_write(tmp_path, "cloud" + ext, _table(XYZ_PTS, "," if ext == ".csv" else " ")))
    assert np.array_equal(s.points, XYZ_PTS) and s.faces is None
    assert ext.lower() in SUPPORTED_EXTENSIONS and ext.lower() in READERS


def test_unknown_extension_lists_the_accepted_ones(tmp_path):
    path = _write(tmp_path, "cloud.vtk", _table(XYZ_PTS))
    for load in (load_surface, read_file):
        with pytest.raises(InputFileError, match="unsupported file type '.vtk'") as info:
            load(path)
        assert all(ext in str(info.value) for ext in (".xyz", ".txt", ".csv", ".asc", ".obj", ".ply", ".las", ".laz",
                                                      ".e57"))


def test_warnings_are_not_raised_for_ordinary_files(tmp_path):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        read_file(_write(tmp_path, "ok.stl", _stl_binary(PTS[TRI].astype(np.float32))))


def test_many_polygons_with_one_bent_corner_are_fanned_from_it():
    """Darts (one notch) and squares with a vertex in mid-edge, 200 of each at random
    starting corners in one file: each fanned from its bent corner in one vectorised pass
    (ear clipping them one by one took 0.6 ms a polygon), every triangle wound like its
    polygon with area, and the areas summing to the polygon's."""
    rng = np.random.default_rng(0)
    dart = np.array([[0, 0, 0], [2, 1, 0], [0, 2, 0], [0.6, 1, 0]], float)  # the notch at (0.6, 1)
    square = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [2, 2, 0], [0, 2, 0]], float)  # (1, 0) in mid-edge
    points, indices, sizes, expected = [], [], [], []
    for shape, area in [(dart, 1.4), (square, 4.0)] * 200:
        offset = len(points) and sum(len(p) for p in points)
        corners = np.roll(np.arange(len(shape)), -rng.integers(len(shape))) + offset
        points.append(shape + rng.normal(size=3) * 10)
        indices.append(corners)
        sizes.append(len(shape))
        expected.append(area)
    pts = np.vstack(points)
    tris = polygons_to_triangles(np.concatenate(indices), np.array(sizes), pts, lambda f: f"face {f}", "x.obj")
    areas = _signed_areas(pts, tris)
    per_polygon = np.add.reduceat(areas, np.concatenate([[0], np.cumsum(np.array(sizes) - 2)[:-1]]))
    assert np.all(areas > 0.05) and np.allclose(per_polygon, expected)


def test_a_name_ending_in_a_backslash_continues_nothing(tmp_path):
    """``g C:\\temp\\`` (a group named after a Windows folder) swallowed the next line's vertex."""
    path = _write(tmp_path, "g.obj", b"g C:\\temp\\\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 \\\n 2 3\n")
    mesh = read_file(path)
    assert len(mesh.points) == 3 and mesh.faces.tolist() == [[0, 1, 2]]


@pytest.mark.parametrize("sep", [b"\t", b" "])
def test_decimal_commas_between_spaces_or_tabs(tmp_path, sep):
    """``1,5<TAB>2,25<TAB>3``: each value was split at its comma into two, six values a row,
    silently. Commas as separators (with or without spaces after them) stay separators."""
    rows = [[0.5, 1.25, -3.0], [2.0, 0.75, 1.5], [1.0, 2.0, 0.0], [0.25, 0.5, 4.0]]
    text = b"\n".join(sep.join(f"{v:g}".replace(".", ",").encode() for v in row) for row in rows) + b"\n"
    assert np.allclose(read_file(_write(tmp_path, "p.txt", text)).points, rows)
    for joiner in (b",", b", "):
        ints = b"\n".join(joiner.join(str(int(v)).encode() for v in row) for row in [[1, 2, 3], [4, 5, 6], [7, 8, 9],
                                                                                      [1, 0, 2]]) + b"\n"
        assert read_file(_write(tmp_path, "i.csv", ints)).points.tolist()[0] == [1.0, 2.0, 3.0]


def test_quoted_header_and_mixed_line_breaks(tmp_path):
    """R's write.csv quotes its header; a CR-only file whose last line ends in CRLF."""
    path = _write(tmp_path, "q.csv", b'"x","y","z"\n0,0,0\n1,0,0\n0,1,0\n1,1,0.5\n')
    assert read_file(path).points.shape == (4, 3)
    mixed = b"v 0 0 0\rv 1 0 0\rv 0 1 0\r\nf 1 2 3\r\n"
    assert read_file(_write(tmp_path, "m.obj", mixed)).faces.tolist() == [[0, 1, 2]]


def test_header_with_units(tmp_path):
    """``x [m],y [m],z [m]`` was six header values over rows of three ("3 value(s) where line 1 has 6")."""
    path = _write(tmp_path, "u.csv", b"x [m],y [m],z (mm),intensity\n0,0,0,5\n1,0,0,6\n0,1,0,7\n1,1,0.5,8\n")
    cloud = read_file(path)
    assert cloud.points.shape == (4, 3) and cloud.normals is None
    with pytest.raises(InputFileError, match="line 2"):  # rows keep their line numbers
        read_file(_write(tmp_path, "v.csv", b"x [m],y [m],z [m]\n0,zero,0\n"))
