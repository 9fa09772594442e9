"""``--repair``: the largest connected piece of a mesh or point set, its mesh repaired."""

from __future__ import annotations

import numpy as np
import pytest

from parambench.bench.cli import main
from parambench.datasets_gen.errors import DisconnectedError, NotADiskError
from parambench.datasets_gen.real import pymeshlab_samples_dir
from parambench.datasets_gen.repair import repair_surface
from parambench.datasets_gen.surface import Surface
from parambench.methods.mesh.topology import require_connected_disk_like


def _grid(n, offset=(0.0, 0.0)):
    """An n x n unit grid in the plane z = 0, two triangles per cell."""
    x, y = np.meshgrid(np.arange(n, dtype=float), np.arange(n, dtype=float))
    pts = np.c_[x.ravel() + offset[0], y.ravel() + offset[1], np.zeros(n * n)]
    i = np.arange(n * n).reshape(n, n)[:-1, :-1].ravel()
    faces = np.r_[np.c_[i, i + 1, i + n + 1], np.c_[i, i + n + 1, i + n]]
    return pts, faces


def _write_obj(path, points, faces):
    path.write_text("".join(f"v {x:.17g} {y:.17g} {z:.17g}\n" for x, y, z in points)
                    + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in faces))


def _assert_the_plane_s_exact_map(out, points):
    """The uv written to ``out`` (OBJ) is the planar ``points``' own (x, y) up to a similarity."""
    uv = np.array([[float(t) for t in line.split()[1:3]] for line in out.read_text().splitlines()
                   if line.startswith("vt ")])
    z, w = uv[:, 0] + 1j * uv[:, 1], points[:, 0] + 1j * points[:, 1]
    z, w = z - z.mean(), w - w.mean()
    fit = np.vdot(z, w) / np.vdot(z, z) * z
    assert np.abs(fit - w).max() < 1e-6 * np.abs(w).max()


def _scan_like():
    """A 10 x 10 grid, a 3 x 3 speck far away, and a bowtie: a second 3 x 3 grid touching
    the first at its corner vertex only (a non-manifold vertex)."""
    big, fb = _grid(10)
    speck, fs = _grid(3, (100.0, 0.0))
    bow, fw = _grid(3, (9.0, 9.0))
    fw = fw + len(big) + len(speck)
    corner = len(big) + len(speck)  # bow's (9, 9) vertex is big's last vertex
    bow = bow[1:]
    fw = np.where(fw == corner, len(big) - 1, np.where(fw > corner, fw - 1, fw))
    points = np.r_[big, speck, bow]
    faces = np.r_[fb, fs + len(big), fw]
    return points, faces


def test_a_mesh_keeps_its_largest_piece_with_the_non_manifold_vertex_split():
    points, faces = _scan_like()
    surface = Surface(points=points, faces=faces, name="scan")
    with pytest.raises(NotADiskError):  # the bowtie's shared corner
        require_connected_disk_like(surface.points, surface.faces)
    repaired, facts = repair_surface(surface)
    # 10 x 10 grid + bowtie (one piece through the corner) against the 3 x 3 speck.
    assert facts["pieces"] == 2 and facts["faces_in"] == len(faces)
    assert facts["vertices_split"] == 1 and facts["pieces_after_repair"] == 2
    # After the split the bowtie is a piece of its own and the larger grid is kept, whole.
    assert facts["faces_out"] == 162 and facts["points_out"] == 100
    loops = require_connected_disk_like(repaired.points, repaired.faces)
    assert len(loops) == 1 and len(loops[0]) == 36
    assert np.allclose(np.sort(repaired.points, axis=0), np.sort(_grid(10)[0], axis=0))
    assert repaired.params["repaired"] == facts


