"""PCD point clouds: the three layouts, LZF, NaN returns, damaged files, and flatten on a PCD file.

Every file here is written byte by byte (struct / numpy, and a small LZF encoder of the
test's own), never by a PCD library, so the reader is checked against the format itself.
"""

from __future__ import annotations

import struct
import time
import warnings

import numpy as np
import pytest

from parambench.bench.cli import main
from parambench.datasets_gen.errors import InputFileError
from parambench.datasets_gen.formats import READERS, read_file
from parambench.datasets_gen.formats import _lzf
from parambench.datasets_gen.formats._lzf import LZFError, lzf_decompress
from parambench.datasets_gen.formats.pcd import read_pcd
from parambench.datasets_gen.io import load_surface
from parambench.datasets_gen.real import REAL_DATASETS

#: The fields of the test clouds: (name, TYPE, SIZE, COUNT), with colour, intensity, a
#: padding field, normals and curvature as PCL's PointXYZRGBNormal-like types write them.
FIELDS = [("x", "F", 4, 1), ("y", "F", 4, 1), ("z", "F", 4, 1), ("_", "U", 1, 4), ("rgb", "F", 4, 1),
          ("intensity", "U", 2, 1), ("normal_x", "F", 4, 1), ("normal_y", "F", 4, 1), ("normal_z", "F", 4, 1),
          ("curvature", "F", 8, 1)]


def lzf_encode(data: bytes) -> bytes:
    """A greedy LZF encoder (hash of 3 bytes, longest match up to 264, distance up to 8192)."""
    out, literal, table = bytearray(), bytearray(), {}
    n, i = len(data), 0

    def flush():
        for k in range(0, len(literal), 32):
            chunk = literal[k:k + 32]
            out.append(len(chunk) - 1)
            out.extend(chunk)
        literal.clear()

    while i < n:
        if i + 3 <= n:
            key = data[i:i + 3]
            ref = table.get(key)
            table[key] = i
            if ref is not None and i - ref - 1 < 8192:
                length, longest = 3, min(264, n - i)
                while length < longest and data[ref + length] == data[i + length]:
                    length += 1
                flush()
                off, code = i - ref - 1, length - 2
                if code < 7:
                    out.append((code << 5) | (off >> 8))
                else:
                    out += bytes([(7 << 5) | (off >> 8), code - 7])
                out.append(off & 0xFF)
                i += length
                continue
        literal.append(data[i])
        i += 1
    flush()
    return bytes(out)


def _cloud(n: int, seed: int = 0) -> np.ndarray:
    """A structured array of ``n`` points with every field of :data:`FIELDS`, packed (no alignment)."""
    rng = np.random.default_rng(seed)
    dtype = np.dtype([(name if name != "_" else "pad", f"<{'f' if t == 'F' else 'u'}{s}", (c,) if c > 1 else ())
                      for name, t, s, c in FIELDS])
    cloud = np.zeros(n, dtype)
    u, v = rng.random(n), rng.random(n)
    cloud["x"], cloud["y"], cloud["z"] = u * 3 - 1, v * 2 + 5, np.sin(u * 3) * np.cos(v * 2)
    normal = rng.normal(size=(n, 3))
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    cloud["normal_x"], cloud["normal_y"], cloud["normal_z"] = normal.T
    cloud["rgb"] = rng.integers(0, 1 << 24, n).astype(np.uint32).view(np.float32)  # PCL packs colour in a float
    cloud["intensity"] = rng.integers(0, 65536, n)
    cloud["curvature"] = rng.random(n)
    return cloud


def _xyz(cloud: np.ndarray) -> np.ndarray:
    return np.column_stack([cloud["x"], cloud["y"], cloud["z"]]).astype(np.float64)


def _normals(cloud: np.ndarray) -> np.ndarray:
    return np.column_stack([cloud["normal_x"], cloud["normal_y"], cloud["normal_z"]]).astype(np.float64)


