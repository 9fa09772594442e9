"""LAS / LAZ LiDAR files: points, classes, damaged files, and flatten on a LiDAR tile.

The LAS files of the first tests are written byte by byte here (LAS 1.2, point format 0),
not by laspy, so the reader (which parses with laspy) is checked against the format
itself: scaled and offset integer coordinates, classification codes, the header's count.
"""

from __future__ import annotations

import json
import struct
import warnings

import numpy as np
import pytest

from parambench.bench.cli import main
from parambench.datasets_gen.errors import InputFileError
from parambench.datasets_gen.formats import las as las_module
from parambench.datasets_gen.formats.las import read_las
from parambench.datasets_gen.io import load_surface
from parambench.datasets_gen.real import REAL_DATASETS

SCALE = (0.01, 0.01, 0.001)
OFFSET = (2_400_000.0, 500_000.0, 1000.0)  # survey coordinates, as LiDAR tiles have


def _las_bytes(ints: np.ndarray, classes: np.ndarray, n_header: int | None = None, withheld=None) -> bytes:
    """A LAS 1.2 file, point format 0, of integer coordinates ``ints`` (N, 3) and ``classes``
    (``withheld``: (N,) bool, the classification byte's bit 7)."""
    n = len(ints)
    real = ints * np.array(SCALE) + np.array(OFFSET)
    header = struct.pack(
        "<4sHH I HH 8s BB 32s 32s HH H I I B H I 5I 3d 3d 6d",
        b"LASF", 0, 0, 0, 0, 0, b"\0" * 8, 1, 2, b"parambench test".ljust(32, b"\0"),
        b"struct.pack".ljust(32, b"\0"), 1, 2026, 227, 227, 0, 0, 20, n if n_header is None else n_header,
        n, 0, 0, 0, 0, *SCALE, *OFFSET,
        real[:, 0].max(), real[:, 0].min(), real[:, 1].max(), real[:, 1].min(), real[:, 2].max(), real[:, 2].min())
    assert len(header) == 227
    flags = np.zeros(n, dtype=bool) if withheld is None else np.asarray(withheld, dtype=bool)
    records = b"".join(struct.pack("<3iHBBbBH", *map(int, p), 100, 0b00001001, int(c) | (0x80 if w else 0), 0, 0, 1)
                       for p, c, w in zip(ints, classes, flags))
    return header + records


@pytest.fixture
def grid():
    """A 12 x 10 lattice of returns on a gentle slope, ground (2) with a block of buildings (6)."""
    i, j = np.meshgrid(np.arange(12), np.arange(10), indexing="ij")
    ints = np.column_stack([i.ravel() * 150, j.ravel() * 150, (i.ravel() * 7 + j.ravel() * 3) * 10]).astype(np.int64)
    classes = np.full(len(ints), 2)
    classes[(i.ravel() > 7) & (j.ravel() > 6)] = 6
    return ints, classes


def test_points_are_the_scaled_coordinates_in_file_order(tmp_path, grid):
    ints, classes = grid
    path = tmp_path / "tile.las"
    path.write_bytes(_las_bytes(ints, classes))
    expected = ints * np.array(SCALE) + np.array(OFFSET)
    with pytest.warns(UserWarning, match=r"of 2 classification classes \(2 ground: 108, 6 building: 12\)"):
        raw = read_las(path, path.read_bytes())
    np.testing.assert_allclose(raw.points, expected, rtol=0, atol=1e-9)
    assert raw.faces is None and raw.normals is None


def test_classes_keep_their_points_in_file_order(tmp_path, grid):
    ints, classes = grid
    path = tmp_path / "tile.las"
    path.write_bytes(_las_bytes(ints, classes))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a filter given: no warning about the classes
        surface = load_surface(path, las_classes=[2])
    expected = (ints * np.array(SCALE) + np.array(OFFSET))[classes == 2]
    np.testing.assert_allclose(surface.points, expected, rtol=0, atol=1e-9)
    assert surface.params["las_classes"] == [2] and surface.params["format"] == "las"
    both = load_surface(path, las_classes=(6, 2, 2))
    assert both.n_points == len(ints) and both.params["las_classes"] == [2, 6]
    with pytest.raises(InputFileError, match=r"no point of class 9; the file holds 2 ground: 108, 6 building: 12"):
        load_surface(path, las_classes=[9])


