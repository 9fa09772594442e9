"""Handles of the surface a point set samples (methods/pointset/handles.py): genus of meshes
whose topology is known, the agreed triangles of point sets, and the self-check's cause."""

from __future__ import annotations

import numpy as np
import pytest

from parambench.bench.cli import main
from parambench.datasets_gen.errors import NoBoundaryError
from parambench.datasets_gen.registry import make_surface
from parambench.methods import get_method
from parambench.datasets_gen.surface import MethodInput
from parambench.methods.pointset.handles import agreed_triangles, handle_cause, handle_count
from parambench.methods.pointset.neighbourhoods import knn_graph
from parambench.methods.pointset.normals import pca_normals


def _grid_faces(nu: int, nv: int, wrap_u: bool, wrap_v: bool) -> np.ndarray:
    """Triangles of an nu x nv vertex grid (vertex i * nv + j), wrapped round where asked."""
    iu = np.arange(nu if wrap_u else nu - 1)
    jv = np.arange(nv if wrap_v else nv - 1)
    i, j = (a.ravel() for a in np.meshgrid(iu, jv, indexing="ij"))
    a, b = i * nv + j, ((i + 1) % nu) * nv + j
    c, d = ((i + 1) % nu) * nv + (j + 1) % nv, i * nv + (j + 1) % nv
    return np.r_[np.c_[a, b, c], np.c_[a, c, d]]


def _without_stars(faces: np.ndarray, vertices) -> np.ndarray:
    return faces[~np.isin(faces, vertices).any(axis=1)]


def _torus_points(n: int, seed: int, holes: int, noise: float = 0.0) -> np.ndarray:
    """Uniform random points on a torus (R 2, r 0.8) with ``holes`` disks of radius 0.6 cut out."""
    rng = np.random.default_rng(seed)
    big, small = 2.0, 0.8
    u, v, w = rng.uniform(0, 2 * np.pi, 3 * n), rng.uniform(0, 2 * np.pi, 3 * n), rng.uniform(0, 1, 3 * n)
    keep = w < (big + small * np.cos(v)) / (big + small)  # area-uniform
    u, v = u[keep], v[keep]
    p = np.c_[(big + small * np.cos(v)) * np.cos(u), (big + small * np.cos(v)) * np.sin(u), small * np.sin(v)]
    for centre in ([big + small, 0, 0], [-(big + small), 0, 0])[:holes]:
        p = p[np.linalg.norm(p - centre, axis=1) > 0.6]
    p = p[:n]
    if noise:
        p = p + rng.normal(0, noise * np.sqrt(4 * np.pi**2 * big * small / n), p.shape)
    return p


def _normals(points: np.ndarray) -> np.ndarray:
    return pca_normals(points, knn_graph(points, 8).indices)


@pytest.mark.parametrize("wrap_u,wrap_v,cut,genus,loops", [
    (False, False, [], 0, 1),         # a disk
    (True, False, [], 0, 2),          # a cylinder: an annulus
    (False, False, [40], 0, 2),       # a disk with a hole (interior vertex (4, 4): its star removed)
    (True, True, [27], 1, 1),         # a torus with a hole
    (True, True, [27, 62], 1, 2),     # a torus with two holes
])
def test_genus_and_loops_of_meshes_of_known_topology(wrap_u, wrap_v, cut, genus, loops):
    faces = _without_stars(_grid_faces(10, 9, wrap_u, wrap_v), cut)
    count = handle_count(faces, 90)
    assert count["genus"] == genus and count["boundary_loops"] == loops
    assert count["share"] == pytest.approx((90 - len(cut)) / 90)


def test_vertices_joined_only_at_a_corner_are_split():
    """Two grid disks sharing one corner vertex (a pinch): counted as the manifold they are.
    Unsplit, the shared vertex would take 1 from chi and join the two rims into one loop."""
    square = _grid_faces(4, 4, False, False)  # vertices 0..15, corner 15 at (3, 3)
    other = np.where(square == 0, 15, square + 16)  # its corner 0 is the first one's 15
    count = handle_count(np.r_[square, other], 31)
    assert count["genus"] == 0 and count["boundary_loops"] == 1  # the largest piece: one of the two disks
    assert count["share"] == pytest.approx(16 / 31)