def _header(kind: str, n: int, *, fields=FIELDS, width=None, height=1, points=None, extra: str = "") -> bytes:
    names = " ".join(f[0] for f in fields)
    return (f"# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS {names}\n"
            f"SIZE {' '.join(str(f[2]) for f in fields)}\nTYPE {' '.join(f[1] for f in fields)}\n"
            f"COUNT {' '.join(str(f[3]) for f in fields)}\nWIDTH {n if width is None else width}\nHEIGHT {height}\n"
            f"VIEWPOINT 0 0 0 1 0 0 0\n{extra}POINTS {n if points is None else points}\nDATA {kind}\n").encode()


def _columns(cloud: np.ndarray) -> bytes:
    """The structure-of-arrays bytes of the compressed layout: each field's values of all points in turn."""
    return b"".join(np.ascontiguousarray(cloud[name]).tobytes() for name in cloud.dtype.names)


def pcd_bytes(cloud: np.ndarray, kind: str, **header) -> bytes:
    n = len(cloud)
    if kind == "binary":
        return _header(kind, n, **header) + cloud.tobytes()
    if kind == "binary_compressed":
        raw = _columns(cloud)
        packed = lzf_encode(raw)
        return _header(kind, n, **header) + struct.pack("<II", len(packed), len(raw)) + packed
    columns = []
    for name in cloud.dtype.names:
        values = cloud[name].reshape(n, -1)
        as_text = (lambda v: repr(float(v))) if values.dtype.kind == "f" else (lambda v: str(int(v)))
        text = [as_text(v) for v in values.ravel()]
        columns.append(np.array(text, dtype=object).reshape(values.shape))
    rows = [" ".join(row) for row in np.concatenate(columns, axis=1).tolist()]
    return _header(kind, n, **header) + ("\n".join(rows) + "\n").encode()


def _write(tmp_path, name: str, data: bytes):
    path = tmp_path / name
    path.write_bytes(data)
    return path


# ---------------------------------------------------------------- LZF


def test_hand_written_lzf_stream_with_literals_and_back_references():
    stream = bytes([3]) + b"abcd"  # literal run of 4
    stream += bytes([(4 << 5) | 0, 0])  # 6 bytes from 1 back: overlaps what it writes, "dddddd"
    stream += bytes([(7 << 5) | 0, 3, 9])  # 7 + 3 + 2 = 12 bytes from 10 back, overlapping its last 2
    stream += bytes([1]) + b"xy"
    expected = b"abcddddddd" + b"abcddddddd" + b"ab" + b"xy"
    assert lzf_decompress(stream, len(expected)).tobytes() == expected
    far = bytes([31]) + bytes(range(32)) + bytes([31]) + bytes(range(100, 132)) + bytes([(7 << 5) | 0, 50, 63])
    decoded = lzf_decompress(far, 64 + 59).tobytes()  # a 59-byte reference to the start, 64 back
    assert decoded == bytes(range(32)) + bytes(range(100, 132)) + (bytes(range(32)) + bytes(range(100, 127)))


def test_back_reference_beyond_one_byte_of_distance():
    head = bytes(range(256)) * 2 + b"tail"
    stream = lzf_encode(head[:300]) + bytes([31]) + head[300:332]
    # copy 40 bytes from position 5: distance 332 - 5 - 1 = 326 = 0x146 (high bits in the control byte)
    stream += bytes([(7 << 5) | 0x01, 40 - 2 - 7, 0x46])
    assert lzf_decompress(stream, 372).tobytes() == head[:332] + head[5:45]


@pytest.mark.parametrize("seed", range(4))
def test_lzf_round_trip_of_random_and_point_data(seed):
    rng = np.random.default_rng(seed)
    samples = [rng.integers(0, 256, 5000, dtype=np.uint8).tobytes(),  # incompressible: literal runs only
               rng.integers(0, 4, 20000, dtype=np.uint8).tobytes(),  # short matches everywhere
               bytes(3000) + b"x" + bytes(3000),  # long runs: len == 7 extensions, overlapping copies
               _columns(_cloud(500, seed))]
    for raw in samples:
        packed = lzf_encode(raw)
        assert lzf_decompress(packed, len(raw)).tobytes() == raw
    assert len(lzf_encode(samples[2])) < 100  # the encoder really used back-references


