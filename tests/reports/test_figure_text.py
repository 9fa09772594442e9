"""Readable figures: no text on top of other text at the full method list, one k axis, ~20 checks across."""

import numpy as np
import pytest

from parambench.methods.registry import all_methods
from parambench.reports.figures import (LandscapeCurve, LayoutPanel, checkerboard_figure, landscape_figure,
                             uv_layout_figure)
from parambench.reports.figures._common import figure_to_picture, new_figure, overlapping_texts
from parambench.reports.figures.checkerboard import CHECKS_ACROSS, checks_for_size
from parambench.reports.figures.landscape import split_by_scale
from parambench.reports.load import CellArrays


def full_method_list():
    """Every registered method plus the quick suite's extra variants and a long parameter label."""
    names = sorted(all_methods())
    return names + ["ocp [energy=paper]", "sdp [b_orthonormal=False]",
                    "scp [b_matrix=mass, normalized=True, weights=mean-value]"]


@pytest.fixture(scope="module")
def cell(mesh_tools):
    points, faces, loop = mesh_tools["grid_mesh"](14, "bump")
    uv = mesh_tools["method_uv"]("ocp", points, 14, 0)
    return CellArrays(points, faces, uv, mesh_tools["per_face_qc"](points, faces, uv),
                      mesh_tools["flipped_mask"](faces, uv), [loop], [loop])


def test_the_overlap_check_finds_overlapping_text():
    fig = new_figure(3, 2)
    ax = fig.subplots()
    ax.set_title("a long title that runs on")
    ax.text(0.5, 1.02, "sits on the title", transform=ax.transAxes, ha="center")
    picture = figure_to_picture(fig, "t")
    assert {frozenset(pair) for pair in picture.text_overlaps} == {frozenset(("a long title that runs on",
                                                                              "sits on the title"))}
    fig = new_figure(3, 2)
    fig.subplots().set_title("alone")
    assert overlapping_texts(fig) == []


def test_uv_layouts_and_checkerboards_of_every_method_have_no_overlapping_text(cell):
    labels = full_method_list()
    assert len(labels) >= 17
    layouts = uv_layout_figure([LayoutPanel(label, cell, 1.0123, 12.0) for label in labels], "bump · 2000 pts")
    assert layouts.text_overlaps == []
    assert layouts.rows == int(np.ceil(len(labels) / 8))
    assert set(layouts.panels) == set(labels)  # every panel located for the detail view
    for left, top, right, bottom in layouts.panels.values():
        assert 0 <= left < right <= 1 and 0 <= top < bottom <= 1
    checks = checkerboard_figure([(label, cell) for label in labels], "bump · 2000 pts")
    assert checks.text_overlaps == []
    assert set(checks.panels) == set(labels)


def test_landscape_puts_far_k_on_its_own_panel_without_overlaps(mesh_tools):
    curves = []
    for label, k_opt in (("ocp", 1.009), ("dncp-opt", 0.9999), ("scp-rl", 1.13), ("ocp [energy=paper]", 28.9)):
        k, energy, t = mesh_tools["landscape"](k_opt)
        curves.append(LandscapeCurve(label, k, energy, t, k_opt))
    groups = split_by_scale(curves)
    assert [[c.label for c in g] for g in groups] == [["ocp", "dncp-opt", "scp-rl"], ["ocp [energy=paper]"]]
    picture = landscape_figure(curves, "saddle · 2000 pts · jittered (seed 0)")
    assert picture.text_overlaps == []  # the k_opt labels near k = 1 used to collide
    assert "separate panels" in picture.caption


def test_one_group_when_k_are_close(mesh_tools):
    k, energy, t = mesh_tools["landscape"](1.0)
    curves = [LandscapeCurve("a", k, energy, t, 1.0), LandscapeCurve("b", k, energy, t, 2.5),
              LandscapeCurve("no k", k, energy, t)]
    assert [[c.label for c in g] for g in split_by_scale(curves)] == [["a", "b", "no k"]]


def test_checks_across_follow_the_size():
    assert checks_for_size(2000) == CHECKS_ACROSS == 20
    assert checks_for_size(1_000_000) == 20
    assert checks_for_size(144) == 6
    assert checks_for_size(400) == 10