def test_agreed_triangles_of_a_jittered_plane_mesh_it_with_no_edge_in_three():
    rng = np.random.default_rng(3)
    g = np.stack(np.meshgrid(np.arange(30.0), np.arange(30.0), indexing="ij"), axis=-1).reshape(-1, 2)
    points = np.c_[g + rng.uniform(-0.25, 0.25, g.shape), np.zeros(len(g))]
    faces = agreed_triangles(points, np.tile([0.0, 0.0, 1.0], (len(points), 1)))
    edges = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    _, uses = np.unique(edges, axis=0, return_counts=True)
    assert uses.max() == 2
    count = handle_count(faces, len(points))
    assert count["genus"] == 0 and count["share"] > 0.99
    # Delaunay of a 30 x 30 jittered grid: about 2 * 29 * 29 triangles, all agreed on inside.
    assert len(faces) > 0.95 * 2 * 29 * 29


@pytest.mark.parametrize("n,holes,noise", [(2000, 1, 0.0), (5000, 2, 0.25)])
def test_a_torus_cut_open_is_found_to_have_a_handle(n, holes, noise):
    points = _torus_points(n, 0, holes, noise)
    cause = handle_cause(points, _normals(points))
    assert cause is not None and cause["genus"] == 1 and cause["share"] > 0.9


@pytest.mark.parametrize("name,sampling", [("bump", "random"), ("holes", "graded"), ("cylinder", "random"),
                                           ("fold", "jittered"), ("real/bunny10k", None)])
def test_disks_and_annuli_have_no_handle(name, sampling):
    surface = make_surface(name, 2000, sampling=sampling, seed=0) if sampling else make_surface(name, seed=0)
    points = surface.points
    assert handle_cause(points, _normals(points)) is None
    count = handle_count(agreed_triangles(points, _normals(points)), len(points))
    assert count["genus"] == 0 and count["share"] > 0.75  # judged, and found to have none


def test_a_failed_map_of_a_torus_says_handle_and_runs_no_retry():
    points = _torus_points(3000, 1, 1)
    result = get_method("ocp")(MethodInput(points))
    check = result.diagnostics["selfcheck"]
    assert not check["passed"] and check["causes"]["handle"]["genus"] == 1
    assert "handle(s), which no map lays flat" in check["reason"]
    assert "retry" not in check  # no parameter takes a handle off


def test_flatten_of_a_torus_cut_open_exits_3_with_the_cut_to_make(tmp_path, capsys):
    src = tmp_path / "mug.xyz"
    np.savetxt(src, _torus_points(3000, 2, 1))
    assert main(["flatten", str(src), "-o", str(tmp_path / "uv.obj")]) == 3
    err = capsys.readouterr().err
    assert "cut the surface open across each handle" in err and "--param" not in err
    assert not (tmp_path / "uv.obj").exists()


def test_no_boundary_on_a_closed_torus_names_its_handle_and_not_on_a_sphere():
    points = _torus_points(3000, 4, 0)
    with pytest.raises(NoBoundaryError, match=r"1 handle\(s\).*a cut across each handle"):
        get_method("ocp")(MethodInput(points))
    rng = np.random.default_rng(5)
    sphere = rng.normal(size=(3000, 3))
    sphere /= np.linalg.norm(sphere, axis=1)[:, None]
    with pytest.raises(NoBoundaryError) as caught:
        get_method("ocp")(MethodInput(sphere))
    assert "handle" not in str(caught.value)


def test_inspect_reports_the_handle_and_exits_3(tmp_path, capsys):
    import json

    src, out = tmp_path / "mug.xyz", tmp_path / "front.json"
    np.savetxt(src, _torus_points(3000, 2, 1))
    assert main(["inspect", str(src), "-o", str(out)]) == 3
    assert "1 handle(s)" in capsys.readouterr().err
    assert json.loads(out.read_text())["selfcheck"]["handle"]["genus"] == 1
    flat = tmp_path / "bump.xyz"
    np.savetxt(flat, make_surface("bump", 2000, sampling="random", seed=0).points)
    assert main(["inspect", str(flat), "-o", str(out)]) == 0
    assert json.loads(out.read_text())["selfcheck"]["handle"] is None


def test_the_count_is_made_once_per_checked_run(monkeypatch):
    """The retries' checks judge the same points: inside one checked run the agreed
    triangles are built once; outside a run (no memo) every call counts afresh."""
    import parambench.methods.base as base
    import parambench.methods.pointset.handles as handles

    points = _torus_points(2000, 0, 1)
    normals = _normals(points)
    calls = []
    real = handles.agreed_triangles
    monkeypatch.setattr(handles, "agreed_triangles", lambda *a: calls.append(1) or real(*a))
    token = base._RETRY_MEMO.set({})
    try:
        first, second = handle_cause(points, normals), handle_cause(points, normals)
    finally:
        base._RETRY_MEMO.reset(token)
    assert first == second and first["genus"] == 1 and len(calls) == 1
    handle_cause(points, normals)
    handle_cause(points, normals)
    assert len(calls) == 3
