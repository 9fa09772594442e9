"""What a method receives: coincident points merged for point-set methods, cut seams kept for mesh methods."""

from __future__ import annotations

import warnings

import numpy as np

from parambench.methods.pose import surface_pose
import pytest
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import shortest_path

from parambench.bench.metrics import count_foldovers, jacobian_singular_values
from parambench.datasets_gen.registry import make_surface
from parambench.datasets_gen.surface import Surface
from parambench.methods import Method, Parameterization, get_method
from parambench.methods.pointset.coincident import MERGE_SPACING_TOL, CoincidentPointsWarning, coincident_groups


def _spacing(points):
    from scipy.spatial import cKDTree

    d, _ = cKDTree(points).query(points, k=2)
    return float(np.median(d[:, 1]))


# --- coincident points ------------------------------------------------------------------


def test_groups_by_hand():
    a, b, c, d = np.eye(4, 3) + 1.0  # four distinct points, 1 or sqrt(2) apart
    groups = coincident_groups(np.array([a, b, a, c, b, d, a]))
    np.testing.assert_array_equal(groups.representatives, [0, 1, 3, 5])
    np.testing.assert_array_equal(groups.inverse, [0, 1, 0, 2, 1, 3, 0])
    assert groups.n_merged == 3


def test_tolerance_follows_the_spacing():
    base = make_surface("bump", 500, sampling="jittered", seed=0).points
    h = _spacing(base)
    near = base[:3] + [0, 0, 0.1 * MERGE_SPACING_TOL * h]   # well inside the tolerance: merged
    apart = base[3:6] + [0, 0, 10 * MERGE_SPACING_TOL * h]  # ten times outside: distinct samples
    groups = coincident_groups(np.vstack([base, near, apart]))
    assert groups.n_merged == 3
    np.testing.assert_array_equal(groups.inverse[len(base):len(base) + 3], [0, 1, 2])
    assert groups.representatives[-3:].tolist() == list(range(len(base) + 3, len(base) + 6))


def _with_copies(points, fraction, rng):
    """``points`` plus copies of ``fraction`` of them (offset far below the tolerance), shuffled.

    Returns the new array, and for each copy pair (first row, later row) in the new order.
    """
    n = len(points)
    src = rng.choice(n, int(round(fraction * n)), replace=False)
    offset = rng.standard_normal((len(src), 3)) * 1e-3 * MERGE_SPACING_TOL * _spacing(points)
    stacked = np.vstack([points, points[src] + offset])
    order = rng.permutation(len(stacked))
    where = np.empty_like(order)
    where[order] = np.arange(len(order))
    pairs = np.sort(np.c_[where[src], where[n:]], axis=1)
    return stacked[order], pairs


@pytest.mark.parametrize("method", ["sdp", "ocp"])
def test_duplicated_rows_get_their_representatives_uv(method):
    base = make_surface("bump", 800, sampling="jittered", seed=1).points
    points, pairs = _with_copies(base, 0.05, np.random.default_rng(3))
    keep = np.setdiff1d(np.arange(len(points)), pairs[:, 1])  # the de-duplicated set, input order
    with pytest.warns(CoincidentPointsWarning, match=rf"\b{len(pairs)} of {len(points)} points"):
        result = get_method(method)(Surface(points, name="dup"))
    assert result.uv.shape == (len(points), 2)
    np.testing.assert_array_equal(result.uv[pairs[:, 1]], result.uv[pairs[:, 0]])
    assert result.diagnostics["n_coincident_merged"] == len(pairs)
    clean = get_method(method)(Surface(points[keep], name="clean"))
    scale = np.ptp(clean.uv, axis=0).max()
    np.testing.assert_allclose(result.uv[keep], clean.uv, atol=1e-9 * scale)
    # detected boundary loops index the input rows (the caller draws them over its own points)
    loops = result.diagnostics["boundary_loops"]
    np.testing.assert_array_equal(np.concatenate(loops), keep[np.concatenate(clean.diagnostics["boundary_loops"])])


