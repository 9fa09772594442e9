"""Fixtures for command-line and sweep tests."""

from __future__ import annotations

from pathlib import Path

import pytest

from parambench.datasets_gen.real import real_data_dir


@pytest.fixture
def real_dir() -> Path:
    """The folder of the real meshes shipped with the package (or ``$PARAMBENCH_REAL_DATA``)."""
    folder = real_data_dir()
    if not (folder / "camelhead.off").exists():
        pytest.fail(f"real meshes not found in {folder}; they ship in datasets_gen/data/real/")
    return folder.resolve()


def _write_obj(path: Path, points, faces=None) -> Path:
    lines = [f"v {float(x)!r} {float(y)!r} {float(z)!r}" for x, y, z in points]
    if faces is not None:
        lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces]
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.fixture
def write_obj():
    """A minimal OBJ writer for test inputs: ``write_obj(path, points, faces=None)``."""
    return _write_obj