@pytest.mark.parametrize("stream, size, problem", [
    (bytes([3]) + b"abc", 4, "ends inside a chunk"),  # literal run cut short
    (bytes([0]) + b"a" + bytes([(7 << 5)]), 20, "ends inside a chunk"),  # no length byte
    (bytes([0]) + b"a" + bytes([(1 << 5)]), 20, "ends inside a chunk"),  # no distance byte
    (bytes([0x20, 5]), 3, "before the start"),  # a reference with no output yet
    (bytes([1]) + b"ab" + bytes([0x20 | 0x1F, 0xFF]), 5, "before the start"),  # 8191 back from 2
    (bytes([3]) + b"abcd" + bytes([0x80, 0]), 8, "more bytes than announced"),
    (bytes([3]) + b"abcd", 3, "more bytes than announced"),
    (bytes([3]) + b"abcd" + bytes([0x80, 0]), 12, "decodes to 10 bytes, not the 12 announced"),
    (b"", 4, "decodes to 0 bytes"),
])
def test_malformed_lzf_streams_are_errors(stream, size, problem):
    with pytest.raises(LZFError, match=problem):
        lzf_decompress(stream, size)


# ---------------------------------------------------------------- layouts


@pytest.mark.parametrize("kind", ["ascii", "binary", "binary_compressed"])
def test_the_three_layouts_read_the_same_points_and_normals(tmp_path, kind):
    cloud = _cloud(300)
    path = _write(tmp_path, f"{kind}.pcd", pcd_bytes(cloud, kind))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        raw = read_file(path)
    assert raw.points.dtype == np.float64 and raw.faces is None
    np.testing.assert_array_equal(raw.points, _xyz(cloud))
    np.testing.assert_array_equal(raw.normals, _normals(cloud))


def test_layouts_agree_with_integer_and_double_coordinates(tmp_path):
    fields = [("intensity", "U", 1, 1), ("x", "I", 4, 1), ("y", "I", 2, 1), ("z", "F", 8, 1), ("label", "U", 4, 3)]
    rng = np.random.default_rng(3)
    dtype = np.dtype([("intensity", "<u1"), ("x", "<i4"), ("y", "<i2"), ("z", "<f8"), ("label", "<u4", (3,))])
    cloud = np.zeros(50, dtype)
    cloud["x"] = rng.integers(-100000, 100000, 50)
    cloud["y"] = rng.integers(-30000, 30000, 50)
    cloud["z"] = rng.normal(size=50) * 1e6
    cloud["label"] = rng.integers(0, 1 << 32, (50, 3))
    expected = np.column_stack([cloud["x"], cloud["y"], cloud["z"]]).astype(np.float64)
    for kind in ("ascii", "binary", "binary_compressed"):
        raw = read_pcd(tmp_path / kind, pcd_bytes(cloud, kind, fields=fields))
        np.testing.assert_array_equal(raw.points, expected)
        assert raw.normals is None  # no normal fields


def test_normals_need_all_three_fields(tmp_path):
    fields = [("x", "F", 4, 1), ("y", "F", 4, 1), ("z", "F", 4, 1), ("normal_x", "F", 4, 1), ("normal_y", "F", 4, 1)]
    cloud = np.zeros(4, [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("normal_x", "<f4"), ("normal_y", "<f4")])
    cloud["x"] = [0, 1, 0, 1]
    cloud["y"] = [0, 0, 1, 1]
    raw = read_pcd(tmp_path / "a.pcd", pcd_bytes(cloud, "binary", fields=fields))
    assert raw.normals is None and raw.points.shape == (4, 3)


