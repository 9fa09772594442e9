"""E57 laser-scan files: scans placed by their poses, scan choice, invalid points, damaged files, flatten.

The files are written at test time with pye57's writer (``write_scan_raw``, float32
coordinates, so the test points are float32 values and come back exactly); spherical and
empty scans with libE57Format's nodes through pye57's binding. The expected points are computed
here with numpy from an axis and angle, not from the quaternion the file stores. Bytes
are changed by hand for the header checks and, with each 1024-byte page's CRC-32C
recomputed, for points without coordinates and for the fuzz loop (libE57Format refuses a
page whose checksum fails before parsing it).
"""

from __future__ import annotations

import json
import struct
import uuid
import warnings

import platform
import sys

import numpy as np
import pytest

if (sys.platform, platform.machine()) in {("linux", "x86_64"), ("darwin", "arm64"), ("win32", "AMD64")}:
    import pye57  # a dependency here (pyproject's marker), not skipped: a green run would hide a missing install
else:  # no wheels: pye57 is not a dependency, and the reader says how to get it (tested below)
    pye57 = pytest.importorskip("pye57")

from parambench.bench.cli import main
from parambench.datasets_gen.errors import InputFileError
from parambench.datasets_gen.formats import RawMesh, read_file
from parambench.datasets_gen.formats import e57 as e57_module
from parambench.datasets_gen.io import load_surface
from parambench.datasets_gen.real import REAL_DATASETS

IDENTITY = (np.array([1.0, 0.0, 0.0, 0.0]), np.zeros(3))