class _Spy(Method):
    """Records what ``run`` is given; maps to the xy coordinates."""

    name = "spy-points"
    seen: list = []

    def run(self, surface, **params):
        type(self).seen.append(surface)
        return Parameterization(uv=surface.points[:, :2], method=self.name)


def test_every_point_set_method_gets_distinct_points_and_no_faces():
    pts = np.random.default_rng(0).random((40, 3))
    faces = np.array([[0, 1, 2], [2, 3, 4]])
    _Spy.seen = []
    with pytest.warns(CoincidentPointsWarning, match=r"\b3 of 43"):
        out = _Spy()(Surface(np.vstack([pts, pts[[5, 7, 5]]]), faces, name="spy"))
    given = _Spy.seen[0]
    assert given.n_points == 40 and given.faces is None
    # the distinct points, in the unit pose every method sees (parambench.methods.pose)
    np.testing.assert_allclose(given.points, surface_pose(pts).to_unit(pts), atol=1e-12)
    np.testing.assert_array_equal(out.uv[40:], out.uv[[5, 7, 5]])


def test_no_copies_no_warning_and_same_surface():
    surface = Surface(np.random.default_rng(0).random((30, 3)), name="plain")
    _Spy.seen = []
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        _Spy()(surface)
    # nothing merged: the method sees all points, only moved to the unit pose (parambench.methods.pose)
    np.testing.assert_allclose(_Spy.seen[0].points, surface_pose(surface.points).to_unit(surface.points), atol=1e-12)


# --- cut seams ---------------------------------------------------------------------------


def _edge_graph(points, faces):
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    w = np.linalg.norm(points[e[:, 0]] - points[e[:, 1]], axis=1)
    n = len(points)
    return coo_matrix((w, (e[:, 0], e[:, 1])), shape=(n, n)).tocsr()


def _seam_path(surface):
    """Edge path from a boundary vertex to the vertex nearest the centre, through the interior."""
    pts, faces = surface.points, surface.faces
    graph = _edge_graph(pts, faces).tolil()
    start = int(surface.boundary_loops[0][0])
    for b in np.flatnonzero(surface.boundary_mask):  # keep the path off the rest of the boundary
        if b != start:
            graph[b, :] = 0
            graph[:, b] = 0
    end = int(np.argmin(np.linalg.norm(pts - pts.mean(axis=0), axis=1)))
    _, pred = shortest_path(graph.tocsr(), directed=False, indices=start, return_predecessors=True)
    path = [end]
    while path[-1] != start:
        path.append(int(pred[path[-1]]))
    return path[::-1]


def _cut(points, faces, path):
    """Cut the mesh along ``path``: around each path vertex, the faces on either side of the cut
    edges get their own copy of the vertex (the tip, with one cut edge, stays whole)."""
    cut = {frozenset(e) for e in zip(path[:-1], path[1:])}
    points, faces = list(points), faces.copy()
    for v in path:
        fan = list(np.flatnonzero((faces == v).any(axis=1)))
        label = {f: f for f in fan}

        def root(f):
            while label[f] != f:
                f = label[f]
            return f

        for i, a in enumerate(fan):
            for b in fan[i + 1:]:
                shared = (set(faces[a]) & set(faces[b])) - {v}
                if shared and frozenset((v, shared.pop())) not in cut:
                    label[root(a)] = root(b)
        sides = {}
        for f in fan:
            sides.setdefault(root(f), []).append(f)
        for side in list(sides.values())[1:]:
            points.append(points[v])
            rows = np.array(side)
            faces[rows] = np.where(faces[rows] == v, len(points) - 1, faces[rows])
    return np.array(points), faces


@pytest.fixture(scope="module")
def cut_disk():
    disk = make_surface("bump", 600, sampling="jittered", seed=0)
    assert len(disk.boundary_loops) == 1
    path = _seam_path(disk)
    points, faces = _cut(disk.points, disk.faces, path)
    assert len(points) == len(disk.points) + len(path) - 1  # every path vertex but the tip is doubled
    return Surface(points, faces, name="cut-bump"), disk.n_points, path


