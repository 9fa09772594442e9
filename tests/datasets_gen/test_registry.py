"""The registry: names, descriptions, errors that list the valid choices, real datasets."""

from __future__ import annotations

import numpy as np
import pytest

from parambench.datasets_gen.errors import InputFileError, InvalidInputError, TooFewPointsError, UnknownNameError
from parambench.datasets_gen.registry import SAMPLINGS, dataset_info, dataset_names, make_surface

PROCEDURAL = ["plane", "saddle", "bump", "holes", "holes-bumped", "cap", "cylinder", "protrusions", "gnome-strip",
              "slit", "fold"]
REAL = ["real/camelhead", "real/lilium", "real/bump-domain", "real/meg-helmet", "real/spot-top", "real/cortex-lh",
        "real/bunny10k", "real/chameleon", "real/lidar-ground"]


def test_names_and_info():
    assert SAMPLINGS == ("grid", "jittered", "random", "blue-noise", "graded")
    assert dataset_names() == PROCEDURAL + REAL
    info = dataset_info()
    assert list(info) == dataset_names()
    assert all(isinstance(v, str) and v and "\n" not in v for v in info.values())


def test_unknown_names_list_the_valid_ones():
    with pytest.raises(UnknownNameError) as err:
        make_surface("torus")
    assert "saddle" in str(err.value) and "real/camelhead" in str(err.value)
    with pytest.raises(UnknownNameError) as err:
        make_surface("plane", 500, sampling="hexagonal")
    assert all(s in str(err.value) for s in SAMPLINGS)
    with pytest.raises(UnknownNameError) as err:
        make_surface("bump", 500, height=3)
    assert "h, s" in str(err.value)
    with pytest.raises(UnknownNameError):
        make_surface("real/lilium", scale=2)


def test_bad_values():
    with pytest.raises(TooFewPointsError):
        make_surface("plane", 50)
    for count in (500.5, "500", None):
        with pytest.raises(InvalidInputError):
            make_surface("plane", count)
    assert make_surface("plane", np.int64(500)).params["n_points"] == 500
    with pytest.raises(InvalidInputError):
        make_surface("plane", 500, noise=-0.1)
    with pytest.raises(InvalidInputError):
        make_surface("bump", 500, s=0.0)
    with pytest.raises(InvalidInputError):
        make_surface("protrusions", 500, radius=0.6)


@pytest.mark.parametrize("name,n,loops", [("real/camelhead", 11381, 1), ("real/lilium", 3389, 1),
                                          ("real/bump-domain", 4172, 1), ("real/meg-helmet", 2044, 1),
                                          ("real/spot-top", 2089, 1), ("real/cortex-lh", 12226, 1),
                                          ("real/bunny10k", 5051, 5)])
def test_real_meshes(name, n, loops):
    s = make_surface(name, 999, sampling="grid", seed=4)
    assert s.name == name and s.n_points == n and len(s.boundary_loops) == loops
    assert s.params["n_points"] == n and s.params["sampling"] is None
    assert s.params["ignored"] == {"n_points": 999, "sampling": "grid"}
    assert s.exact_uv is None
    # mesh normals agree with the faces' orientation
    p = s.points[s.faces]
    fn = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    assert np.mean(np.einsum("ij,ij->i", fn, s.normals[s.faces].sum(axis=1)) > 0) > 0.99


def _one_chain(link_edges: list) -> bool:
    """Whether edges (pairs of vertex ids) form one path or one cycle."""
    degree, parent = {}, {}

    def root(x):
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    for a, b in link_edges:
        for x in (a, b):
            degree[x] = degree.get(x, 0) + 1
            parent.setdefault(x, x)
        parent[root(a)] = root(b)
    return max(degree.values()) <= 2 and len({root(x) for x in parent}) == 1


