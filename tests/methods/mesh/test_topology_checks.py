"""Mesh topology checks that fire (issue #11 item 7): duplicate faces, non-manifold edges, bowties.

Before: ``igl.is_edge_manifold`` returns a tuple, whose truth is always True, so a
non-manifold edge passed the check (the libigl baselines ran on it) and a duplicate face
surfaced as "a boundary loop has 1 vertices".
"""

import numpy as np
import pytest

from parambench.datasets_gen.errors import NotADiskError, TopologyError
from parambench.datasets_gen.mesh_loops import mesh_boundary
from parambench.datasets_gen.surface import Surface
from parambench.methods import get_method, method_names
from parambench.methods.mesh.topology import (
    coherent_flips,
    duplicate_faces,
    non_manifold_edges,
    non_manifold_vertices,
    require_connected_disk_like,
)

#: Every registered method that takes faces, so a new mesh method is checked without editing this list.
MESH_METHODS = [name for name in method_names() if get_method(name).needs_faces]


def test_the_known_mesh_methods_are_all_checked():
    assert {"scp", "dncp-opt", "scp-igl", "lscm-igl", "bff-mouette"} <= set(MESH_METHODS)


def _grid(n: int = 6, offset=(0.0, 0.0, 0.0)):
    """An n x n vertex grid of the unit square in z = 0, two triangles per cell, counter-clockwise."""
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    pts = np.column_stack([i.ravel() / (n - 1), j.ravel() / (n - 1), np.zeros(n * n)]) + np.asarray(offset)
    v = lambda a, b: a * n + b  # noqa: E731
    faces = []
    for a in range(n - 1):
        for b in range(n - 1):
            faces += [[v(a, b), v(a + 1, b), v(a + 1, b + 1)], [v(a, b), v(a + 1, b + 1), v(a, b + 1)]]
    return pts, np.array(faces, dtype=np.int64)


def _with_duplicate_face():
    pts, faces = _grid()
    return pts, np.vstack([faces, faces[7][::-1]]), 1


def _with_fin():
    # a third triangle on an interior edge, standing out of the plane: a non-manifold edge
    pts, faces = _grid()
    a, b = faces[12, 0], faces[12, 2]
    tip = len(pts)
    pts = np.vstack([pts, (pts[a] + pts[b]) / 2 + [0.0, 0.0, 0.5]])
    return pts, np.vstack([faces, [a, b, tip]]), 1


def _bowtie():
    # two grids touching at one corner: one component, one vertex with two fans of faces
    pts, faces = _grid(4)
    pts2, faces2 = _grid(4, offset=(1.0, 1.0, 0.0))
    shared = len(pts) - 1  # (1, 1, 0): the first grid's last vertex is the second grid's vertex 0
    remap = np.concatenate([[shared], np.arange(1, len(pts2)) + len(pts) - 1])
    return np.vstack([pts, pts2[1:]]), np.vstack([faces, remap[faces2]]), shared


def test_duplicate_faces_found_in_either_orientation():
    faces = np.array([[0, 1, 2], [0, 2, 3], [2, 1, 0], [3, 2, 0], [1, 2, 0]])
    np.testing.assert_array_equal(duplicate_faces(faces), [[2, 0], [3, 1], [4, 0]])
    assert duplicate_faces(_grid()[1]).shape == (0, 2)


def test_non_manifold_edge_found_with_its_face_count():
    edges, counts = non_manifold_edges(np.array([[0, 1, 2], [0, 2, 3], [0, 4, 2]]))
    np.testing.assert_array_equal(edges, [[0, 2]])
    np.testing.assert_array_equal(counts, [3])
    assert non_manifold_edges(_grid()[1])[0].shape == (0, 2)


def test_bowtie_vertex_found_and_fans_are_not():
    np.testing.assert_array_equal(non_manifold_vertices(np.array([[0, 1, 2], [0, 3, 4]]), 5), [0])
    # a closed fan (interior vertex) and an open fan (boundary vertex) are manifold
    assert non_manifold_vertices(np.array([[0, 1, 2], [0, 2, 3], [0, 3, 1]]), 4).size == 0
    assert non_manifold_vertices(_grid()[1], 36).size == 0
    # inconsistently oriented neighbours still form one fan
    assert non_manifold_vertices(np.array([[0, 1, 2], [0, 3, 2]]), 4).size == 0
    pts, faces, shared = _bowtie()
    np.testing.assert_array_equal(non_manifold_vertices(faces, len(pts)), [shared])


@pytest.mark.parametrize("case, words", [
    (_with_duplicate_face, ["1 duplicate face", "face 50 = face 7", "meshing_remove_duplicate_faces"]),
    (_with_fin, ["1 non-manifold edge", "on 3 faces", "meshing_repair_non_manifold_edges"]),
    (_bowtie, ["1 non-manifold vertex", "meshing_repair_non_manifold_vertices"]),
])
def test_topology_check_names_the_problem(case, words):
    pts, faces, example = case()
    with pytest.raises(NotADiskError) as err:
        require_connected_disk_like(pts, faces)
    message = str(err.value)
    for word in words:
        assert word in message
    if case is _bowtie:
        assert f"vertex {example}" in message
    assert "boundary loop has" not in message


