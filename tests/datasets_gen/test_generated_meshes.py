"""Every procedural dataset, every sampling: a valid ground-truth mesh with the promised boundary."""

from __future__ import annotations

import numpy as np
import pytest

from parambench.datasets_gen.registry import SAMPLINGS, dataset_names, make_surface
from parambench.datasets_gen.shapes import SHAPES
from parambench.methods.mesh.topology import require_connected_disk_like

PROCEDURAL = [n for n in dataset_names() if not n.startswith("real/")]
N_HOLES = {"holes": 3, "holes-bumped": 3, "slit": 1}


def _planar(surface):
    """The meshing chart (orientation-preserving): the exact map, or the chart of the xy footprint."""
    if surface.exact_uv is not None:
        return surface.exact_uv
    assert np.all(surface.normals[:, 2] > 0), "height fields have normals towards +z"
    return SHAPES[surface.name]().chart(surface.points[:, :2])


def _check_surface(s, helpers, name):
    n = s.n_points
    # one manifold component, every point used, boundary loops as planted
    loops = require_connected_disk_like(s.points, s.faces)
    expected_loops = 1 + N_HOLES.get(name, 0)
    assert len(loops) == expected_loops and len(s.boundary_loops) == expected_loops
    assert sorted(len(lp) for lp in loops) == sorted(len(lp) for lp in s.boundary_loops)
    used = np.zeros(n, bool)
    used[s.faces.ravel()] = True
    assert used.all()
    # Euler characteristic of a disk with k holes: 1 - k
    v, e, f = n, len(helpers.unique_edges(s.faces)), len(s.faces)
    assert v - e + f == 1 - N_HOLES.get(name, 0)
    # faces counter-clockwise in the (orientation-preserving) chart ...
    uv = _planar(s)
    q = uv[s.faces]
    a, b = q[:, 1] - q[:, 0], q[:, 2] - q[:, 0]
    assert np.all(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0] > 0)
    # ... hence seen from the normals' side; coarse random points may put a few triangles
    # across a fingertip whose flat face tilts away from the exact normals
    p = s.points[s.faces]
    fn = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    agree = np.einsum("ij,ij->i", fn, s.normals[s.faces].sum(axis=1)) > 0
    assert agree.all() or (s.params["sampling"] == "random" and agree.mean() > 0.995)
    # loops: outer CCW, holes CW in a faithful flattening; consecutive loop vertices are mesh edges
    areas = [helpers.signed_area(uv[lp]) for lp in s.boundary_loops]
    assert areas[0] > 0 and all(a < 0 for a in areas[1:])
    assert abs(areas[0]) == max(abs(a) for a in areas)
    edges = {tuple(e) for e in helpers.unique_edges(s.faces)}
    for lp in s.boundary_loops:
        assert all(tuple(sorted((a, b))) in edges for a, b in zip(lp, np.roll(lp, -1)))
    # mask matches loops
    mask = np.zeros(n, bool)
    mask[np.concatenate(s.boundary_loops)] = True
    assert np.array_equal(mask, s.boundary_mask)
    # exact unit normals
    assert np.allclose(np.linalg.norm(s.normals, axis=1), 1.0)


@pytest.mark.parametrize("sampling", SAMPLINGS)
@pytest.mark.parametrize("name", PROCEDURAL)
def test_small_surfaces_are_valid(name, sampling, helpers):
    s = make_surface(name, 600, sampling=sampling, seed=1)
    assert s.name == name and s.seed == 1
    assert abs(s.n_points / 600 - 1) < 0.1
    assert s.params["n_points"] == 600 and s.params["sampling"] == sampling and s.params["noise"] == 0.0
    assert s.params["n_actual"] == s.n_points
    _check_surface(s, helpers, name)


