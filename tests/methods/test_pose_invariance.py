"""Scale and pose do not matter (issue #12 item 4): every registered method, same QC and foldovers.

Before inputs were normalised, default ``ocp`` on a 400-point cap gave QC 2.9 / 6.4 with
5 / 13 foldovers at coordinates x1e-12 / x1e12 (1.03 and none at unit scale), and
``scp-igl`` folded 365 triangles at x1e12; robust-laplacian's peers changed with a rotation.
"""

import numpy as np
import pytest
from dataclasses import replace

from parambench.bench.metrics import evaluate
from parambench.datasets_gen.registry import make_surface
from parambench.methods import get_method, method_names
from parambench.methods.pose import normalised_surface, surface_pose


def _random_rotation(seed: int) -> np.ndarray:
    q, r = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


ROTATION = _random_rotation(7)

#: name -> (points transform, normals transform)
POSES = {
    "x1e-12": (lambda p: p * 1e-12, lambda n: n),
    "x1e12": (lambda p: p * 1e12, lambda n: n),
    "shift1e6": (lambda p: p + 1e6, lambda n: n),
    "rotated": (lambda p: p @ ROTATION.T, lambda n: n @ ROTATION.T),
}


@pytest.fixture(scope="module")
def cap():
    # Random sampling of a curved cap: robust-laplacian's local triangulations flip with
    # rounding on exactly planar patches (e.g. bump's flat rim), which no pose can fix.
    return make_surface("cap", 400, sampling="random", seed=0)


def _posed(surface, pose: str, mesh: bool):
    move_points, move_normals = POSES[pose]
    posed = replace(surface, points=move_points(surface.points), normals=move_normals(surface.normals),
                    exact_uv=None)
    return posed if mesh else posed.points_only()


def _uv_size(uv):
    # RMS radius: unlike a bounding box it ignores where in the plane the map is turned
    return float(np.sqrt(np.mean(np.sum((uv - uv.mean(axis=0)) ** 2, axis=1))))


def _metrics(base, uv):
    # Evaluated on the unmoved ground-truth mesh: QC and foldovers ignore uv scale and reflection.
    return evaluate(base.points, base.faces, uv, boundary_loops=base.boundary_loops)


@pytest.fixture(scope="module")
def reference(cap):
    out = {}
    for name in method_names():
        method = get_method(name)
        result = method(cap if method.needs_faces else cap.points_only())
        out[name] = (result, _metrics(cap, result.uv))
    return out


@pytest.mark.parametrize("pose", sorted(POSES))
@pytest.mark.parametrize("name", method_names())
def test_every_method_ignores_scale_and_pose(cap, reference, name, pose):
    method = get_method(name)
    posed = _posed(cap, pose, method.needs_faces)
    result = method(posed)
    ref_result, ref = reference[name]
    got = _metrics(cap, result.uv)
    assert got["qc_mean"] == pytest.approx(ref["qc_mean"], abs=1e-6)
    assert got["qc_p95"] == pytest.approx(ref["qc_p95"], abs=1e-6)
    assert got["foldovers"] == ref["foldovers"]
    assert got["collapsed"] == ref["collapsed"]
    # uv comes back in the input's units: a 1e12 times larger surface has a 1e12 times larger map.
    factor = {"x1e-12": 1e-12, "x1e12": 1e12}.get(pose, 1.0)
    assert _uv_size(result.uv) == pytest.approx(factor * _uv_size(ref_result.uv), rel=1e-6)


def test_a_faithful_map_keeps_input_lengths():
    # scp on a flat patch is a similarity: the uv edge lengths equal the 3D ones at any scale.
    flat = make_surface("plane", 300, sampling="random", seed=2)
    for factor in (1e-12, 1.0, 1e12):
        surface = replace(flat, points=flat.points * factor, exact_uv=None)
        uv = get_method("lscm-igl")(surface).uv
        i, j = surface.faces[:, 0], surface.faces[:, 1]
        ratio = np.linalg.norm(uv[i] - uv[j], axis=1) / np.linalg.norm(surface.points[i] - surface.points[j], axis=1)
        np.testing.assert_allclose(ratio, 1.0, rtol=1e-6)


def test_normalised_copy_is_centred_unit_and_leaves_the_caller_alone(cap):
    big = replace(cap, points=cap.points * 1e12 + 5e12)
    points_before, normals_before = big.points.copy(), big.normals.copy()
    unit, pose = normalised_surface(big)
    np.testing.assert_array_equal(big.points, points_before)
    np.testing.assert_array_equal(big.normals, normals_before)
    np.testing.assert_allclose(unit.points.mean(axis=0), 0.0, atol=1e-12)
    assert np.sqrt(np.mean(np.sum(unit.points**2, axis=1))) == pytest.approx(1.0, rel=1e-12)
    # principal frame: variances decrease along the axes, the frame is a proper rotation
    variances = unit.points.var(axis=0)
    assert variances[0] >= variances[1] >= variances[2]
    np.testing.assert_allclose(pose.rotation @ pose.rotation.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(pose.rotation) == pytest.approx(1.0)
    # normals turn with the points; faces and loops are the caller's
    np.testing.assert_allclose(unit.normals, big.normals @ pose.rotation.T, atol=1e-15)
    assert unit.faces is big.faces and unit.name == big.name


def test_unit_points_do_not_depend_on_the_input_pose(cap):
    unit, _ = normalised_surface(cap)
    for pose in POSES:
        moved, _ = normalised_surface(_posed(cap, pose, mesh=True))
        np.testing.assert_allclose(moved.points, unit.points, atol=1e-8)


def test_pose_of_huge_and_tiny_coordinates_does_not_overflow():
    points = np.random.default_rng(0).normal(size=(50, 3))
    for factor in (1e-300, 1e300):
        pose = surface_pose(points * factor)
        assert np.isfinite(pose.scale) and pose.scale > 0
        assert pose.scale == pytest.approx(factor * surface_pose(points).scale, rel=1e-12)