def test_pcd_is_a_supported_extension(tmp_path):
    assert READERS[".pcd"] is read_pcd
    cloud = _cloud(200)
    surface = load_surface(_write(tmp_path, "scan.PCD", pcd_bytes(cloud, "binary_compressed")))
    assert surface.params["format"] == "pcd" and surface.n_points == 200
    np.testing.assert_allclose(np.linalg.norm(surface.normals, axis=1), 1.0, atol=1e-6)


def test_old_headers_without_size_and_type(tmp_path):
    """A v0.5 header: COLUMNS instead of FIELDS, no SIZE / TYPE (4-byte floats), no WIDTH / HEIGHT."""
    pts = np.array([[0, 0, 0], [1, 0, 0.5], [0, 1, 0.25]], dtype=np.float32)
    data = b"VERSION .5\nCOLUMNS x y z\nPOINTS 3\nDATA binary\n" + pts.tobytes()
    np.testing.assert_array_equal(read_pcd(tmp_path / "old.pcd", data).points, pts.astype(np.float64))
    ascii_ = b"# old\r\nVERSION .6\r\nFIELDS x y z\r\nWIDTH 3\r\nDATA ascii\r\n0 0 0\r\n1 0 0.5\r\n0 1 0.25\r\n"
    np.testing.assert_array_equal(read_pcd(tmp_path / "old.pcd", ascii_).points, pts.astype(np.float64))
    with pytest.raises(InputFileError, match="no SIZE line"):
        read_pcd(tmp_path / "new.pcd", b"VERSION .7\nFIELDS x y z\nPOINTS 3\nDATA binary\n" + pts.tobytes())


# ---------------------------------------------------------------- NaN returns


def _organized(kind: str):
    """A 4 x 3 organized cloud whose points 1, 2, 7 have no return (x, y, z NaN)."""
    cloud = _cloud(12, seed=5)
    holes = [1, 2, 7]
    for name in ("x", "y", "z", "normal_x", "normal_y", "normal_z"):
        cloud[name][holes] = np.nan
    return cloud, pcd_bytes(cloud, kind, width=4, height=3), holes


@pytest.mark.parametrize("kind", ["ascii", "binary", "binary_compressed"])
def test_organized_cloud_drops_points_without_a_return(tmp_path, kind):
    cloud, data, holes = _organized(kind)
    keep = np.setdiff1d(np.arange(12), holes)
    with pytest.warns(UserWarning, match=r"cam.pcd: 3 of 12 points have x, y, z all NaN .* are dropped") as caught:
        raw = read_pcd(tmp_path / "cam.pcd", data)
    assert len(caught) == 1
    np.testing.assert_array_equal(raw.points, _xyz(cloud)[keep])
    np.testing.assert_array_equal(raw.normals, _normals(cloud)[keep])


def test_nan_normals_of_kept_points_are_left_to_the_loader(tmp_path):
    """As for PLY and XYZ: the reader returns the normals as stored; load_surface drops them with a warning."""
    cloud = _cloud(40, seed=2)
    cloud["normal_x"][3] = np.nan
    path = _write(tmp_path, "n.pcd", pcd_bytes(cloud, "binary"))
    assert np.isnan(read_file(path).normals[3, 0])
    with pytest.warns(UserWarning, match="normals are non-finite or zero"):
        assert load_surface(path).normals is None


@pytest.mark.parametrize("kind, where", [("ascii", "line 17"), ("binary", r"byte \d+"), ("binary_compressed", "")])
def test_a_point_with_some_coordinates_nan_is_refused(tmp_path, kind, where):
    cloud = _cloud(12, seed=5)
    cloud["y"][5] = np.nan
    data = pcd_bytes(cloud, kind)
    with pytest.raises(InputFileError, match=f"p.pcd: {where}.*point 5 has coordinates .*nan.*NaN or infinite"):
        read_pcd(tmp_path / "p.pcd", data)
    if kind == "binary":
        offset = data.index(b"DATA binary\n") + len(b"DATA binary\n") + 5 * cloud.itemsize
        with pytest.raises(InputFileError, match=f"byte {offset}:"):
            read_pcd(tmp_path / "p.pcd", data)
    cloud["y"][5], cloud["z"][9] = 1.0, np.inf
    with pytest.raises(InputFileError, match="point 9 has coordinates .*inf"):
        read_pcd(tmp_path / "p.pcd", pcd_bytes(cloud, kind))


