"""The triangles of neighbouring points keep their orientation under a fold-free map."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from parambench.bench.metrics import evaluate
from parambench.datasets_gen.registry import make_surface
from parambench.datasets_gen.surface import MethodInput
from parambench.methods.pointset.ring_orientation import ring_orientation, unresolved_points
from parambench.methods.registry import get_method


def _plane(n=600, seed=3):
    rng = np.random.default_rng(seed)
    xy = rng.uniform(0.0, 1.0, (n, 2))
    points = np.c_[xy, np.zeros(n)]
    normals = np.tile([0.0, 0.0, 1.0], (n, 1))
    _, idx = cKDTree(points).query(points, k=9)
    knn = idx[:, 1:].astype(np.int64)
    spacing = np.linalg.norm(points[knn] - points[:, None], axis=-1).mean(axis=1)
    return points, normals, knn, spacing


def _rings(points, uv, normals, knn, spacing, mirrored=False):
    return ring_orientation(points, uv, normals, knn, [], spacing, tol_deg=1.0, mirrored=mirrored,
                            min_uv_area=1e-14, bridge_factor=4.0)


@pytest.mark.parametrize("matrix", [[[2.0, 0.3], [0.0, 0.5]], [[0.0, -1.0], [1.0, 0.0]], [[5.0, 4.0], [1.0, 1.0]]])
def test_an_affine_map_reverses_no_ring_triangle(matrix):
    points, normals, knn, spacing = _plane()
    uv = points[:, :2] @ np.asarray(matrix).T
    facts, flipped = _rings(points, uv, normals, knn, spacing)
    assert facts["n_ring_flipped"] == 0 and flipped.shape == (0, 3)
    assert facts["n_ring_judged"] > 2 * len(points)  # most of each one-ring is well shaped


def test_a_mirror_image_reverses_every_judged_triangle_unless_it_is_called_a_mirror():
    points, normals, knn, spacing = _plane()
    uv = points[:, :2] * [1.0, -1.0]
    assert _rings(points, uv, normals, knn, spacing, mirrored=True)[0]["n_ring_flipped"] == 0
    facts, flipped = _rings(points, uv, normals, knn, spacing, mirrored=False)
    # Each triangle is judged from up to three centres and counted once.
    assert facts["n_ring_judged"] / 3 <= facts["n_ring_flipped"] <= facts["n_ring_judged"]
    assert len(np.unique(np.sort(flipped, axis=1), axis=0)) == len(flipped)


def test_a_point_pushed_across_its_neighbour_is_found():
    points, normals, knn, spacing = _plane()
    i = int(np.argmin(np.linalg.norm(points[:, :2] - 0.5, axis=1)))
    j = knn[i, 0]
    uv = points[:, :2].copy()
    uv[i] = uv[i] + 1.6 * (uv[j] - uv[i])  # beyond its nearest neighbour: a local fold
    facts, flipped = _rings(points, uv, normals, knn, spacing)
    assert facts["n_ring_flipped"] > 0
    assert np.all(np.any(flipped == i, axis=1))  # every reversed triangle has the moved point


def test_triangles_whose_corner_normals_disagree_are_not_judged():
    # Where the normals turn by more than 60 degrees the points do not resolve the surface:
    # neither the triangle's sign nor the map's is known, so no verdict.
    points, normals, knn, spacing = _plane()
    i = int(np.argmin(np.linalg.norm(points[:, :2] - 0.5, axis=1)))
    uv = points[:, :2].copy()
    uv[i] = uv[i] + 1.6 * (uv[knn[i, 0]] - uv[i])
    normals = normals.copy()
    normals[i] = [1.0, 0.0, 0.0]
    facts, _ = _rings(points, uv, normals, knn, spacing)
    assert facts["n_ring_flipped"] == 0


def test_ocp_on_a_graded_plane_has_no_fold_the_uv_triangulation_hides():
    # Found on a graded plane: 8 neighbours pulled a boundary point into a spike; the true
    # mesh folded one triangle beside it while every uv Delaunay triangle kept its sign.
    surf = make_surface("plane", 2000, sampling="graded", seed=1)
    first = get_method("ocp")(MethodInput(surf.points), refine="none", retry_k_nn=0)
    check = first.diagnostics["selfcheck"]
    assert evaluate(surf.points, surf.faces, first.uv)["foldovers"] >= 1
    assert check["n_flipped"] == 0 and check["n_ring_flipped"] >= 1 and not check["passed"]
    assert "neighbouring points reversed" in check["reason"]
    # The default run retries on the failed check; a plane's conformal map is a similarity.
    final = get_method("ocp")(MethodInput(surf.points))
    metrics = evaluate(surf.points, surf.faces, final.uv)
    assert final.diagnostics["selfcheck"]["passed"]
    assert metrics["foldovers"] == 0 and metrics["qc_mean"] < 1.001


def test_unresolved_points_are_those_beside_a_normal_that_turns_away():
    points, normals, knn, _ = _plane()
    assert not unresolved_points(normals, knn).any()
    i = 17
    tilted = normals.copy()
    tilted[i] = [np.sin(np.radians(70.0)), 0.0, np.cos(np.radians(70.0))]
    mask = unresolved_points(tilted, knn)
    assert mask[i] and set(np.flatnonzero(mask)) == {i} | set(np.flatnonzero((knn == i).any(axis=1)))
    tilted[i] = [np.sin(np.radians(50.0)), 0.0, np.cos(np.radians(50.0))]  # within 60 degrees
    assert not unresolved_points(tilted, knn).any()