def test_cut_mesh_is_one_disk_with_the_seam_on_its_boundary(cut_disk):
    from parambench.datasets_gen.mesh_loops import mesh_boundary

    surface, n_before, path = cut_disk
    loops, _ = mesh_boundary(surface.faces, surface.n_points)
    assert len(loops) == 1
    on_boundary = set(loops[0].tolist())
    copies = range(n_before, surface.n_points)
    assert set(path[:-1]) <= on_boundary and set(copies) <= on_boundary


@pytest.mark.parametrize("method", ["scp", "dncp-opt", "scp-igl"])
def test_mesh_methods_flatten_a_cut_mesh(cut_disk, method):
    surface, n_before, path = cut_disk
    result = get_method(method)(surface)
    *_, signed, _ = jacobian_singular_values(surface.points, surface.faces, result.uv)
    assert count_foldovers(signed) == 0
    # The seam stays open: the copy of the boundary end of the seam lands away from its twin.
    twin = path[0]
    copy = n_before + int(np.flatnonzero(np.all(surface.points[n_before:] == surface.points[twin], axis=1))[0])
    gap = np.linalg.norm(result.uv[copy] - result.uv[twin])
    assert gap > 1e-3 * np.ptp(result.uv, axis=0).max()


def test_textured_bunny_obj_loads_as_a_mesh():
    from parambench.datasets_gen.io import load_surface
    from parambench.datasets_gen.real import pymeshlab_samples_dir

    surface = load_surface(pymeshlab_samples_dir() / "bunny10k_textured.obj")
    assert surface.has_faces and surface.n_points == 5051 and len(surface.faces) == 9999


def test_a_far_junk_row_does_not_widen_the_merge_tolerance():
    """A 12 cm part sampled every 2 mm at UTM coordinates, plus one ``0 0 0`` row 5.4e6 m away:
    the whole bounding box's tolerance (1e-9 of its diagonal, 5.4 mm) merged 3999 of the 4000
    points; the box of the 1st-99th percentiles does not see the junk row."""
    g = np.arange(60) * 0.002
    x, y = np.meshgrid(g, g)
    part = np.c_[x.ravel() + 500000.0, y.ravel() + 5400000.0, np.full(x.size, 120.0)]
    groups = coincident_groups(np.vstack([part, [0.0, 0.0, 0.0]]))
    assert groups.n_merged == 0 and groups.tolerance < 1e-6


def test_the_duplicate_tolerance_does_not_turn_with_the_points():
    """Before: copies merged at 2.83e-9 in the input's frame were refused as copies at 4.15e-9
    in the frame a method runs in, with advice to merge what had just been merged."""
    from scipy.spatial.transform import Rotation

    from parambench.datasets_gen.surface import duplicate_tolerance

    rng = np.random.default_rng(4)
    pts = make_surface("bump", 3000, sampling="jittered", seed=0).points
    n = len(pts)
    turned = pts @ Rotation.from_euler("xyz", [20, 35, 50], degrees=True).as_matrix().T
    assert duplicate_tolerance(turned) == pytest.approx(duplicate_tolerance(pts), rel=1e-9)
    # Copies just inside the tolerance, turned off the axes: merged once, never refused after.
    tol = duplicate_tolerance(turned)
    step = rng.normal(size=(1500, 3))
    copies = turned[:1500] + 0.9 * tol * step / np.linalg.norm(step, axis=1, keepdims=True)
    with pytest.warns(CoincidentPointsWarning, match=f"1500 of {n + 1500} points coincide"):
        result = get_method("ocp")(Surface(np.vstack([turned, copies]), name="copies"))
    assert result.diagnostics["selfcheck"]["passed"]
    np.testing.assert_array_equal(result.uv[n:], result.uv[:1500])
