"""The uv writers: the same text as numpy.savetxt, chunk boundaries included."""

from __future__ import annotations

import numpy as np
import pytest

from parambench.bench import uv_output
from parambench.bench.uv_output import write_uv


def _savetxt_reference(suffix: str, points: np.ndarray, uv: np.ndarray, faces: np.ndarray) -> str:
    """What the writers produced with np.savetxt (before they formatted whole chunks)."""
    import io

    fh = io.StringIO()
    if suffix == ".obj":
        fh.write("# parambench flattening: one vt per v, in input order\n")
        np.savetxt(fh, points, fmt="v %.17g %.17g %.17g")
        np.savetxt(fh, uv, fmt="vt %.17g %.17g")
        np.savetxt(fh, np.repeat(faces + 1, 2, axis=1), fmt="f %d/%d %d/%d %d/%d")
    elif suffix == ".ply":
        fh.write("ply\nformat ascii 1.0\ncomment parambench flattening: texture_u texture_v per vertex, in input order\n"
                 f"element vertex {points.shape[0]}\nproperty double x\nproperty double y\nproperty double z\n"
                 "property double texture_u\nproperty double texture_v\n"
                 f"element face {faces.shape[0]}\nproperty list uchar int vertex_indices\nend_header\n")
        np.savetxt(fh, np.hstack([points, uv]), fmt="%.17g")
        np.savetxt(fh, faces, fmt="3 %d %d %d")
    else:
        np.savetxt(fh, uv, fmt="%.17g", delimiter=",", header="u,v", comments="")
    return fh.getvalue()


@pytest.mark.parametrize("suffix", [".obj", ".ply", ".csv"])
def test_writers_match_savetxt_across_chunks(suffix, tmp_path, monkeypatch):
    rng = np.random.default_rng(3)
    points = rng.standard_normal((23, 3)) * np.array([1e-300, 1.0, 1e300])
    points[0] = [0.0, -0.0, 1 / 3]
    uv = rng.standard_normal((23, 2))
    faces = rng.integers(0, 23, size=(17, 3)).astype(np.int64)
    monkeypatch.setattr(uv_output, "_ROWS_PER_CHUNK", 5)  # several chunks, the last one short
    out = write_uv(tmp_path / f"out{suffix}", points, uv, faces)
    assert out.read_text() == _savetxt_reference(suffix, points, uv, faces)
