"""Boundary loops of a square lattice from its rebuilt cells:
:mod:`parambench.methods.pointset.lattice_loops` and its use in the front end."""

import numpy as np
import pytest

from parambench.bench.metrics import evaluate
from parambench.datasets_gen.elevation import matplotlib_dem, raster_surface
from parambench.datasets_gen.registry import make_surface
from parambench.methods.pointset.frontend import build_frontend
from parambench.methods.pointset.lattice_loops import lattice_cells, lattice_loops
from parambench.methods.registry import get_method


def _same_cycle(found: np.ndarray, truth: np.ndarray) -> bool:
    """Whether ``found`` runs through ``truth``'s points in the same cyclic order and direction."""
    if len(found) != len(truth) or set(found.tolist()) != set(truth.tolist()):
        return False
    start = int(np.flatnonzero(truth == found[0])[0])
    return bool(np.array_equal(np.roll(truth, -start), found))


def _normals_up(points: np.ndarray) -> np.ndarray:
    return np.tile([0.0, 0.0, 1.0], (len(points), 1))


def _knn(points: np.ndarray, k: int = 8) -> np.ndarray:
    from scipy.spatial import cKDTree

    return cKDTree(points).query(points, k=k + 1)[1][:, 1:]


@pytest.mark.parametrize("step", [1, 2, 3])
def test_a_ragged_coast_gets_its_raster_meshs_loops(step):
    """matplotlib's topobathy land: a coast with inlets one cell wide (and at every second
    sample a one-cell hole). The rebuilt cells' loops are the raster mesh's, point for
    point and in the same direction."""
    surface = matplotlib_dem("topobathy", step, 0.0)
    loops = lattice_loops(surface.points, _normals_up(surface.points), _knn(surface.points))
    assert loops is not None and len(loops) == len(surface.boundary_loops)
    for truth in surface.boundary_loops:
        assert any(_same_cycle(found, truth) for found in loops)


def test_cells_of_a_full_raster_are_its_cells():
    y, x = np.mgrid[0:6, 0:9].astype(float)
    z = 0.3 * np.sin(x) * np.cos(y / 2)
    keep = np.ones_like(x, dtype=bool)
    keep[2, 3] = False  # one missing sample: a hole of 4 half cells' rims
    surface = raster_surface(x, y, z, keep, "patch")
    faces, is_half = lattice_cells(surface.points, _normals_up(surface.points), _knn(surface.points))
    assert faces.shape[0] == surface.faces.shape[0]  # 8 x 5 cells, 4 of them halves
    assert is_half.sum() == 4
    loops = lattice_loops(surface.points, _normals_up(surface.points), _knn(surface.points))
    assert sorted(len(loop) for loop in loops) == [4, 26]


@pytest.mark.parametrize("sampling", ["jittered", "random", "grid"])
def test_no_cells_without_a_square_lattice(sampling):
    """Irregular samplings give no clean surface of cells, and the generated grid samplings
    are triangular lattices (6 neighbours within axis reach), whose cells are not looked
    for: the angle criterion stands."""
    surface = make_surface("bump", 2000, sampling=sampling, seed=0)
    assert lattice_loops(surface.points, surface.normals, _knn(surface.points)) is None
    fe = build_frontend(surface.points)
    assert fe.diagnostics["boundary"].get("loops_from") is None


def test_front_end_and_ocp_on_a_coast_the_angle_criterion_missed():
    """topobathy at every second sample (664 points): the angle criterion's walk found the
    coast with 118 of its 139 points and not the one-cell hole, and ``ocp`` stopped with
    NoBoundaryError; with the cells' loops both loops are exact and the map is within 3 %
    of scp-igl's QC on the raster's mesh, with no foldover."""
    surface = matplotlib_dem("topobathy", 2, 0.0)
    fe = build_frontend(surface.points)
    assert fe.diagnostics["boundary"]["loops_from"] == "lattice cells"
    assert fe.diagnostics["boundary"]["n_candidates"] > 0  # the angle criterion's, kept for the self-check
    assert np.array_equal(fe.boundary_mask, surface.boundary_mask)
    result = get_method("ocp")(surface.method_input(False))
    assert result.diagnostics["selfcheck"]["passed"]
    ours = evaluate(surface.points, surface.faces, result.uv, boundary_loops=surface.boundary_loops)
    base = evaluate(surface.points, surface.faces, get_method("scp-igl")(surface).uv,
                    boundary_loops=surface.boundary_loops)
    assert ours["foldovers"] == 0 and ours["qc_mean"] <= 1.03 * base["qc_mean"]


def test_a_sloping_raster_is_read_along_its_view_direction():
    """matplotlib's jacksboro DEM (every fourth sample, hills): in each point's tangent
    plane only half the cells come out, and no clean surface; seen along the mean normal
    they all do, and the front end's loop is the raster mesh's rim."""
    surface = matplotlib_dem("jacksboro", 4)
    fe = build_frontend(surface.points)
    assert fe.diagnostics["boundary"]["loops_from"] == "lattice cells"
    assert np.array_equal(fe.boundary_mask, surface.boundary_mask)
    tangent_only = lattice_cells(fe.points, fe.normals, fe.knn_indices)[0]
    assert len(tangent_only) < 0.9 * len(surface.faces)


def test_lakes_in_a_rough_raster_are_holes():
    """A rectangular raster (steps 0.85 x 1) of rough heights (noise 0.3 steps) cut to the
    land above a level: many lakes, some of a single grid point. The cells give every loop
    of the raster's mesh (here all 12 and no other; elsewhere a tiny extra one can come
    where two cells touch at a corner, which the raster mesher drops), with no point off
    the rim; the angle criterion's walk found 1 of the 12."""
    rng = np.random.default_rng(3)
    y, x = np.mgrid[0:60, 0:70].astype(float)
    x *= 0.85
    z = 3 * np.sin(x / 7) * np.cos(y / 9) + 2 * np.sin((x + y) / 13) + 0.3 * rng.standard_normal(x.shape)
    surface = raster_surface(x, y, z, z > -2.5, "lakes")
    fe = build_frontend(surface.points)
    assert fe.diagnostics["boundary"]["loops_from"] == "lattice cells"
    found, truth = fe.boundary_mask, surface.boundary_mask
    assert (found & ~truth).sum() == 0
    assert (found & truth).sum() >= 0.98 * truth.sum()
    assert len(surface.boundary_loops) <= len(fe.boundary_loops) <= len(surface.boundary_loops) + 3