def _disk_topology(faces: np.ndarray, n_vertices: int) -> dict:
    """Components, manifoldness and Euler characteristic, counted from the faces alone."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    edges = np.sort(faces[:, [[0, 1], [1, 2], [2, 0]]].reshape(-1, 2), axis=1)
    unique_edges, faces_per_edge = np.unique(edges, axis=0, return_counts=True)
    graph = coo_matrix((np.ones(len(unique_edges)), tuple(unique_edges.T)), shape=(n_vertices, n_vertices))
    n_components = connected_components(graph, directed=False)[0]
    # Vertex manifold: the faces around each vertex form one fan, i.e. the link edges opposite
    # the vertex make one chain (a path, or a cycle for an interior vertex).
    links = [[] for _ in range(n_vertices)]
    for a, b, c in faces.tolist():
        links[a].append((b, c))
        links[b].append((c, a))
        links[c].append((a, b))
    fans_ok = all(_one_chain(link) for link in links if link)
    return {"components": n_components, "edge_manifold": bool(faces_per_edge.max() <= 2),
            "vertex_manifold": fans_ok, "boundary_edges": int(np.sum(faces_per_edge == 1)),
            "euler": n_vertices - len(unique_edges) + len(faces)}


@pytest.mark.parametrize("name,n,f,loop_edges", [("real/camelhead", 11381, 22704, None),
                                                 ("real/lilium", 3389, 6590, None),
                                                 ("real/bump-domain", 4172, 8058, None),
                                                 ("real/meg-helmet", 2044, 3987, 99),
                                                 ("real/spot-top", 2089, 4112, 64),
                                                 ("real/cortex-lh", 12226, 23999, 451)])
def test_shipped_meshes_are_disks(name, n, f, loop_edges):
    s = make_surface(name)
    assert s.points.shape == (n, 3) and s.faces.shape == (f, 3)
    topo = _disk_topology(s.faces, n)
    # One manifold component with one boundary loop and Euler characteristic 1: a disk.
    assert topo["components"] == 1 and topo["edge_manifold"] and topo["vertex_manifold"]
    assert topo["euler"] == 1 and len(s.boundary_loops) == 1
    assert topo["boundary_edges"] == len(s.boundary_loops[0]) == s.boundary_mask.sum()
    if loop_edges is not None:
        assert len(s.boundary_loops[0]) == loop_edges
    assert np.all(np.isfinite(s.points)) and np.unique(s.points, axis=0).shape[0] == n


def test_disk_topology_counter_catches_what_it_should():
    # Two triangles sharing only a vertex (bow tie): one component, edge-manifold, not vertex-manifold.
    bowtie = np.array([[0, 1, 2], [0, 3, 4]])
    assert _disk_topology(bowtie, 5)["vertex_manifold"] is False
    # Three faces on one edge: not edge-manifold.
    assert _disk_topology(np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]]), 5)["edge_manifold"] is False
    # Two separate triangles: two components. A closed tetrahedron: Euler characteristic 2.
    assert _disk_topology(np.array([[0, 1, 2], [3, 4, 5]]), 6)["components"] == 2
    tet = _disk_topology(np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [2, 0, 3]]), 4)
    assert tet["euler"] == 2 and tet["boundary_edges"] == 0 and tet["vertex_manifold"]


def test_camelhead_counts_and_noise():
    s = make_surface("real/camelhead")
    assert s.faces.shape == (22704, 3)
    noisy = make_surface("real/camelhead", seed=1, noise=0.3)
    d = noisy.points - s.points
    assert np.allclose(d, np.einsum("ij,ij->i", d, s.normals)[:, None] * s.normals, atol=1e-12)
    assert np.array_equal(make_surface("real/camelhead", seed=1, noise=0.3).points, noisy.points)


def test_chameleon_is_points_only():
    s = make_surface("real/chameleon")
    assert s.faces is None and s.n_points == 4594 and s.params["normals"] == "file"


def test_missing_real_data_says_where_it_looked(tmp_path, monkeypatch):
    monkeypatch.setenv("PARAMBENCH_REAL_DATA", str(tmp_path))
    with pytest.raises(InputFileError) as err:
        make_surface("real/lilium")
    assert str(tmp_path) in str(err.value) and "lilium.obj" in str(err.value)


def test_env_var_points_to_another_folder(tmp_path, monkeypatch):
    (tmp_path / "lilium.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0.5\nf 1 2 3\nf 2 4 3\n")
    monkeypatch.setenv("PARAMBENCH_REAL_DATA", str(tmp_path))
    assert make_surface("real/lilium").n_points == 4