def test_a_cloud_of_no_returns_is_refused(tmp_path):
    cloud = _cloud(6)
    cloud["x"] = cloud["y"] = cloud["z"] = np.nan
    with pytest.raises(InputFileError, match="all 6 points have x, y, z NaN"):
        read_pcd(tmp_path / "e.pcd", pcd_bytes(cloud, "binary_compressed"))


# ---------------------------------------------------------------- damaged headers and payloads


def _binary_file(n=10):
    return pcd_bytes(_cloud(n), "binary")


@pytest.mark.parametrize("change, message", [
    (lambda d: d.replace(b"DATA binary\n", b"DATA zipped\n"), "unknown DATA kind 'zipped'"),
    (lambda d: d.split(b"DATA")[0], "no DATA line ends the header"),
    (lambda d: b"ply\nformat ascii 1.0\n" + d, "line 1: unexpected header line 'ply'"),
    (lambda d: d.replace(b"FIELDS x ", b"FIELDS xx "), "no field 'x'"),
    (lambda d: d.replace(b"FIELDS x y z _ rgb", b"FIELDS x y z _ X"), "two fields named 'x'"),
    (lambda d: d.replace(b"COUNT 1 1 1", b"COUNT 3 1 1"), "no field 'x' of COUNT 1"),
    (lambda d: d.replace(b"SIZE 4 4 4 1", b"SIZE 4 4 4"), "line 4: SIZE gives 9 value.s. for 10 field"),
    (lambda d: d.replace(b"TYPE F F F", b"TYPE F F"), "TYPE gives 9 value"),
    (lambda d: d.replace(b"COUNT 1 1 1 4", b"COUNT 1 1 1 4 1"), "COUNT gives 11 value"),
    (lambda d: d.replace(b"SIZE 4 4 4", b"SIZE 4 4 2"), "field 'z' has TYPE 'F' with SIZE '2'"),
    (lambda d: d.replace(b"SIZE 4 4 4 1", b"SIZE 4 4 4 3"), "field '_' has TYPE 'U' with SIZE '3'"),
    (lambda d: d.replace(b"TYPE F F F", b"TYPE F F Q"), "field 'z' has TYPE 'Q'"),
    (lambda d: d.replace(b"COUNT 1 1 1 4", b"COUNT 1 1 1 0"), "field '_' has COUNT '0'"),
    (lambda d: d.replace(b"WIDTH 10", b"WIDTH 10.0"), "WIDTH '10.0' is not a whole number"),
    (lambda d: d.replace(b"HEIGHT 1", b"HEIGHT -1"), "HEIGHT '-1' is not a whole number"),
    (lambda d: d.replace(b"POINTS 10", b"POINTS ten"), "POINTS 'ten' is not a whole number"),
    (lambda d: d.replace(b"POINTS 10", b"POINTS " + b"9" * 5000), "POINTS '9999.*' is not a whole number"),
    (lambda d: d.replace(b"COUNT 1 1 1 4", b"COUNT 1 1 1 " + b"4" * 5000), "field '_' has COUNT '444"),
    (lambda d: d.replace(b"SIZE 4 4 4 1", b"SIZE 4 4 4 " + b"1" * 5000), "field '_' has TYPE 'U' with SIZE '111"),
    (lambda d: d.replace(b"POINTS 10", b"POINTS 11"), r"POINTS 11 is not WIDTH \* HEIGHT \(10 \* 1 = 10\)"),
    (lambda d: d.replace(b"POINTS 10", b"POINTS 10\nPOINTS 10"), "a second POINTS line"),
    (lambda d: d.replace(b"WIDTH 10", b"WIDTH 0").replace(b"POINTS 10", b"POINTS 0"), "holds no points"),
    (lambda d: d[:-1], r"byte 261: the header announces 10 points of 42 bytes \(420 bytes\) but 419 bytes "
                       r"follow \(fewer\)"),
    (lambda d: d[:-42], "but 378 bytes follow"),
    (lambda d: d + b"\n", r"but 421 bytes follow \(more\)"),
])
def test_damaged_headers_and_binary_payloads_are_refused(tmp_path, change, message):
    data = _binary_file()
    with pytest.raises(InputFileError, match=message):
        read_pcd(tmp_path / "bad.pcd", change(data))


