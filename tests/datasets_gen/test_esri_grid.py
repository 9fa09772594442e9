"""ESRI ASCII grids (``.asc``): GIS elevation models read as the points at their cell centres.

Before, a ``.asc`` was always read as XYZ text and a grid was refused with "a row with 2
value(s)" at its header.
"""

from __future__ import annotations

import numpy as np
import pytest

from parambench.datasets_gen.errors import InputFileError
from parambench.datasets_gen.formats import read_file
from parambench.methods import get_method
from parambench.datasets_gen.surface import MethodInput

HEADER = "ncols 3\nnrows 2\nxllcorner 100\nyllcorner 200\ncellsize 10\nnodata_value -9999\n"


def _write(tmp_path, text, name="dem.asc"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_cells_become_their_centres_in_file_order_without_no_data(tmp_path):
    raw = read_file(_write(tmp_path, HEADER + "1 2 3\n4 -9999 6\n"))
    # the first row is the northern one: its centres lie at y = 200 + 1.5 * 10
    expected = [[105, 215, 1], [115, 215, 2], [125, 215, 3], [105, 205, 4], [125, 205, 6]]
    np.testing.assert_array_equal(raw.points, expected)
    assert raw.faces is None and raw.normals is None


def test_centre_keys_dx_dy_any_case_and_free_line_breaks(tmp_path):
    text = "NROWS 2\nNCOLS 3\nXLLCENTER 105\nYLLCENTER 205\nDX 10\nDY 20\n1 2\n3 4 5\n6\n"
    raw = read_file(_write(tmp_path, text))
    np.testing.assert_array_equal(raw.points[:, 0], [105, 115, 125, 105, 115, 125])
    np.testing.assert_array_equal(raw.points[:, 1], [225, 225, 225, 205, 205, 205])
    np.testing.assert_array_equal(raw.points[:, 2], [1, 2, 3, 4, 5, 6])


def test_nan_cells_are_no_data_too(tmp_path):
    raw = read_file(_write(tmp_path, HEADER.replace("nodata_value -9999\n", "") + "1 nan 3\n4 5 6\n"))
    assert len(raw.points) == 5 and np.isfinite(raw.points).all()


def test_an_asc_without_a_grid_header_is_still_xyz_text(tmp_path):
    raw = read_file(_write(tmp_path, "0 0 0\n1 0 0\n0 1 0\n"))
    np.testing.assert_array_equal(raw.points, [[0, 0, 0], [1, 0, 0], [0, 1, 0]])


@pytest.mark.parametrize("text, message", [
    (HEADER + "1 2 3\n4 5\n", "5 height(s) after the header, but ncols x nrows is 3 x 2 = 6"),
    (HEADER.replace("cellsize 10\n", "") + "1 2 3\n4 5 6\n", "without 'cellsize'"),
    (HEADER.replace("xllcorner 100\n", "") + "1 2 3\n4 5 6\n", "neither of 'xllcorner' and 'xllcenter'"),
    (HEADER + "xllcenter 105\n1 2 3\n4 5 6\n", "both 'xllcorner' and 'xllcenter'"),
    (HEADER.replace("ncols 3", "ncols 2.5") + "1 2 3\n4 5 6\n", "ncols 2.5 is not a positive whole number"),
    (HEADER.replace("cellsize 10", "cellsize -1") + "1 2 3\n4 5 6\n", "a cell size of -1"),
    (HEADER + "1 2 3\n4 x 6\n", "height 'x' is not a number"),
    (HEADER + "-9999 -9999 -9999\n-9999 -9999 -9999\n", "every cell holds the no-data value"),
    (HEADER + "cellsize 5\n1 2 3\n4 5 6\n", "a second 'cellsize'"),
])
def test_malformed_grids_are_refused_by_name(tmp_path, text, message):
    with pytest.raises(InputFileError, match=message.replace("(", r"\(").replace(")", r"\)")):
        read_file(_write(tmp_path, text))


def test_a_grid_with_a_lake_flattens_to_the_plane_it_is(tmp_path):
    """A flat grid with a no-data lake: ocp must give back the grid itself up to a similarity."""
    rows, cols = 30, 36
    i, j = np.mgrid[0:rows, 0:cols]
    z = np.full((rows, cols), 50.0)
    z[(i - 15) ** 2 + (j - 18) ** 2 < 20] = -9999
    text = (f"ncols {cols}\nnrows {rows}\nxllcorner 500000\nyllcorner 4100000\ncellsize 30\n"
            "nodata_value -9999\n" + "".join(" ".join(f"{v:g}" for v in r) + "\n" for r in z))
    raw = read_file(_write(tmp_path, text))
    assert len(raw.points) == rows * cols - int((z == -9999).sum())
    result = get_method("ocp")(MethodInput(raw.points))
    assert result.diagnostics["selfcheck"]["passed"]
    assert result.diagnostics["selfcheck"]["turning_numbers"] == [1.0, -1.0]  # the outline and the lake
    xy = raw.points[:, :2] - raw.points[:, :2].mean(axis=0)
    uv = result.uv - result.uv.mean(axis=0)
    # best similarity uv -> xy as one complex factor
    zc, wc = uv[:, 0] + 1j * uv[:, 1], xy[:, 0] + 1j * xy[:, 1]
    mirrored = np.abs(np.vdot(zc.conj(), wc)) > np.abs(np.vdot(zc, wc))
    zc = zc.conj() if mirrored else zc
    fit = np.vdot(zc, wc) / np.vdot(zc, zc) * zc
    assert np.sqrt(np.mean(np.abs(fit - wc) ** 2)) < 1e-6 * np.ptp(xy[:, 0])
