"""The hole-vs-sampling-gap diagnostic of bench/boundary_separability.py, on small generated surfaces."""

import numpy as np
import pytest

from parambench.bench import boundary_separability as sep
from parambench.datasets_gen.registry import make_surface
from parambench.methods.pointset.frontend import build_frontend


@pytest.fixture(scope="module")
def jittered():
    s = make_surface("holes", 2000, sampling="jittered", seed=0)
    return s, build_frontend(s.points).normals


def test_triangles_over_holes_are_no_faces_and_lie_on_one_loop(jittered):
    s, normals = jittered
    tri = sep.ring_triangles(s.points, normals)
    over = sep.hole_triangles(tri, s.faces, s.boundary_loops)
    faces = {tuple(f) for f in np.sort(s.faces, axis=1).tolist()}
    for j in range(1, len(s.boundary_loops)):  # every hole is spanned by one-ring triangles
        mine = tri[over == j]
        assert len(mine) > 0
        assert np.isin(mine, np.asarray(s.boundary_loops[j])).all()
        assert not any(tuple(t) in faces for t in mine.tolist())


def test_on_a_regular_sampling_every_hole_stands_out_from_every_gap(jittered):
    s, normals = jittered
    out = sep.empty_clusters(s.points, normals, s.faces, s.boundary_loops, 1.0)
    assert all(n > 0 for n, _ in out["holes"][1:])
    assert out["gaps_larger"][1:] == [0] * (len(s.boundary_loops) - 1)
    assert out["largest_gap"] == [0, 0.0]


def test_random_sampling_is_less_regular_than_jittered(jittered):
    s, _ = jittered
    rnd = make_surface("holes", 2000, sampling="random", seed=0)
    q_jit, q_rnd = sep.face_regularity(s.points, s.faces), sep.face_regularity(rnd.points, rnd.faces)
    assert q_jit["q99"] < 0.8 < 1.2 < q_rnd["q99"]


def test_interior_spacing_near_the_boundary_is_not_overstated(jittered):
    s, _ = jittered
    plain, fixed = sep.spacing_around(s.points), sep.spacing_around(s.points, s.boundary_mask)
    assert np.median(fixed[s.boundary_mask]) < np.median(plain[s.boundary_mask])
    assert np.mean(plain == fixed) > 0.7  # only points on or next to the boundary change (13 % on it)
