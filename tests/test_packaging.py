"""The project stands on its own: the real meshes ship in the wheel and load from any location.

These tests copy or build the project into temporary folders and load the real datasets in a
fresh interpreter whose working directory and import path hold no ``../shared`` folder, so
they would fail if any code path still reached outside the package for its data.
"""

from __future__ import annotations

import importlib.util
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = ("camelhead.off", "lilium.obj", "bump-domain.obj")
DATA_IN_PACKAGE = "datasets_gen/data/real"

# Loads each shipped dataset and prints where the package was imported from and the counts.
LOAD_SCRIPT = """
import parambench.datasets_gen
from parambench.datasets_gen.registry import make_surface
from parambench.datasets_gen.real import real_data_dir
print(datasets_gen.__file__)
print(real_data_dir())
for name in ("real/camelhead", "real/lilium", "real/bump-domain"):
    s = make_surface(name)
    print(name, s.n_points, len(s.faces), len(s.boundary_loops))
"""

EXPECTED_COUNTS = {"real/camelhead": (11381, 22704), "real/lilium": (3389, 6590), "real/bump-domain": (4172, 8058)}


def _clean_env(pythonpath: Path) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in ("PARAMBENCH_REAL_DATA", "PYTHONPATH")}
    env["PYTHONPATH"] = str(pythonpath)
    return env


def _load_in_subprocess(pythonpath: Path, cwd: Path) -> list[str]:
    done = subprocess.run([sys.executable, "-c", LOAD_SCRIPT], cwd=cwd, env=_clean_env(pythonpath),
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    return done.stdout.splitlines()


def _check_loaded(lines: list[str], tree: Path) -> None:
    module_file, data_dir, *rows = lines
    # The interpreter must have imported the copy, not the project this test runs from.
    assert Path(module_file).resolve().is_relative_to(tree.resolve())
    assert Path(data_dir).resolve() == (tree / DATA_IN_PACKAGE).resolve()
    loaded = {row.split()[0]: tuple(int(x) for x in row.split()[1:]) for row in rows}
    assert loaded == {name: (*counts, 1) for name, counts in EXPECTED_COUNTS.items()}


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    """Build the project's wheel once (build isolation fetches setuptools>=77 when needed)."""
    out = tmp_path_factory.mktemp("wheel")
    cmd = [sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(out), str(ROOT)]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    (whl,) = out.glob("parambench-*.whl")
    return whl


@pytest.mark.slow
def test_wheel_ships_the_real_meshes_their_sources_and_the_licence(wheel):
    names = set(zipfile.ZipFile(wheel).namelist())
    for filename in (*SHIPPED, "SOURCES.md"):
        assert f"{DATA_IN_PACKAGE}/{filename}" in names
    assert any(n.endswith(".dist-info/licenses/LICENSE") for n in names)
    # Byte-for-byte the files of the source tree, so the wheel loads the same meshes.
    with zipfile.ZipFile(wheel) as zf:
        for filename in SHIPPED:
            assert zf.read(f"{DATA_IN_PACKAGE}/{filename}") == (ROOT / DATA_IN_PACKAGE / filename).read_bytes()


@pytest.mark.slow
def test_wheel_metadata_has_spdx_licence(wheel):
    with zipfile.ZipFile(wheel) as zf:
        (meta,) = [n for n in zf.namelist() if n.endswith(".dist-info/METADATA")]
        text = zf.read(meta).decode()
    assert "License-Expression: MIT" in text.splitlines()
    assert "License-File: LICENSE" in text.splitlines()


@pytest.mark.slow
def test_real_datasets_load_from_the_unpacked_wheel(wheel, tmp_path):
    site = tmp_path / "site"
    zipfile.ZipFile(wheel).extractall(site)
    elsewhere = tmp_path / "cwd"
    elsewhere.mkdir()
    _check_loaded(_load_in_subprocess(site, elsewhere), site)


@pytest.mark.slow
def test_real_datasets_load_from_a_copy_of_the_project_without_shared_beside_it(tmp_path):
    copy = tmp_path / "clone" / "parambench"
    shutil.copytree(ROOT, copy, ignore=shutil.ignore_patterns(".venv", ".git", "__pycache__", "*.egg-info",
                                                              "build", "dist", ".pytest_cache", ".benchmarks"))
    assert not (copy.parent / "shared").exists()
    elsewhere = tmp_path / "cwd"
    elsewhere.mkdir()
    _check_loaded(_load_in_subprocess(copy, elsewhere), copy)


def test_sources_file_credits_every_shipped_mesh():
    text = (ROOT / DATA_IN_PACKAGE / "SOURCES.md").read_text()
    for filename in SHIPPED:
        assert f"`{filename}`" in text
    assert "libigl-tutorial-data" in text and "Sorkine" in text


def test_project_code_never_reaches_for_a_shared_folder_beside_it():
    # The old layout read ../shared/data/real; any such path left behind breaks a fresh clone.
    offenders = []
    for folder in ("datasets_gen", "methods", "bench", "reports", "tests"):
        for path in (ROOT / folder).rglob("*.py"):
            text = path.read_text(encoding="utf-8")
            if '"shared"' in text or "../shared" in text or "'shared'" in text:
                offenders.append(str(path.relative_to(ROOT)))
    offenders.remove("tests/test_packaging.py")
    assert offenders == []


def test_setuptools_config_lists_only_existing_package_data():
    tomllib = pytest.importorskip("tomllib")
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())
    for package, patterns in config["tool"]["setuptools"]["package-data"].items():
        base = ROOT / package.replace(".", "/")
        assert importlib.util.find_spec(package) is not None
        for pattern in patterns:
            assert list(base.glob(pattern)), f"{package}: {pattern} matches no file"


def test_env_var_still_overrides_the_shipped_folder(tmp_path, monkeypatch):
    from parambench.datasets_gen.real import PACKAGE_DATA_DIR, real_data_dir
    from parambench.datasets_gen.registry import make_surface

    monkeypatch.delenv("PARAMBENCH_REAL_DATA", raising=False)
    assert real_data_dir() == PACKAGE_DATA_DIR == ROOT / DATA_IN_PACKAGE
    # A 4-vertex stand-in, so the count proves which file was read (the shipped one has 3389).
    (tmp_path / "lilium.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0.5\nf 1 2 3\nf 2 4 3\n")
    monkeypatch.setenv("PARAMBENCH_REAL_DATA", str(tmp_path))
    assert real_data_dir() == tmp_path
    assert make_surface("real/lilium").n_points == 4
