"""Loop subdivision of a real mesh: counts, boundary and shape as the scheme gives them."""

from __future__ import annotations

import igl
import numpy as np
import pytest

from parambench.datasets_gen.errors import InvalidInputError
from parambench.datasets_gen.registry import make_surface
from parambench.datasets_gen.subdivide import loop_subdivided


@pytest.fixture(scope="module")
def lilium():
    return make_surface("real/lilium")


def test_every_edge_is_split_each_round(lilium):
    once = loop_subdivided(lilium, 1)
    n_edges = len(igl.edges(lilium.faces))
    assert once.n_points == lilium.n_points + n_edges
    assert len(once.faces) == 4 * len(lilium.faces)
    twice = loop_subdivided(lilium, 2)
    assert len(twice.faces) == 16 * len(lilium.faces) and twice.params["subdivision"] == 2
    # The one boundary loop stays one loop, with every boundary edge split.
    for refined, rounds in ((once, 1), (twice, 2)):
        assert len(refined.boundary_loops) == 1
        assert refined.boundary_loops[0].size == 2 ** rounds * lilium.boundary_loops[0].size
        assert refined.boundary_mask.sum() == refined.boundary_loops[0].size


def test_the_shape_is_kept(lilium):
    """Loop subdivision moves the old vertices by a local average: the refined vertices stay
    within a fraction of an edge of the original surface."""
    refined = loop_subdivided(lilium, 2)
    distance = np.sqrt(igl.point_mesh_squared_distance(refined.points, lilium.points, lilium.faces)[0])
    edge = igl.avg_edge_length(lilium.points, lilium.faces)
    assert np.quantile(distance, 0.99) < 0.3 * edge


@pytest.mark.parametrize("bad", [0, -1, 1.5, True])
def test_bad_rounds_and_point_sets_are_refused(lilium, bad):
    with pytest.raises(InvalidInputError, match="whole number"):
        loop_subdivided(lilium, bad)
    with pytest.raises(InvalidInputError, match="needs a mesh"):
        loop_subdivided(lilium.points_only(), 1)