@pytest.mark.parametrize("name", PROCEDURAL)
def test_20k_surfaces_are_valid(name, helpers):
    s = make_surface(name, 20000, sampling="blue-noise" if name in ("cap", "protrusions") else "jittered", seed=0)
    assert abs(s.n_points / 20000 - 1) < 0.1
    _check_surface(s, helpers, name)


@pytest.mark.parametrize("name", ["plane", "cap", "protrusions", "holes"])
def test_grid_and_blue_noise_triangles_are_well_shaped(name, helpers):
    """No slivers on the surface, even on the steep fingers (the mesher's chart is conformal)."""
    for sampling in ("grid", "blue-noise"):
        s = make_surface(name, 4000, sampling=sampling, seed=0)
        p = s.points[s.faces]
        angles = []
        for k in range(3):
            u, v = p[:, (k + 1) % 3] - p[:, k], p[:, (k + 2) % 3] - p[:, k]
            cos = np.einsum("ij,ij->i", u, v) / np.linalg.norm(u, axis=1) / np.linalg.norm(v, axis=1)
            angles.append(np.degrees(np.arccos(np.clip(cos, -1, 1))))
        smallest = np.min(angles, axis=0)
        assert smallest.min() > 10.0, (name, sampling, smallest.min())
        assert np.max(angles) < 150.0


def test_protrusions_sampling_is_uniform_on_the_surface(helpers):
    """Fingers carry area in proportion to their surface area, not their footprint."""
    s = make_surface("protrusions", 8000, sampling="grid", seed=0)
    areas = helpers.face_areas(s.points, s.faces)
    # with uniform density, triangle areas are nearly all alike: a footprint-uniform grid
    # would make side triangles ~6x larger than base ones
    assert np.percentile(areas, 95) / np.percentile(areas, 5) < 3.0
    on_fingers = s.points[:, 2] > 0.05
    frac_points = on_fingers.mean()
    frac_area = areas[np.all(on_fingers[s.faces], axis=1)].sum() / areas.sum()
    assert abs(frac_points - frac_area) < 0.05


def test_holes_boundary_loops_are_the_domain_circles():
    s = make_surface("holes", 3000, sampling="grid", seed=0)
    from parambench.datasets_gen.shapes.flat import HOLES

    outer = s.points[s.boundary_loops[0], :2]
    assert np.all(np.isclose(np.abs(outer), 1.0).any(axis=1))  # on the square's sides
    for loop, hole in zip(s.boundary_loops[1:], HOLES):
        r = np.hypot(*(s.points[loop, :2] - hole.center).T)
        assert np.allclose(r, hole.radius)


def test_gnome_strip_is_irregular_only_in_the_strip():
    s = make_surface("gnome-strip", 6000, sampling="grid", seed=0)
    from scipy.spatial import cKDTree

    shape = SHAPES["gnome-strip"]()
    interior = ~s.boundary_mask
    nn = cKDTree(s.points).query(s.points, k=2)[0][:, 1]
    strip = shape.in_strip(s.points[:, :2]) & interior
    far = interior & (np.abs(s.points[:, 0] - 0.2) > 0.3)
    # outside the strip: a lattice (nearest-neighbour distances all alike)
    assert np.std(nn[far]) / np.mean(nn[far]) < 0.1
    # inside: two merged scans, denser and irregular, but no near-duplicates below min_spacing
    assert np.mean(nn[strip]) < 0.85 * np.mean(nn[far])
    assert np.std(nn[strip]) / np.mean(nn[strip]) > 0.15
    assert nn[strip].min() >= 0.3 * np.mean(nn[far])


def test_options_change_the_geometry():
    low = make_surface("bump", 800, sampling="grid", seed=0, h=0.2)
    high = make_surface("bump", 800, sampling="grid", seed=0)
    assert np.isclose(low.points[:, 2].max(), 0.2, atol=0.01) and np.isclose(high.points[:, 2].max(), 0.5, atol=0.03)
    assert low.params["h"] == 0.2 and high.params["h"] == 0.5 and high.params["s"] == 0.3
