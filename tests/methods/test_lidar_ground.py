"""Point-set methods on real LiDAR ground returns: rim and hole found, the map as good as a mesh method's.

The shipped tile (``real/lidar-ground``, laspy's test data) has a hole about 8 spacings
across where vegetation hid the ground. With 12 neighbours the front end once missed it and
the self-check passed the map (the forty-seventh session); now the front end sees the missed
hole and finds it at a lower angle (before the forty-eighth session, the check saw it and the
method ran again at that angle, 10.4 s instead of 3 s).
"""

from __future__ import annotations

import numpy as np
import pytest

from parambench.bench.cli import EXIT_SELFCHECK, main
from parambench.bench.metrics import evaluate
from parambench.datasets_gen.real import REAL_DATASETS
from parambench.datasets_gen.registry import make_surface
from parambench.methods.registry import get_method


@pytest.fixture(scope="module")
def tile():
    return make_surface("real/lidar-ground")


@pytest.fixture(scope="module")
def scp_igl_qc(tile):
    return evaluate(tile.points, tile.faces, get_method("scp-igl")(tile).uv)["qc_mean"]


@pytest.mark.parametrize("params", [{}, {"k_nn": 12}], ids=["default", "k_nn=12"])
def test_ocp_maps_the_bare_returns_with_rim_and_hole(tile, scp_igl_qc, params):
    result = get_method("ocp")(tile.method_input(False), **params)
    check = result.diagnostics["selfcheck"]
    loops = result.diagnostics["boundary_loops"]
    assert check["passed"], check["failed"]
    assert result.diagnostics["boundary_angle_lowered_to"] == 100.0 and "retry" not in check
    assert len(loops) == 2
    true_hole = set(tile.boundary_loops[1].tolist())
    found_hole = min(loops, key=len)
    assert len(true_hole & set(np.asarray(found_hole).tolist())) >= 0.8 * len(true_hole)
    quality = evaluate(tile.points, tile.faces, result.uv)
    assert quality["foldovers"] == 0
    assert quality["qc_mean"] <= 1.01 * scp_igl_qc  # measured 1.0003x (default), 1.0008x (k_nn=12)


def test_flatten_writes_the_shipped_file_with_both_loops(tmp_path, capsys):
    src = REAL_DATASETS["real/lidar-ground"].path()
    out = tmp_path / "ground.obj"
    code = main(["flatten", str(src), "-o", str(out)])
    printed = capsys.readouterr().out
    assert code == 0 and code != EXIT_SELFCHECK
    assert "self-check ok" in printed and "boundary found at 100 degrees" in printed
    lines = out.read_text().splitlines()
    assert sum(line.startswith("vt ") for line in lines) == 9808
    faces = np.array([[int(t.split("/")[0]) - 1 for t in line.split()[1:]] for line in lines if line.startswith("f ")])
    from parambench.bench.metrics.loops import mesh_boundary_loops

    assert len(mesh_boundary_loops(faces)) == 2  # the uv triangulation keeps the hole open