def test_only_the_header_is_read_in_this_process(tmp_path, grid, monkeypatch):
    """The child decodes the file; here its first bytes and its size are enough."""
    import parambench.datasets_gen.formats as formats

    ints, classes = grid
    path = tmp_path / "tile.las"
    path.write_bytes(_las_bytes(ints, classes))
    monkeypatch.setattr(formats, "read_bytes", lambda p: pytest.fail("the whole file was read"))
    assert load_surface(path, las_classes=[6]).n_points == int((classes == 6).sum())


def test_a_file_cut_at_a_record_boundary_is_refused(tmp_path, grid):
    """laspy itself returns the 100 points present and says nothing."""
    ints, classes = grid
    path = tmp_path / "cut.las"
    path.write_bytes(_las_bytes(ints, classes)[: 227 + 100 * 20])
    with pytest.raises(InputFileError, match="the header counts 120 points but the file holds 100: it is truncated"):
        load_surface(path)
    mid_record = tmp_path / "mid.las"
    mid_record.write_bytes(_las_bytes(ints, classes)[: 227 + 100 * 20 + 7])
    with pytest.raises(InputFileError, match="mid.las"):
        load_surface(mid_record)


@pytest.mark.parametrize("payload", [b"not a point cloud at all\n" * 20, b"LASF" + b"\0" * 300, b"LASF"])
def test_other_contents_are_refused_with_one_line(tmp_path, payload):
    path = tmp_path / "scan.laz"
    path.write_bytes(payload)
    with pytest.raises(InputFileError, match=r"scan.laz: not a readable LAS/LAZ file .*export the points as XYZ text"):
        load_surface(path)


def test_laz_holds_the_same_points_as_las(tmp_path, grid):
    laspy = pytest.importorskip("laspy")
    ints, classes = grid
    las_path = tmp_path / "tile.las"
    las_path.write_bytes(_las_bytes(ints, classes))
    las = laspy.read(las_path)
    laz_path = tmp_path / "tile.laz"
    las.write(laz_path)  # compressed by the suffix (lazrs)
    assert laz_path.stat().st_size < las_path.stat().st_size
    np.testing.assert_array_equal(load_surface(laz_path, las_classes=[2]).points,
                                  load_surface(las_path, las_classes=[2]).points)
    damaged = tmp_path / "damaged.laz"
    damaged.write_bytes(laz_path.read_bytes()[:-40])
    with pytest.raises(InputFileError, match="damaged.laz: not a readable LAS/LAZ file"):
        load_surface(damaged)


@pytest.mark.parametrize("child, said", [
    ("import os; os.abort()", "its decoder failed: exit status -6"),  # lazrs aborts on a failed allocation
    ("import sys; sys.stderr.write('memory allocation of 3238002705 bytes failed\\nstack backtrace:\\n'); sys.exit(134)",
     "its decoder failed: memory allocation of 3238002705 bytes failed"),
    (las_module._CHILD_CODE.replace("las = laspy.read(sys.argv[1])", "las = bytearray(1 << 40)"),
     "its decoder failed: the decoder ran out of memory"),
])
def test_a_decoder_that_crashes_or_runs_out_of_memory_is_a_damaged_file(tmp_path, grid, monkeypatch, child, said):
    """The decoder runs in a child process: what kills it (a Rust abort, a runaway
    allocation under the child's memory cap) leaves this process standing, with one line."""
    ints, classes = grid
    path = tmp_path / "tile.las"
    path.write_bytes(_las_bytes(ints, classes))
    monkeypatch.setattr(las_module, "_CHILD_CODE", child)
    with pytest.raises(InputFileError, match=f"tile.las: not a readable LAS/LAZ file \\({said}"):
        load_surface(path)


def test_a_compressed_header_announcing_too_many_points_is_refused(tmp_path, grid):
    ints, classes = grid
    data = bytearray(_las_bytes(ints, classes))
    data[104] |= 0x80  # the LAZ flag
    struct.pack_into("<I", data, 107, 4_000_000_000)
    path = tmp_path / "big.laz"
    path.write_bytes(bytes(data))
    with pytest.raises(InputFileError, match="counts 4000000000 points, more than a compressed file of 2627 bytes"):
        load_surface(path)