@pytest.mark.parametrize("change, message", [
    (lambda d: d[:-1], "announces .* bytes but .* follow"),
    (lambda d: d + b"\7", "announces .* bytes but .* follow"),
    (lambda d: d.replace(b"POINTS 40", b"POINTS 39").replace(b"WIDTH 40", b"WIDTH 39"),
     "decompresses to 1680 bytes, but the header's 39 points of 42 bytes take 1638"),
    (lambda d: d[:d.index(b"binary_compressed\n") + 22], "too few for the compressed block's two sizes"),
])
def test_inconsistent_compressed_sizes_are_refused(tmp_path, change, message):
    data = pcd_bytes(_cloud(40), "binary_compressed")
    with pytest.raises(InputFileError, match=message):
        read_pcd(tmp_path / "bad.pcd", change(data))


@pytest.mark.parametrize("kind", ["binary", "binary_compressed"])
def test_zero_padding_after_the_data_is_read_as_pcl_does(tmp_path, kind):
    """PCL-written files (pypcd4's test data) can end in zeros past their data: read by
    the header; anything else there is refused."""
    cloud = _cloud(30)
    data = pcd_bytes(cloud, kind)
    np.testing.assert_array_equal(read_pcd(tmp_path / "z.pcd", data + bytes(3918)).points, _xyz(cloud))
    with pytest.raises(InputFileError, match="follow"):
        read_pcd(tmp_path / "z.pcd", data + bytes(100) + b"\1")


def _split_compressed(data: bytes):
    start = data.index(b"DATA binary_compressed\n") + len(b"DATA binary_compressed\n")
    packed, unpacked = struct.unpack_from("<II", data, start)
    return data[:start], unpacked, data[start + 8:]


def _with_stream(head: bytes, unpacked: int, stream: bytes) -> bytes:
    return head + struct.pack("<II", len(stream), unpacked) + stream