@pytest.mark.parametrize("method", MESH_METHODS)
@pytest.mark.parametrize("case", [_with_duplicate_face, _with_fin, _bowtie])
def test_every_mesh_method_refuses_non_manifold_input(method, case):
    pts, faces, _ = case()
    with pytest.raises(TopologyError, match="non-manifold|duplicate face"):
        get_method(method)(Surface(pts, faces, name=case.__name__))


def test_clean_grid_passes():
    pts, faces = _grid()
    loops = require_connected_disk_like(pts, faces)
    assert len(loops) == 1 and loops[0].size == 20


def test_loaded_mesh_loops_undefined_on_non_manifold_edges():
    pts, faces, _ = _with_fin()
    assert mesh_boundary(faces, len(pts)) == (None, None)
    loops, mask = mesh_boundary(_grid()[1], 36)
    assert len(loops) == 1 and mask.sum() == 20


@pytest.mark.parametrize("reverse", [False, True])
def test_reader_and_methods_take_loops_from_one_definition(reverse):
    # a grid with a square hole: the loops a reader stores are the loops a mesh method checks
    pts, faces = _grid(7)
    cell = 2 * (3 * 6 + 3)  # the two triangles of the middle cell
    faces = np.delete(faces, [cell, cell + 1], axis=0)
    if reverse:
        faces = faces[:, ::-1].copy()
    read, mask = mesh_boundary(faces, len(pts))
    checked = require_connected_disk_like(pts, faces)
    assert [lp.tolist() for lp in read] == [lp.tolist() for lp in checked]
    assert [len(lp) for lp in read] == [24, 4] and mask.sum() == 28
    # each loop runs along its faces' directed edges, whichever way the faces turn
    directed = {(int(a), int(b)) for f in faces for a, b in zip(f, np.roll(f, -1))}
    for loop in read:
        assert all((int(a), int(b)) in directed for a, b in zip(loop, np.roll(loop, -1)))


def _moebius(n: int = 40):
    """A Moebius band: 3 vertices across, ``n`` steps round, the last row glued to the first turned over."""
    t = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)[:, None]
    s = np.array([-0.3, 0.0, 0.3])[None, :]
    pts = np.stack([(1 + s * np.cos(t / 2)) * np.cos(t), (1 + s * np.cos(t / 2)) * np.sin(t),
                    s * np.sin(t / 2) + 0 * t], axis=-1).reshape(-1, 3)
    faces = []
    for i in range(n):
        for k in range(2):
            a, b = 3 * i + k, 3 * i + k + 1
            c, d = (3 * (i + 1) + k + 1, 3 * (i + 1) + k) if i < n - 1 else (1 - k, 2 - k)
            faces += [[a, b, c], [a, c, d]]
    return pts, np.array(faces, dtype=np.int64)


def test_coherent_flips_finds_exactly_the_reversed_minority():
    pts, faces = _grid(8)
    rng = np.random.default_rng(3)
    reversed_ = np.zeros(len(faces), dtype=bool)
    reversed_[rng.choice(len(faces), 20, replace=False)] = True
    mixed = np.where(reversed_[:, None], faces[:, ::-1], faces)
    flips, n_conflicts = coherent_flips(mixed)
    np.testing.assert_array_equal(flips, reversed_)
    assert n_conflicts > 0
    # Reversing the whole mesh is no conflict: nothing to flip.
    assert not coherent_flips(faces[:, ::-1])[0].any() and coherent_flips(faces)[1] == 0


def test_a_moebius_band_is_not_orientable_and_every_mesh_method_says_so():
    pts, faces = _moebius()
    assert coherent_flips(faces)[0] is None
    for method in MESH_METHODS:
        with pytest.raises(NotADiskError, match="not orientable"):
            get_method(method)(Surface(pts, faces, name="moebius"))


@pytest.mark.parametrize("method", MESH_METHODS)
def test_faces_wound_against_their_neighbours_are_refused_with_the_repair(method):
    """Before: ``scp`` mapped such a grid with QC 1.7e12 and ``scp-igl`` folded 74 triangles, exit 0."""
    pts, faces = _grid(8)
    faces[:10] = faces[:10, ::-1]
    with pytest.raises(NotADiskError, match="10 face.s. are wound against their neighbours") as err:
        get_method(method)(Surface(pts, faces, name="mixed"))
    assert getattr(err.value, "repairable", False)
    assert "meshing_re_orient_faces_coherently" in str(err.value)