def test_a_point_set_keeps_its_largest_knn_component_with_its_normals():
    big, _ = _grid(12)
    small, _ = _grid(4, (50.0, 0.0))
    points = np.r_[small, big]
    normals = np.tile([0.0, 0.0, 1.0], (len(points), 1))
    normals[len(small):, 2] = -1.0  # tell the kept rows apart
    repaired, facts = repair_surface(Surface(points=points, normals=normals, name="pts"), k_nn=8)
    assert facts == {"kind": "points", "pieces": 2, "k_nn": 8, "points_in": 160, "points_out": 144}
    assert np.array_equal(repaired.points, big) and np.all(repaired.normals[:, 2] == -1.0)
    assert repaired.faces is None


def test_flatten_offers_repair_and_repair_gives_the_exact_map(tmp_path, capsys):
    """The planar grid's conformal map is the identity up to similarity."""
    from parambench.datasets_gen.formats import read_file

    points, faces = _scan_like()
    src = tmp_path / "scan.obj"
    _write_obj(src, points, faces)
    out = tmp_path / "uv.obj"
    assert main(["flatten", str(src), "-o", str(out)]) == 2
    assert "pass --repair" in capsys.readouterr().err and not out.exists()
    assert main(["flatten", str(src), "--repair", "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert "kept the largest of 2 piece(s), 162 of 178 faces and 100 of 117 vertices" in err
    mesh = read_file(out)
    assert len(mesh.points) == 100 and len(mesh.faces) == 162
    _assert_the_plane_s_exact_map(out, mesh.points)


def test_points_only_offers_repair_for_a_disconnected_point_set(tmp_path, capsys):
    big, _ = _grid(12)
    src = tmp_path / "two.xyz"
    np.savetxt(src, np.r_[big, _grid(4, (50.0, 0.0))[0]])
    assert main(["inspect", str(src), "-o", str(tmp_path / "f.json")]) == 2
    err = capsys.readouterr().err
    assert "several components" in err and "pass --repair" in err
    assert main(["inspect", str(src), "--repair", "-o", str(tmp_path / "f.json")]) == 0
    assert "kept the largest of 2 piece(s) of the 8-nearest-neighbour graph, 144 of 160 points" in capsys.readouterr().err
    with pytest.raises(DisconnectedError):
        from parambench.methods.pointset.frontend import build_frontend

        build_frontend(np.r_[big, _grid(4, (50.0, 0.0))[0]])


@pytest.mark.skipif(not (pymeshlab_samples_dir() / "rangemaps" / "face000.ply").is_file(),
                    reason="pymeshlab's sample range scan is not installed")
def test_a_real_range_scan_flattens_after_repair_as_libigl_does():
    """pymeshlab's face range scan: 17 pieces and non-manifold vertices, refused as it is;
    repaired, our SCP and libigl's agree on the map's quality."""
    from parambench.bench.metrics import evaluate
    from parambench.datasets_gen.io import load_surface
    from parambench.methods.registry import get_method

    surface = load_surface(pymeshlab_samples_dir() / "rangemaps" / "face000.ply")
    with pytest.raises(NotADiskError):
        get_method("scp")(surface)
    repaired, facts = repair_surface(surface)
    assert facts["pieces"] == 17 and facts["vertices_split"] > 0
    loops = require_connected_disk_like(repaired.points, repaired.faces)
    assert len(loops) > 10  # a scan with many holes
    ours = evaluate(repaired.points, repaired.faces, get_method("scp")(repaired).uv)
    igl = evaluate(repaired.points, repaired.faces, get_method("scp-igl")(repaired).uv)
    assert ours["qc_mean"] == pytest.approx(igl["qc_mean"], rel=0.01)
    assert ours["foldovers"] <= igl["foldovers"]


def test_repair_reverses_faces_wound_against_their_neighbours(tmp_path, capsys):
    """A grid with a patch of faces written the other way round (files merged from tools that
    wind differently): refused with the repair offered; repaired, its map is the exact one."""
    points, faces = _grid(9)
    faces[5:25] = faces[5:25, ::-1]
    src = tmp_path / "mixed.obj"
    _write_obj(src, points, faces)
    out = tmp_path / "uv.obj"
    assert main(["flatten", str(src), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "20 face(s) are wound against their neighbours" in err and "pass --repair to reverse them" in err
    assert main(["flatten", str(src), "--repair", "-o", str(out)]) == 0
    assert "20 face(s) reversed to match their neighbours' winding" in capsys.readouterr().err
    _assert_the_plane_s_exact_map(out, points)


def test_repair_drops_zero_area_faces_that_the_check_refuses(tmp_path, capsys):
    """A CAD export's null facet: a face over three collinear vertices of the grid's first row.
    Refused with --repair offered (before: no way through but another tool); repaired, the
    grid's map is the exact one."""
    points, faces = _grid(6)
    faces = np.r_[faces, [[0, 2, 1]]]
    src = tmp_path / "null.obj"
    _write_obj(src, points, faces)
    out = tmp_path / "uv.obj"
    assert main(["flatten", str(src), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "DegenerateFacesError: 1 face(s) have zero area" in err and "pass --repair to drop them" in err
    assert main(["flatten", str(src), "--repair", "-o", str(out)]) == 0
    assert "dropped 1 degenerate face(s)" in capsys.readouterr().err
    _assert_the_plane_s_exact_map(out, points)


@pytest.mark.parametrize("fin_first", [False, True])
def test_repair_drops_the_fin_on_a_non_manifold_edge_not_the_surface(fin_first):
    """A triangle standing on an interior edge of a grid: pymeshlab's repair removed, in file
    order, the grid's face instead (the map then had a hole and the fin, QC 1.18 against
    1.01); the two faces that continue each other across the edge are kept."""
    points, faces = _grid(6)
    a, b = faces[12, 0], faces[12, 1]  # an interior edge of the grid's rows
    fin = [[a, b, len(points)]]
    points = np.r_[points, [points[a] + [0.0, 0.0, 1.0]]]
    mixed = np.r_[fin, faces] if fin_first else np.r_[faces, fin]
    repaired, facts = repair_surface(Surface(points=points, faces=mixed, name="fin"))
    assert facts["faces_out"] == len(faces) and facts["points_out"] == len(points) - 1
    kept = {tuple(sorted(map(tuple, repaired.points[f].round(9)))) for f in repaired.faces}
    grid = {tuple(sorted(map(tuple, points[f].round(9)))) for f in faces}
    assert kept == grid


def test_inspect_with_repair_gives_loops_in_the_input_file_s_rows(tmp_path, capsys):
    """Junk rows before and after a point set: the loops indexed the repaired set, shifted by
    the rows dropped before them (10.5 % landed on boundary rows of the input)."""
    import json

    from parambench.datasets_gen.registry import make_surface

    surface = make_surface("holes", 3000, sampling="jittered", seed=0)
    rows = np.r_[np.full((5, 3), 100.0), surface.points, [[50.0, 50.0, 50.0]]]  # a scanner's repeated junk return
    src, out = tmp_path / "scan.xyz", tmp_path / "front.json"
    np.savetxt(src, rows, fmt="%.17g")
    assert main(["inspect", str(src), "--repair", "-o", str(out)]) in (0, 3)
    report = json.loads(out.read_text())
    assert report["input_rows"] == list(range(5, 5 + len(surface.points)))
    on_boundary = np.zeros(len(rows), dtype=bool)
    on_boundary[5:5 + len(surface.points)] = surface.boundary_mask
    found = np.concatenate([np.asarray(loop) for loop in report["boundary_loops"]])
    assert on_boundary[found].mean() > 0.9


def _three_fans_at_a_corner():
    """A 10 x 10 grid with two single triangles standing on its corner vertex (0, 0, 0):
    three fans meet there. pymeshlab's meshing_repair_non_manifold_vertices split off one
    and left the vertex non-manifold (the npm package snowden's bust: 55 such vertices,
    and the "repaired" mesh was refused)."""
    points, faces = _grid(10)
    extra = np.array([[0.0, 0.3, 1.0], [0.3, 0.0, 1.0], [0.0, -0.3, -1.0], [-0.3, 0.0, -1.0]])
    n = len(points)
    return np.r_[points, extra], np.r_[faces, [[0, n, n + 1], [0, n + 2, n + 3]]]


def test_split_fans_gives_each_fan_at_a_vertex_its_own_copy():
    from parambench.datasets_gen.mesh_fans import split_fans
    from parambench.methods.mesh.topology import non_manifold_vertices

    points, faces = _three_fans_at_a_corner()
    assert non_manifold_vertices(faces, len(points)).tolist() == [0]
    split, source = split_fans(faces, len(points))
    assert len(source) == len(points) + 2 and source[len(points):].tolist() == [0, 0]
    assert non_manifold_vertices(split, len(source)).size == 0
    assert np.array_equal(points[source][split], points[faces])  # every face where it was
    assert np.array_equal(split[:-2], faces[:-2])  # the grid keeps its vertices


def test_repair_splits_every_fan_where_three_meet(tmp_path, capsys):
    points, faces = _three_fans_at_a_corner()
    repaired, facts = repair_surface(Surface(points=points, faces=faces, name="fans"))
    assert facts["vertices_split"] == 2 and facts["pieces_after_repair"] == 3
    assert facts["faces_out"] == 162 and facts["points_out"] == 100
    assert len(require_connected_disk_like(repaired.points, repaired.faces)) == 1
    src, out = tmp_path / "fans.obj", tmp_path / "uv.obj"
    _write_obj(src, points, faces)
    assert main(["flatten", str(src), "--repair", "-o", str(out)]) == 0
    capsys.readouterr()
    _assert_the_plane_s_exact_map(out, _grid(10)[0])


def test_comparable_mesh_pieces_are_refused_with_the_weld_advice_not_repaired(tmp_path, capsys):
    """Two halves of a grid stored unwelded, their shared column as coincident vertices (as
    patch exports store them: the npm package teapot's 32 Bezier patches). Keeping the
    largest kept 32 of the teapot's 992 faces, exit 0; now refused, with the weld named."""
    left, fl = _grid(6)
    right, fr = _grid(6, (5.0, 0.0))
    points, faces = np.r_[left, right], np.r_[fl, fr + len(left)]
    src, out = tmp_path / "halves.obj", tmp_path / "uv.obj"
    _write_obj(src, points, faces)
    for extra in ([], ["--repair"]):
        assert main(["flatten", str(src), *extra, "-o", str(out)]) == 2
        err = capsys.readouterr().err
        assert "DisconnectedError: the mesh has 2 connected components (50, 50 faces)" in err
        assert "they meet at 12 coincident vertices" in err and "pass --weld" in err
        assert "keeping the largest would drop 50 of 100 faces" in err and "pass --repair" not in err
    assert not out.exists()
    with pytest.raises(DisconnectedError):
        repair_surface(Surface(points=points, faces=faces, name="halves"))
    # welded as the error says, they are the 6 x 11 grid, and its map is the plane's own
    assert main(["flatten", str(src), "--weld", "-o", str(out)]) == 0
    assert "welded: merged 6 coincident vertices" in capsys.readouterr().err
    from parambench.datasets_gen.formats import read_file

    mesh = read_file(out)
    assert len(mesh.points) == 66 and len(mesh.faces) == 100
    _assert_the_plane_s_exact_map(out, mesh.points)


def test_weld_merges_coincident_vertices_into_the_first():
    from parambench.datasets_gen.weld import weld_coincident

    points, faces = _grid(4)
    points = np.r_[points, points[5:6]]  # a copy of vertex 5, used by the faces at 5 of one row
    uses = np.flatnonzero((faces == 5).any(axis=1))[:2]
    faces[uses] = np.where(faces[uses] == 5, 16, faces[uses])
    welded, facts = weld_coincident(Surface(points=points, faces=faces, name="w"))
    assert facts["vertices_merged"] == 1 and facts["faces_dropped"] == 0
    assert np.array_equal(welded.points, _grid(4)[0]) and np.array_equal(welded.faces, _grid(4)[1])
    same, none = weld_coincident(Surface(points=_grid(4)[0], faces=_grid(4)[1], name="g"))
    assert none["vertices_merged"] == 0 and np.array_equal(same.faces, _grid(4)[1])