def _pose(axis, angle: float, shift) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Quaternion (w, x, y, z), its rotation matrix (Rodrigues' formula) and the translation."""
    axis = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    rotation = np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k
    quaternion = np.r_[np.cos(angle / 2), np.sin(angle / 2) * axis]
    return quaternion, rotation, np.asarray(shift, dtype=float)


def _cloud(n: int, seed: int, scale: float = 3.0) -> np.ndarray:
    """``n`` points whose coordinates are float32 values (pye57 writes float32)."""
    return (np.random.default_rng(seed).normal(size=(n, 3)) * scale).astype(np.float32).astype(np.float64)


def _write(path, scans) -> None:
    """An E57 file of ``scans``: (points (N, 3), quaternion, translation[, invalid states]) each."""
    with pye57.E57(str(path), mode="w") as e57:
        for points, quaternion, translation, *state in scans:
            data = {"cartesianX": points[:, 0], "cartesianY": points[:, 1], "cartesianZ": points[:, 2]}
            if state:
                data["cartesianInvalidState"] = np.asarray(state[0], dtype=np.int8)
            e57.write_scan_raw(data, rotation=quaternion, translation=translation)


def _write_float64(path, names: list[str], scans: list[np.ndarray]) -> None:
    """An E57 file of scans (N, 3) stored as float64 fields ``names``, without poses, built
    from libE57Format's nodes (pye57's writer stores float32 cartesian coordinates only and
    no scan without points)."""
    from pye57 import libe57

    with pye57.E57(str(path), mode="w") as e57:
        imf = e57.image_file
        for values in scans:
            scan = libe57.StructureNode(imf)
            scan.set("guid", libe57.StringNode(imf, "{%s}" % uuid.uuid4()))
            prototype = libe57.StructureNode(imf)
            for k, name in enumerate(names):
                low, high = (float(values[:, k].min()), float(values[:, k].max())) if len(values) else (0.0, 0.0)
                prototype.set(name, libe57.FloatNode(imf, low, libe57.E57_DOUBLE, low, high))
            points = libe57.CompressedVectorNode(imf, prototype, libe57.VectorNode(imf, True))
            scan.set("points", points)
            e57.data3d.append(scan)
            if len(values):
                arrays, buffers = e57.make_buffers(names, len(values))
                for k, name in enumerate(names):
                    arrays[name][:] = values[:, k]
                writer = points.writer(buffers)
                writer.write(len(values))
                writer.close()


_CRC_TABLE = []
for _i in range(256):
    _c = _i
    for _ in range(8):
        _c = (_c >> 1) ^ (0x82F63B78 if _c & 1 else 0)
    _CRC_TABLE.append(_c)


def _crc32c(data: bytes) -> int:
    crc = 0xFFFFFFFF
    for byte in data:
        crc = _CRC_TABLE[(crc ^ byte) & 0xFF] ^ (crc >> 8)
    return crc ^ 0xFFFFFFFF


def _with_checksums(data: bytearray) -> bytes:
    """``data`` with every page's CRC-32C (its last 4 bytes, big-endian) made right again."""
    for start in range(0, len(data) - 1023, 1024):
        data[start + 1020:start + 1024] = _crc32c(bytes(data[start:start + 1020])).to_bytes(4, "big")
    return bytes(data)


@pytest.fixture
def one_scan(tmp_path):
    points = _cloud(200, 0)
    path = tmp_path / "scan.e57"
    _write(path, [(points, *IDENTITY)])
    return path, points


@pytest.fixture
def two_scans(tmp_path):
    """Two scans, the second turned 40 degrees about a tilted axis and moved."""
    a, b = _cloud(150, 1), _cloud(90, 2)
    q, rotation, shift = _pose([0.3, -0.5, 1.0], np.radians(40), [12.5, -7.0, 3.25])
    path = tmp_path / "project.e57"
    _write(path, [(a, *IDENTITY), (b, q, shift)])
    return path, a, b @ rotation.T + shift


def test_one_scan_comes_back_in_order(one_scan):
    path, points = one_scan
    assert path.read_bytes()[:8] == b"ASTM-E57"
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # one scan, every point valid: nothing to say
        raw = read_file(path)
    np.testing.assert_allclose(raw.points, points, rtol=1e-9, atol=0)
    assert raw.points.dtype == np.float64 and raw.faces is None and raw.normals is None


def test_scans_are_placed_by_their_poses_in_file_order(two_scans):
    path, a, b_placed = two_scans
    with pytest.warns(UserWarning, match=r"all 240 points of 2 scans are read, each placed by its pose "
                                         r"\(points per scan: 0: 150, 1: 90\); keep some with e57_scans "
                                         r"\(--e57-scans\), e.g. 0"):
        surface = load_surface(path)
    np.testing.assert_allclose(surface.points, np.vstack([a, b_placed]), rtol=0, atol=1e-12)
    assert surface.params["format"] == "e57" and "e57_scans" not in surface.params


def test_chosen_scans_keep_their_points_and_poses(two_scans):
    path, a, b_placed = two_scans
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # scans chosen: no warning about them
        second = load_surface(path, e57_scans=[1])
    np.testing.assert_allclose(second.points, b_placed, rtol=0, atol=1e-12)
    assert second.params["e57_scans"] == [1]
    both = load_surface(path, e57_scans=(1, 0, 1))  # file order, whatever the order given
    np.testing.assert_allclose(both.points, np.vstack([a, b_placed]), rtol=0, atol=1e-12)
    assert both.params["e57_scans"] == [0, 1]


@pytest.mark.parametrize("w, said", [
    ("9", None),
    ("0", r"the pose of scan 0 has rotation quaternion \[0.0, 0.0, 0.0, 0.0\], not a rotation"),
])
def test_a_quaternion_is_normalised_and_a_zero_one_refused(one_scan, w, said):
    """pye57 writes the identity as w = 1 (x, y, z left at their default 0): w = 9 is the
    identity once normalised, w = 0 no rotation at all."""
    path, points = one_scan
    data = bytearray(path.read_bytes())
    k = bytes(data).index(b'<w type="Float">1</w>')
    data[k + 16:k + 17] = w.encode()
    path.write_bytes(_with_checksums(data))
    if said is None:
        np.testing.assert_array_equal(read_file(path).points, points)
    else:
        with pytest.raises(InputFileError, match=said):
            read_file(path)


@pytest.mark.parametrize("scans, said", [
    ([2], r"no scan 2: the file holds 2 scan\(s\), numbered 0 to 1; choose scans the file holds"),
    ([0, 7], r"no scan 7: the file holds 2 scan\(s\)"),
    ([-1], r"no scan -1: scans are numbered from 0"),
])
def test_a_scan_the_file_does_not_hold_is_refused(two_scans, scans, said):
    path = two_scans[0]
    with pytest.raises(InputFileError, match=said):
        load_surface(path, e57_scans=scans)


def test_invalid_points_and_points_without_coordinates_are_left_out_with_a_count(tmp_path):
    """States 1 (direction only) and 2 (no return) are left out as flagged invalid; a point
    written valid whose coordinates are NaN (patched into the file) as a no-return."""
    points = _cloud(12, 3)
    sentinel = 1234.5625  # a float32 value found once per coordinate stream, then made NaN
    points[4] = sentinel
    state = np.zeros(12, dtype=np.int8)
    state[[1, 7]] = 2
    state[9] = 1
    path = tmp_path / "gaps.e57"
    _write(path, [(points, *IDENTITY, state)])
    data = bytearray(path.read_bytes())
    target = struct.pack("<f", sentinel)
    spots = [k for k in range(len(data) - 3) if data[k:k + 4] == target]
    assert len(spots) == 3
    for k in spots:
        data[k:k + 4] = struct.pack("<f", float("nan"))
    path.write_bytes(_with_checksums(data))
    with pytest.warns(UserWarning, match=r"gaps.e57: 4 of 12 points are flagged invalid or have no coordinates"):
        raw = read_file(path)
    keep = (state == 0) & (np.arange(12) != 4)
    np.testing.assert_array_equal(raw.points, points[keep])
    np.testing.assert_array_equal(raw.rows, np.flatnonzero(keep))  # so a .csv can keep every record's row
    assert raw.n_rows == 12


def test_records_left_out_keep_their_rows_in_a_csv(tmp_path, capsys):
    """A scan whose invalid records are left out: flatten's .csv keeps one row per record of
    the scan, nan,nan at the invalid ones, the others the map of the valid points alone."""
    ground = np.loadtxt(REAL_DATASETS["real/lidar-ground"].path(), skiprows=1)
    local = ground - ground.mean(axis=0)
    n = len(local) + 3
    invalid = np.array([0, 4000, n - 1])
    records = np.zeros((n, 3))
    live = np.setdiff1d(np.arange(n), invalid)
    records[live] = local
    state = np.zeros(n, dtype=np.int8)
    state[invalid] = 2
    path = tmp_path / "ground.e57"
    _write(path, [(records, *IDENTITY, state)])
    out = tmp_path / "uv.csv"
    assert main(["flatten", str(path), "-o", str(out)]) == 0
    assert "the .csv has one row per input row, the 3 dropped ones nan,nan" in capsys.readouterr().err
    uv = np.loadtxt(out, delimiter=",", skiprows=1)
    assert uv.shape == (n, 2) and np.isnan(uv[invalid]).all() and np.isfinite(uv[live]).all()


def test_a_point_with_one_nan_coordinate_is_a_damaged_file(tmp_path):
    points = _cloud(12, 4)
    points[5, 1] = 1234.5625
    path = tmp_path / "partial.e57"
    _write(path, [(points, *IDENTITY)])
    data = bytearray(path.read_bytes())
    k = bytes(data).index(struct.pack("<f", 1234.5625))
    data[k:k + 4] = struct.pack("<f", float("nan"))
    path.write_bytes(_with_checksums(data))
    with pytest.raises(InputFileError, match=r"point 5 of scan 0 has a non-finite coordinate"):
        read_file(path)


def test_no_valid_point_is_refused(tmp_path):
    points = _cloud(5, 5)
    points[0] = 1234.5625  # pye57 writes no scan without a valid point: this one is made NaN below
    path = tmp_path / "empty.e57"
    _write(path, [(points, *IDENTITY, [0, 2, 2, 2, 2])])
    data = bytearray(path.read_bytes())
    for k in [k for k in range(len(data) - 3) if data[k:k + 4] == struct.pack("<f", 1234.5625)]:
        data[k:k + 4] = struct.pack("<f", float("nan"))
    path.write_bytes(_with_checksums(data))
    with pytest.warns(UserWarning, match="5 of 5 points"), pytest.raises(InputFileError, match="no valid point"):
        read_file(path)


@pytest.mark.parametrize("count", [201, 900])
def test_a_scan_counting_more_points_than_it_holds_is_refused(one_scan, count):
    """pye57's read_scan returned uninitialised memory for the records its reader did not find."""
    path, _ = one_scan
    data = bytearray(path.read_bytes())
    k = bytes(data).index(b'recordCount="200"')
    data[k:k + 17] = f'recordCount="{count}"'.encode()
    path.write_bytes(_with_checksums(data))
    said = f"scan 0 holds 200 points where its header counts {count}: it is truncated"
    with pytest.raises(InputFileError, match=said):
        read_file(path)


def test_a_scan_without_points_is_read_as_none(tmp_path):
    """libE57Format refuses to read a scan of no records; the other scans are still read."""
    points = np.random.default_rng(7).normal(size=(30, 3))
    path = tmp_path / "some_empty.e57"
    _write_float64(path, ["cartesianX", "cartesianY", "cartesianZ"], [np.empty((0, 3)), points])
    with pytest.warns(UserWarning, match=r"all 30 points of 2 scans .*\(points per scan: 0: 0, 1: 30\).*e.g. 1"):
        raw = read_file(path)
    np.testing.assert_array_equal(raw.points, points)  # float64 in the file: exact
    with pytest.raises(InputFileError, match=r"no valid point in scan\(s\) 0"):
        read_file(path, e57_scans=[0])


def test_a_spherical_scan_is_converted(tmp_path):
    rng = np.random.default_rng(6)
    rae = np.column_stack([rng.uniform(1, 30, 50), rng.uniform(-np.pi, np.pi, 50), rng.uniform(-1.2, 1.2, 50)])
    path = tmp_path / "spherical.e57"
    _write_float64(path, ["sphericalRange", "sphericalAzimuth", "sphericalElevation"], [rae])
    r, azimuth, elevation = rae.T
    expected = np.column_stack([r * np.cos(elevation) * np.cos(azimuth), r * np.cos(elevation) * np.sin(azimuth),
                                r * np.sin(elevation)])
    np.testing.assert_allclose(read_file(path).points, expected, rtol=1e-12, atol=1e-12)


def _damaged(data: bytes, how: str) -> bytes:
    out = bytearray(data)
    if how == "signature":
        out[:8] = b"ASTM-E58"
    elif how == "major":
        struct.pack_into("<I", out, 8, 2)
    elif how == "truncated":
        del out[-1024:]
    elif how == "padded":
        out += b"\0" * 10
    elif how == "xml past the end":
        struct.pack_into("<Q", out, 24, len(data) + 4096)
    elif how == "xml longer than the file":
        struct.pack_into("<Q", out, 32, len(data))
    elif how == "page size":
        struct.pack_into("<Q", out, 40, 2048)
    elif how == "short":
        del out[30:]
    return bytes(out)


@pytest.mark.parametrize("how, said", [
    ("signature", r"not a readable E57 file \(no E57 header: it must start with 'ASTM-E57'.*export the points as XYZ"),
    ("short", r"not a readable E57 file \(no E57 header"),
    ("major", r"byte 8: not a readable E57 file \(version 2.0; 1.x is read\)"),
    ("truncated", r"its header gives its length as \d+ bytes but the file holds \d+: it is truncated; pass the whole"),
    ("padded", r"the file holds 10 bytes more than the \d+ its header gives: bytes were appended"),
    ("xml past the end", r"byte 24: its header places the XML section at byte \d+, \d+ bytes long, outside the file"),
    ("xml longer than the file", r"byte 24: its header places the XML section .* outside the file of \d+ bytes"),
    ("page size", r"byte 40: not a readable E57 file \(pages of 2048 bytes; the standard's are 1024\)"),
])
def test_a_damaged_header_is_refused_before_the_decoder_runs(one_scan, monkeypatch, how, said):
    path, _ = one_scan
    path.write_bytes(_damaged(path.read_bytes(), how))
    monkeypatch.setattr(e57_module, "decode_in_child", lambda *a, **k: pytest.fail("the decoder saw the file"))
    with pytest.raises(InputFileError, match=said):
        read_file(path)


def test_only_the_header_is_read_in_this_process(one_scan, monkeypatch):
    import parambench.datasets_gen.formats as formats

    path, points = one_scan
    monkeypatch.setattr(formats, "read_bytes", lambda p: pytest.fail("the whole file was read"))
    assert len(read_file(path).points) == len(points)


def test_a_damaged_page_is_refused_by_its_checksum(one_scan):
    path, _ = one_scan
    data = bytearray(path.read_bytes())
    data[300] ^= 0xFF  # in the binary section, its page's CRC left as it was
    path.write_bytes(bytes(data))
    with pytest.raises(InputFileError, match=r"scan.e57: not a readable E57 file \(its decoder failed: .*checksum"):
        read_file(path)


@pytest.mark.parametrize("child, said", [
    ("import os; os.abort()", "its decoder failed: exit status -6"),
    (e57_module._CHILD_CODE.replace("e57 = pye57.E57(sys.argv[1])", "e57 = bytearray(1 << 40)"),
     "its decoder failed: the decoder ran out of memory"),
])
def test_a_decoder_that_crashes_or_runs_out_of_memory_is_a_damaged_file(one_scan, monkeypatch, child, said):
    """What kills the child (libE57Format aborting, an allocation past its memory cap)
    leaves this process standing, with one line."""
    path, _ = one_scan
    assert child != e57_module._CHILD_CODE  # the replaced line is there
    monkeypatch.setattr(e57_module, "_CHILD_CODE", child)
    with pytest.raises(InputFileError, match=f"scan.e57: not a readable E57 file \\({said}"):
        read_file(path)


@pytest.mark.slow
def test_changed_bytes_give_points_or_one_error_never_a_crash(two_scans):
    """100 seeded mutations of a valid two-scan file, 1-8 bytes changed after the header
    (so the header passes), with the pages' checksums made right again for half of them
    so that libE57Format parses the changed XML and binary data."""
    path, _, _ = two_scans
    original = path.read_bytes()
    rng = np.random.default_rng(57)
    outcomes = {"read": 0, "refused": 0}
    for trial in range(100):
        data = bytearray(original)
        spots = rng.integers(48, len(data), size=rng.integers(1, 9))
        data_view = np.frombuffer(data, dtype=np.uint8)
        data_view[spots] ^= rng.integers(1, 256, size=len(spots)).astype(np.uint8)
        path.write_bytes(_with_checksums(data) if trial % 2 else bytes(data))
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                raw = read_file(path)
        except InputFileError as exc:
            assert "\n" not in str(exc) and str(path) in str(exc)
            outcomes["refused"] += 1
        else:
            assert isinstance(raw, RawMesh) and len(raw.points) and np.all(np.isfinite(raw.points))
            outcomes["read"] += 1
    assert outcomes["refused"] >= 50  # at least the mutations whose checksums fail


def test_scans_are_refused_for_other_formats_and_classes_for_e57(tmp_path, one_scan):
    xyz = tmp_path / "pts.xyz"
    xyz.write_text("0 0 0\n1 0 0\n0 1 0\n1 1 0.1\n")
    with pytest.raises(InputFileError, match=r"E57 scans select the scans of an .e57 file; this is a .xyz file"):
        load_surface(xyz, e57_scans=[0])
    with pytest.raises(InputFileError, match=r"LAS classes select points of a .las or .laz file .* this is a .e57"):
        load_surface(one_scan[0], las_classes=[2])


def test_flatten_maps_a_posed_scan_of_lidar_ground(tmp_path, capsys):
    """The shipped ground returns (``real/lidar-ground``), stored in a scanner's frame about
    their centre, turned and moved by a pose back to their survey coordinates: ``flatten``
    writes one uv row per point, and ``inspect --e57-scans 0`` reads them all."""
    ground = np.loadtxt(REAL_DATASETS["real/lidar-ground"].path(), skiprows=1)
    q, rotation, _ = _pose([0.2, 0.1, 1.0], np.radians(-65), [0, 0, 0])
    centre = np.round(ground.mean(axis=0))
    local = ((ground - centre) @ rotation).astype(np.float32).astype(np.float64)  # R^T (p - c), row-wise
    placed = local @ rotation.T + centre
    np.testing.assert_allclose(placed, ground, atol=1e-3)  # float32 in the scanner's frame: sub-mm
    src = tmp_path / "ground.e57"
    _write(src, [(local, q, centre)])
    surface = load_surface(src)
    np.testing.assert_allclose(surface.points, placed, rtol=0, atol=1e-8)
    out = tmp_path / "ground_uv.csv"
    assert main(["flatten", str(src), "-o", str(out)]) == 0
    assert "self-check ok" in capsys.readouterr().out
    rows = out.read_text().splitlines()
    assert rows[0] == "u,v" and len(rows) == 1 + len(ground)
    uv = np.array([r.split(",") for r in rows[1:]], dtype=float)
    assert np.all(np.isfinite(uv)) and len(np.unique(uv, axis=0)) == len(ground)
    report = tmp_path / "diagnostics.json"
    main(["inspect", str(src), "--e57-scans", "0", "-o", str(report)])
    assert json.loads(report.read_text())["n_points"] == len(ground)
    with pytest.raises(SystemExit) as exited:  # argparse's usage error
        main(["inspect", str(src), "--e57-scans", "0,x", "-o", str(report)])
    assert exited.value.code == 2 and "give scan indices as integers" in capsys.readouterr().err
    assert main(["inspect", str(src), "--e57-scans", "1", "-o", str(report)]) == 2
    assert "no scan 1: the file holds 1 scan(s)" in capsys.readouterr().err


def test_without_pye57_an_e57_file_says_how_to_read_it(one_scan, tmp_path, monkeypatch):
    """Where pye57 has no wheels it is not installed: the header is still checked, then one
    line says what is missing and what to do instead of a child's import error."""
    path, _ = one_scan
    monkeypatch.setattr(e57_module, "_pye57_installed", lambda: False)
    with pytest.raises(InputFileError, match="needs pye57, which is not installed.*export the points as LAS"):
        read_file(path)
    bad = tmp_path / "bad.e57"
    bad.write_bytes(b"NOT-E57!" + bytes(60))
    with pytest.raises(InputFileError, match="no E57 header"):
        read_file(bad)