def test_repair_drops_the_faces_across_a_moebius_twist(tmp_path, capsys):
    """pymeshlab's re-orientation turns some of a band's faces and stops; the methods then
    refused the surface (pymeshfix's planar_mesh.ply, a sheet with a twisted flap, too).
    Without the faces on the edges where the windings meet it is a twisted strip, which maps."""
    from parambench.bench.cli import main
    from parambench.datasets_gen.repair import repair_summary, repair_surface

    pts, faces = _moebius()
    repaired, facts = repair_surface(Surface(pts, faces, name="moebius"))
    assert facts["orientable"] is True and 1 <= facts["faces_dropped_to_orient"] <= 6
    assert facts["faces_out"] == len(faces) - facts["faces_dropped_to_orient"]
    assert f"{facts['faces_dropped_to_orient']} of them on a twisted flap" in repair_summary(facts)
    assert len(require_connected_disk_like(repaired.points, repaired.faces)) == 1  # a strip: one loop
    src, out = tmp_path / "band.obj", tmp_path / "uv.obj"
    src.write_text("".join(f"v {x:.17g} {y:.17g} {z:.17g}\n" for x, y, z in pts)
                   + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in faces))
    assert main(["flatten", str(src), "--method", "scp", "--repair", "-o", str(out)]) == 0
    capsys.readouterr()
    pts, faces = _grid(8)
    faces[:10] = faces[:10, ::-1]
    _, facts = repair_surface(Surface(pts, faces, name="mixed"))
    assert facts["orientable"] is True and facts["faces_reversed"] == 10 and facts["faces_dropped_to_orient"] == 0


def test_orientation_signs_reverse_the_minority_and_find_the_twist_of_a_band_only():
    from parambench.datasets_gen.mesh_fans import orientation_signs

    _, faces = _grid(9)
    faces[5:25] = faces[5:25, ::-1]
    sign, conflict = orientation_signs(faces)
    assert np.flatnonzero(sign < 0).tolist() == list(range(5, 25)) and not conflict.any()
    sign, conflict = orientation_signs(_moebius()[1])
    assert 1 <= conflict.sum() <= 3  # the edges across the band where the windings meet


def _torus_with_a_hole(n: int = 24, m: int = 12):
    """A torus (radii 1 and 0.35) on an n x m grid, with one grid face pair removed: genus 1, one loop."""
    u, v = np.meshgrid(np.linspace(0, 2 * np.pi, n, endpoint=False), np.linspace(0, 2 * np.pi, m, endpoint=False),
                       indexing="ij")
    pts = np.stack([(1 + 0.35 * np.cos(v)) * np.cos(u), (1 + 0.35 * np.cos(v)) * np.sin(u), 0.35 * np.sin(v)],
                   axis=-1).reshape(-1, 3)
    idx = np.arange(n * m).reshape(n, m)
    a, b = idx, np.roll(idx, -1, axis=0)
    c, d = np.roll(b, -1, axis=1), np.roll(a, -1, axis=1)
    faces = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    return pts, np.delete(faces, [0, n * m], axis=0)  # both triangles of quad (0, 0)


def test_a_handle_is_named_by_every_mesh_method():
    """Before: "N triangles flipped; try --param weights=hybrid", then advice about triangle shapes."""
    pts, faces = _torus_with_a_hole()
    assert len(mesh_boundary(faces, len(pts))[0]) == 1
    for method in MESH_METHODS:
        with pytest.raises(NotADiskError, match=r"1 handle\(s\) \(Euler characteristic -1 with 1 boundary loop"):
            get_method(method)(Surface(pts, faces, name="torus with a hole"))
    # A disk with holes is no handle: the grid with its middle face pair removed still maps.
    grid, grid_faces = _grid(8)
    holed = np.delete(grid_faces, [24, 24 + 49], axis=0)
    assert get_method("scp")(Surface(grid, holed, name="holed grid")).diagnostics["selfcheck"]["passed"]


def test_the_moebius_message_sends_nobody_to_points_only():
    pts, faces = _moebius()
    with pytest.raises(NotADiskError) as info:
        get_method("scp")(Surface(pts, faces, name="moebius"))
    assert "--points-only" not in str(info.value) and "cut once across is a disk" in str(info.value)


def test_one_fan_per_vertex_keeps_the_largest_fan_at_a_pinch():
    from parambench.datasets_gen.mesh_loops import one_fan_per_vertex, pinched_vertices

    # Three triangles round vertex 0 (one fan) and a fourth touching them only at vertex 0.
    faces = np.array([[0, 1, 2], [0, 2, 3], [0, 3, 4], [0, 5, 6]])
    assert pinched_vertices(faces, 7).tolist() == [0]
    kept = one_fan_per_vertex(faces, 7)
    assert kept.tolist() == faces[:3].tolist()
    assert pinched_vertices(kept, 7).size == 0
    # Nothing to drop: the same faces back.
    assert one_fan_per_vertex(kept, 7).tolist() == kept.tolist()
