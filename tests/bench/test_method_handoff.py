"""What a sweep cell hands its method (no ground truth) and what the command line does with copies."""

from __future__ import annotations

import numpy as np

from parambench.methods.pose import surface_pose
import pytest

from parambench.bench.cells import Cell
from parambench.bench.cli import main
from parambench.bench.run_cell import compute_cell, surface_for
from parambench.datasets_gen.surface import MethodInput
from parambench.methods import Method, Parameterization
from parambench.methods.registry import register, _REGISTRY


class _PointSpy(Method):
    """Records the surface ``run`` is given; maps to the xy coordinates (the test surfaces are graphs)."""

    name = "spy-handoff-points"
    needs_faces = False
    seen: list = []

    def run(self, surface, **params):
        type(self).seen.append(surface)
        return Parameterization(uv=surface.points[:, :2].copy(), method=self.name)


class _MeshSpy(_PointSpy):
    name = "spy-handoff-mesh"
    needs_faces = True
    seen: list = []


@pytest.fixture
def spies():
    for cls in (_PointSpy, _MeshSpy):
        cls.seen = []
        register(cls)
    yield _PointSpy, _MeshSpy
    for cls in (_PointSpy, _MeshSpy):
        _REGISTRY.pop(cls.name, None)


GROUND_TRUTH = ("exact_uv", "exact_map_kind", "boundary_mask", "params", "seed")


def _no_ground_truth(given):
    """A MethodInput: no ground-truth attribute at all, and no loops (the cell did not ask)."""
    return (isinstance(given, MethodInput) and given.boundary_loops is None
            and not any(hasattr(given, key) for key in GROUND_TRUTH))


@pytest.mark.parametrize("noise", [0.0, 0.2])
def test_generated_surface_reaches_methods_without_ground_truth(spies, noise):
    point_spy, mesh_spy = spies
    truth = surface_for("cap", 600, "jittered", noise, 0)
    assert truth.normals is not None and truth.exact_uv is not None and truth.boundary_loops is not None
    for spy in spies:
        row, _ = compute_cell(Cell("cap", 600, "jittered", noise, 0, spy.name))
        # "suspect": the xy projection of the noisy cap folds at its steep rim (self-check).
        assert row["status"] in ("ok", "suspect"), row["error"]
        (given,) = spy.seen
        assert _no_ground_truth(given) and given.normals is None
        # methods see the centred, unit-size principal-frame copy of the points (parambench.methods.pose)
        np.testing.assert_allclose(given.points, surface_pose(truth.points).to_unit(truth.points), atol=1e-12)
    assert point_spy.seen[0].faces is None
    np.testing.assert_array_equal(mesh_spy.seen[0].faces, truth.faces)
    # evaluation still gets the ground truth: the exact-map error is measured
    assert row["exact_error"] is not None and row["eval_mesh"] == "ground-truth"


def test_file_normals_are_data_until_noise_moves_the_points(spies):
    from parambench.bench.run_cell import _method_input
    from parambench.datasets_gen.registry import make_surface

    point_spy, _ = spies
    truth = surface_for("real/chameleon", 0, "", 0.0, 0)
    assert truth.params["normals"] == "file"
    compute_cell(Cell("real/chameleon", 0, "", 0.0, 0, point_spy.name))
    (given,) = point_spy.seen
    # as `flatten` would pass them, turned into the unit pose's frame (parambench.methods.pose)
    np.testing.assert_allclose(given.normals, truth.normals @ surface_pose(truth.points).rotation.T, atol=1e-12)
    assert _no_ground_truth(given)
    # once noise has moved the points, the file's normals describe the clean surface: withheld
    noisy = make_surface("real/chameleon", seed=0, noise=0.5)
    assert noisy.normals is not None and _method_input(noisy, needs_faces=False).normals is None


def test_flatten_merges_copies_with_one_line_and_writes_every_row(tmp_path, capsys):
    from parambench.datasets_gen.registry import make_surface

    base = make_surface("bump", 800, sampling="jittered", seed=0).points
    rng = np.random.default_rng(1)
    copies = np.sort(rng.choice(len(base), len(base) // 20, replace=False))
    points = np.insert(base, copies + 1, base[copies], axis=0)  # each copy right after its original
    src = tmp_path / "scan.xyz"
    np.savetxt(src, points, fmt="%.17g")
    out = tmp_path / "uv.csv"
    assert main(["flatten", str(src), "--method", "sdp", "-o", str(out)]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "CoincidentPointsWarning" in err[0] and f" {len(copies)} of {len(points)} " in err[0]
    uv = np.loadtxt(out, delimiter=",", skiprows=1)
    assert uv.shape == (len(points), 2)
    is_copy = np.zeros(len(points), dtype=bool)
    is_copy[copies + np.arange(1, len(copies) + 1)] = True  # where np.insert put them
    np.testing.assert_array_equal(uv[is_copy], uv[np.flatnonzero(is_copy) - 1])


def test_inspect_merges_copies_as_flatten_does_and_reports_input_indices(tmp_path, capsys):
    # Before: inspect refused the copies (DuplicatePointsError) that flatten merges.
    import json

    from parambench.datasets_gen.registry import make_surface

    base = make_surface("bump", 800, sampling="jittered", seed=0).points
    copies = np.arange(0, len(base), 37)
    points = np.insert(base, copies + 1, base[copies], axis=0)
    src, out = tmp_path / "scan.xyz", tmp_path / "scan.json"
    np.savetxt(src, points, fmt="%.17g")
    assert main(["inspect", str(src), "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert "CoincidentPointsWarning" in err and f" {len(copies)} of {len(points)} " in err
    report = json.loads(out.read_text())
    assert report["n_points"] == len(points) and report["n_coincident_merged"] == len(copies)
    np.savetxt(tmp_path / "plain.xyz", base, fmt="%.17g")
    assert main(["inspect", str(tmp_path / "plain.xyz"), "-o", str(tmp_path / "plain.json")]) == 0
    plain = json.loads((tmp_path / "plain.json").read_text())
    # the same loops, in the input numbering of each file: index i of base is i + (copies before it)
    shift = np.searchsorted(copies, np.arange(len(base)), side="left")
    expected = [sorted((np.asarray(loop) + shift[loop]).tolist()) for loop in plain["boundary_loops"]]
    assert [sorted(loop) for loop in report["boundary_loops"]] == expected


def test_warm_up_runs_each_built_in_method_once_per_process_and_never_a_plugin(spies):
    """The first cell of a method was timed with its kernels' compilation or cache load."""
    from parambench.bench.run_cell import warm_up

    point_spy, _ = spies
    params = {"weights": "hybrid"}
    first = warm_up("scp", params)
    assert first > 0.0 and warm_up("scp", params) == 0.0
    assert warm_up("scp", {"weights": "uniform"}) > 0.0  # a variant takes other paths
    assert warm_up(point_spy.name) == 0.0 and point_spy.seen == []