@pytest.mark.parametrize("corrupt, problem", [
    (lambda s: s[:-1], "ends inside a chunk|decodes to"),  # cut short (its size adjusted to match)
    (lambda s: s[:len(s) // 2], "ends inside a chunk|decodes to"),
    (lambda s: bytes([0x20 | 0x1F, 0xFF]) + s[2:], "before the start"),  # first chunk a far reference
    (lambda s: s + bytes([0]) + b"!", "more bytes than announced"),  # one literal too many
    (lambda s: bytes([0]) + s[1:], "ends inside a chunk|more bytes|before the start|decodes to"),  # chunks misaligned
])
def test_corrupt_lzf_streams_in_a_file_are_refused(tmp_path, corrupt, problem):
    head, unpacked, stream = _split_compressed(pcd_bytes(_cloud(60, seed=1), "binary_compressed"))
    with pytest.raises(InputFileError, match=f"z.pcd: byte \\d+: a malformed compressed stream \\(.*({problem})"):
        read_pcd(tmp_path / "z.pcd", _with_stream(head, unpacked, corrupt(stream)))


def test_a_decompression_bomb_is_refused_before_allocating(tmp_path, monkeypatch):
    """A 200-byte file announcing 4 GB of points: refused from its sizes, nothing decoded."""
    n = 357_913_941  # 12-byte records: 4,294,967,292 bytes
    fields = FIELDS[:3]
    stream = bytes([(7 << 5), 255, 0]) * 4
    data = _header("binary_compressed", n, fields=fields) + struct.pack("<II", len(stream), n * 12) + stream
    monkeypatch.setattr(_lzf, "lzf_decompress", lambda *a: pytest.fail("the stream was decoded"))
    began = time.perf_counter()
    with pytest.raises(InputFileError, match="12 compressed bytes cannot hold 4294967292"):
        read_pcd(tmp_path / "bomb.pcd", data)
    assert time.perf_counter() - began < 1.0
    big = _header("binary_compressed", 1 << 40, fields=fields) + struct.pack("<II", len(stream), 1000) + stream
    with pytest.raises(InputFileError, match="decompresses to 1000 bytes"):
        read_pcd(tmp_path / "bomb.pcd", big)


@pytest.mark.parametrize("rows, message", [
    (b"0 0 0\n1 0\n0 1 0\n", "line 13: 2 value.s. where the header's fields take 3"),
    (b"0 0 0\n1 0 0\n0 1 zero\n", "line 14: value 'zero' is not a number"),
    (b"0 0 0\n1 0 0\n", "counts 3 points but 2 rows follow"),
    (b"0 0 0\n1 0 0\n0 1 0\n1 1 1\n", "counts 3 points but 4 rows follow"),
])
def test_bad_ascii_rows_are_refused_with_their_line(tmp_path, rows, message):
    data = _header("ascii", 3, fields=FIELDS[:3]) + rows
    with pytest.raises(InputFileError, match=message):
        read_pcd(tmp_path / "a.pcd", data)


def test_fuzzed_files_read_or_raise_input_file_error(tmp_path):
    """Byte changes, cuts and appended junk in binary and compressed files: a RawMesh of
    finite points or an InputFileError, nothing else (no other exception, no crash)."""
    rng = np.random.default_rng(12)
    sources = [pcd_bytes(_cloud(80, seed=4), "binary"), pcd_bytes(_cloud(80, seed=4), "binary_compressed")]
    outcomes = {"read": 0, "refused": 0}
    for trial in range(200):
        data = bytearray(sources[trial % 2])
        action = rng.integers(0, 4)
        if action == 0:
            for _ in range(rng.integers(1, 8)):
                data[rng.integers(0, len(data))] = rng.integers(0, 256)
        elif action == 1:
            del data[rng.integers(0, len(data)):]
        elif action == 2:
            start = data.index(b"DATA")
            pos = rng.integers(start + 12, len(data))
            data[pos:pos + 4] = rng.integers(0, 256, 4, dtype=np.uint8).tobytes()
        else:
            data += rng.integers(0, 256, rng.integers(1, 50), dtype=np.uint8).tobytes()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                raw = read_pcd(tmp_path / "f.pcd", bytes(data))
            except InputFileError:
                outcomes["refused"] += 1
                continue
        assert raw.points.ndim == 2 and raw.points.shape[1] == 3 and len(raw.points)
        assert np.isfinite(raw.points).all()
        outcomes["read"] += 1
    assert outcomes["read"] > 10 and outcomes["refused"] > 50, outcomes


# ---------------------------------------------------------------- end to end


def test_flatten_maps_a_compressed_pcd_of_lidar_ground(tmp_path, capsys):
    """The shipped ground returns (``real/lidar-ground``) as an organized-looking
    binary_compressed PCD with rows of no return between them: ``flatten`` drops those
    with a warning and maps every other point; the .csv keeps one row per file row (the
    organized cloud's pixels), nan,nan where there was no return."""
    ground = np.loadtxt(REAL_DATASETS["real/lidar-ground"].path(), skiprows=1)
    origin = np.floor(ground.min(axis=0))
    local = ground - origin  # float32 keeps centimetres near the origin, as PCL clouds are stored
    n_holes = 192
    n = len(local) + n_holes
    cloud = np.zeros(n, [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("intensity", "<f4")])
    holes = np.sort(np.random.default_rng(1).choice(n, n_holes, replace=False))
    kept = np.setdiff1d(np.arange(n), holes)
    for k, name in enumerate("xyz"):
        cloud[name][holes] = np.nan
        cloud[name][kept] = local[:, k]
    cloud["intensity"] = 7.0
    fields = [("x", "F", 4, 1), ("y", "F", 4, 1), ("z", "F", 4, 1), ("intensity", "F", 4, 1)]
    src = _write(tmp_path, "ground.pcd", pcd_bytes(cloud, "binary_compressed", fields=fields, width=n))
    out = tmp_path / "uv.csv"
    assert main(["flatten", str(src), "-o", str(out)]) == 0
    said = capsys.readouterr()
    assert "self-check ok" in said.out
    assert f"warning: UserWarning: {src}: {n_holes} of {n} points have x, y, z all NaN" in said.err
    assert f"the .csv has one row per input row, the {n_holes} dropped ones nan,nan" in said.err
    uv = np.loadtxt(out, delimiter=",", skiprows=1)
    assert uv.shape == (n, 2)
    assert np.isnan(uv[holes]).all() and np.isfinite(uv[kept]).all()
    assert len(np.unique(np.round(uv[kept], 9), axis=0)) == len(ground)  # one distinct uv per kept point
    # The rows line up with the file's points: the same map as the cloud without the empty rows.
    bare = _write(tmp_path, "bare.pcd", pcd_bytes(cloud[kept], "binary", fields=fields, width=len(kept)))
    assert main(["flatten", str(bare), "-o", str(tmp_path / "bare.csv")]) == 0
    np.testing.assert_allclose(uv[kept], np.loadtxt(tmp_path / "bare.csv", delimiter=",", skiprows=1), atol=1e-9)


def test_rows_without_a_return_and_repaired_rows_both_keep_their_file_rows(tmp_path, capsys):
    """Rows of no return (dropped by the reader) and a junk return (dropped by ``--repair``)
    in one file: the .csv still has one row per file row, nan,nan at both kinds, and
    ``inspect`` names loop points by their file rows."""
    import json

    from parambench.datasets_gen.registry import make_surface

    surface = make_surface("holes", 2000, sampling="jittered", seed=0)
    n = len(surface.points) + 4
    empty, junk = np.array([0, 501, 1502]), n - 1
    live = np.setdiff1d(np.arange(n), np.r_[empty, junk])
    cloud = np.full(n, np.nan, [("x", "<f8"), ("y", "<f8"), ("z", "<f8")])
    for k, name in enumerate("xyz"):
        cloud[name][live] = surface.points[:, k]
        cloud[name][junk] = 40.0  # far from all others
    fields = [("x", "F", 8, 1), ("y", "F", 8, 1), ("z", "F", 8, 1)]
    src = _write(tmp_path, "scan.pcd", pcd_bytes(cloud, "binary", fields=fields, width=n))
    out = tmp_path / "uv.csv"
    assert main(["flatten", str(src), "--repair", "-o", str(out)]) == 0
    assert "the .csv has one row per input row, the 4 dropped ones nan,nan" in capsys.readouterr().err
    uv = np.loadtxt(out, delimiter=",", skiprows=1)
    assert uv.shape == (n, 2) and np.isnan(uv[np.r_[empty, junk]]).all() and np.isfinite(uv[live]).all()
    report_path = tmp_path / "front.json"
    assert main(["inspect", str(src), "--repair", "-o", str(report_path)]) in (0, 3)
    report = json.loads(report_path.read_text())
    assert report["input_rows"] == live.tolist()
    found = np.concatenate([np.asarray(loop) for loop in report["boundary_loops"]])
    on_boundary = np.zeros(n, dtype=bool)
    on_boundary[live] = surface.boundary_mask
    assert on_boundary[found].mean() > 0.9  # loop points are the file's boundary rows
