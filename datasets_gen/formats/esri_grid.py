"""ESRI ASCII grids (``.asc``), the raster text format GIS tools export elevation models in.

A header of ``key value`` lines (``ncols``, ``nrows``, ``xllcorner`` or ``xllcenter``,
``yllcorner`` or ``yllcenter``, ``cellsize`` or GDAL's ``dx`` and ``dy``, optional
``nodata_value``; any order, any case), then ``nrows`` rows of ``ncols`` heights, the
northernmost row first. Each cell with data becomes the point at its centre, in the file's
order (row by row from the north, west to east), so output row i is the i-th cell with data;
cells holding the no-data value (or NaN) are left out. A ``.asc`` file without such a header
is XYZ text (:func:`~parambench.datasets_gen.formats.xyz.read_xyz`), as other tools also use
that name for point clouds.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ._common import RawMesh, Tokens, file_error, show, text_of
from .xyz import read_xyz

__all__ = ["read_asc"]

_SIZE_KEYS = ("ncols", "nrows")
_KEYS = {"ncols", "nrows", "xllcorner", "xllcenter", "yllcorner", "yllcenter", "cellsize", "dx", "dy",
         "nodata_value"}


def read_asc(path: Path, data: bytes) -> RawMesh:
    """Parse an ESRI ASCII grid, or XYZ text when the file has no grid header.

    Parameters
    ----------
    path : pathlib.Path
        For messages.
    data : bytes
        The file's contents.

    Returns
    -------
    RawMesh
        Points (K, 3) float64: x, y of each data cell's centre (in the header's units) and
        its height; no faces, no normals.

    Raises
    ------
    InputFileError
        A header without ``ncols``, ``nrows``, the lower-left corner or the cell size, a
        repeated or non-numeric header value, a count of heights other than
        ``ncols * nrows``, a height that is not a number, or no cell with data.
    """
    text = text_of(data)
    words = text.split(maxsplit=1)
    if not words or words[0].lower() not in {k.encode() for k in _SIZE_KEYS}:
        return read_xyz(path, data)
    t = Tokens(path, text)
    header, n_header = _header(t)
    ncols, nrows = (_whole(t, header, key) for key in _SIZE_KEYS)
    dx, dy = _cell_size(t, header)
    x0, y0 = (_corner(t, header, axis, size) for axis, size in (("x", dx), ("y", dy)))
    first = int(t.first[n_header]) if n_header < t.n_lines else len(t.tok)
    n_values = len(t.tok) - first
    if n_values != ncols * nrows:
        raise file_error(path, None, f"{n_values} height(s) after the header, but ncols x nrows is "
                         f"{ncols} x {nrows} = {ncols * nrows}", "fix ncols / nrows or the rows")
    heights = t.numbers(np.arange(first, len(t.tok)), "height", finite=False).reshape(nrows, ncols)
    has_data = np.isfinite(heights)
    if "nodata_value" in header:
        has_data &= heights != header["nodata_value"][0]
    if not has_data.any():
        raise file_error(path, None, "every cell holds the no-data value", "pass a grid with heights")
    row, col = np.nonzero(has_data)  # row-major: the file's order
    x = x0 + (col + 0.5) * dx
    y = y0 + (nrows - 1 - row + 0.5) * dy
    return RawMesh(points=np.column_stack([x, y, heights[row, col]]).astype(np.float64))


def _header(t: Tokens) -> tuple[dict, int]:
    """``{key: (value, line index)}`` of the leading ``key value`` lines, and how many there are."""
    header: dict = {}
    n = 0
    while n < t.n_lines:
        key = t.tok[int(t.first[n])].lower().decode("ascii", "replace")
        if key not in _KEYS:
            break
        if t.count[n] != 2:
            raise t.line_error(n, f"header line {key!r} with {int(t.count[n]) - 1} value(s)",
                               "give each header key one value")
        if key in header:
            raise t.line_error(n, f"a second {key!r}", "give each header key once")
        header[key] = (float(t.numbers(np.array([t.first[n] + 1]), f"{key} value", finite=True)[0]), n)
        n += 1
    return header, n


def _whole(t: Tokens, header: dict, key: str) -> int:
    if key not in header:
        raise file_error(t.path, None, f"an ESRI grid header without {key!r}", "add it to the header")
    value, line = header[key]
    if value != int(value) or value < 1:
        raise t.line_error(line, f"{key} {value:g} is not a positive whole number", "fix the header")
    return int(value)


def _cell_size(t: Tokens, header: dict) -> tuple[float, float]:
    if "cellsize" in header:
        sizes = (header["cellsize"],) * 2
    elif "dx" in header and "dy" in header:
        sizes = (header["dx"], header["dy"])
    else:
        raise file_error(t.path, None, "an ESRI grid header without 'cellsize' (or 'dx' and 'dy')",
                         "add the cell size to the header")
    for value, line in sizes:
        if not value > 0:
            raise t.line_error(line, f"a cell size of {value:g}", "give a positive cell size")
    return sizes[0][0], sizes[1][0]


def _corner(t: Tokens, header: dict, axis: str, size: float) -> float:
    """The outer edge of the grid's lower-left cell along ``axis`` (a centre is moved by half a cell)."""
    corner, centre = header.get(f"{axis}llcorner"), header.get(f"{axis}llcenter")
    if (corner is None) == (centre is None):
        what = "both" if corner is not None else "neither of"
        raise file_error(t.path, None, f"an ESRI grid header with {what} {show((axis + 'llcorner').encode())} "
                         f"and {show((axis + 'llcenter').encode())}", "give exactly one of them")
    return corner[0] if corner is not None else centre[0] - 0.5 * size