def test_classes_are_refused_for_other_formats(tmp_path):
    path = tmp_path / "pts.xyz"
    path.write_text("0 0 0\n1 0 0\n0 1 0\n1 1 0.1\n")
    with pytest.raises(InputFileError, match=r"LAS classes select points of a .las or .laz file .* this is a .xyz file"):
        load_surface(path, las_classes=[2])


def test_flatten_maps_the_ground_of_a_lidar_tile(tmp_path, capsys):
    """The shipped ground returns (laspy's test tile), written back as a LAS tile with
    vegetation returns above them: ``--las-classes 2`` maps the ground alone, every
    ground return a vertex of the output with its own coordinates."""
    laspy = pytest.importorskip("laspy")
    ground = np.loadtxt(REAL_DATASETS["real/lidar-ground"].path(), skiprows=1)
    rng = np.random.default_rng(0)
    canopy = ground[rng.choice(len(ground), 600, replace=False)] + [0.0, 0.0, 25.0]
    header = laspy.LasHeader(point_format=3, version="1.2")
    header.scales = np.array([0.01, 0.01, 0.01])
    header.offsets = np.floor(ground.min(axis=0))
    las = laspy.LasData(header)
    pts = np.vstack([canopy[:300], ground, canopy[300:]])
    las.x, las.y, las.z = pts[:, 0], pts[:, 1], pts[:, 2]
    las.classification = np.r_[np.full(300, 5), np.full(len(ground), 2), np.full(300, 5)].astype(np.uint8)
    src = tmp_path / "tile.laz"
    las.write(src)
    out = tmp_path / "ground.obj"
    assert main(["flatten", str(src), "--las-classes", "2", "-o", str(out)]) == 0
    assert "self-check ok" in capsys.readouterr().out
    v = np.array([line.split()[1:4] for line in out.read_text().splitlines() if line.startswith("v ")], dtype=float)
    np.testing.assert_allclose(v, ground, atol=0.006)  # stored to the header's 0.01 ft
    with pytest.raises(SystemExit) as exited:  # argparse's usage error
        main(["flatten", str(src), "--las-classes", "2,x", "-o", str(out)])
    assert exited.value.code == 2 and "give classification codes as integers" in capsys.readouterr().err


def test_inspect_reads_the_chosen_classes(tmp_path, grid):
    ints, classes = grid
    src = tmp_path / "tile.las"
    src.write_bytes(_las_bytes(ints, classes))
    out = tmp_path / "diagnostics.json"
    assert main(["inspect", str(src), "--las-classes", "2", "-o", str(out)]) == 0
    assert json.loads(out.read_text())["n_points"] == int((classes == 2).sum())


def test_withheld_points_are_left_out_and_keep_their_rows(tmp_path, grid, capsys):
    """ASPRS: withheld means deleted. They are left out with a count; without a class filter
    the points kept carry their file rows, so flatten's .csv keeps a nan,nan row for each."""
    ints, classes = grid
    ground = classes == 2
    withheld = np.zeros(len(ints), dtype=bool)
    withheld[[3, 50, 51]] = True
    path = tmp_path / "tile.las"
    path.write_bytes(_las_bytes(ints, classes, withheld=withheld))
    expected = ints * np.array(SCALE) + np.array(OFFSET)
    with pytest.warns(UserWarning) as said:
        raw = read_las(path, path.read_bytes())
    messages = [str(w.message) for w in said]
    assert any("3 of 120 points are flagged withheld (deleted) and are left out" in m for m in messages)
    assert any("all 117 points are read, of 2 classification classes (2 ground: 105, 6 building: 12)" in m
               for m in messages)
    np.testing.assert_allclose(raw.points, expected[~withheld], rtol=0, atol=1e-9)
    np.testing.assert_array_equal(raw.rows, np.flatnonzero(~withheld))
    assert raw.n_rows == 120
    with pytest.warns(UserWarning, match="withheld"):
        chosen = read_las(path, path.read_bytes(), [2])
    np.testing.assert_allclose(chosen.points, expected[ground & ~withheld], rtol=0, atol=1e-9)
    assert chosen.rows is None  # a class filter: rows are the kept points
    all_withheld = tmp_path / "deleted.las"
    all_withheld.write_bytes(_las_bytes(ints, classes, withheld=np.ones(len(ints), dtype=bool)))
    with pytest.warns(UserWarning), pytest.raises(InputFileError, match="all 120 points are flagged withheld"):
        read_las(all_withheld, all_withheld.read_bytes())
