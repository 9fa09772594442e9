"""The project stands on its own: the real meshes ship in the wheel and load from any location.

These tests copy or build the project into temporary folders and load the real datasets in a
fresh interpreter whose working directory and import path hold no ``../shared`` folder, so
they would fail if any code path still reached outside the package for its data.
"""

from __future__ import annotations

import importlib.util
import os
import re
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = ("camelhead.off", "lilium.obj", "bump-domain.obj", "meg-helmet.obj", "spot-top.obj", "cortex-lh.obj",
           "lidar-ground.xyz")
DATA_IN_PACKAGE = "datasets_gen/data/real"  # in the source tree
DATA_IN_WHEEL = f"parambench/{DATA_IN_PACKAGE}"
TOP_FOLDERS = ("methods", "datasets_gen", "bench", "reports")

# Loads each shipped dataset and prints where the package was imported from and the counts.
LOAD_SCRIPT = """
import parambench.datasets_gen
from parambench.datasets_gen.registry import make_surface
from parambench.datasets_gen.real import real_data_dir
print(parambench.datasets_gen.__file__)
print(real_data_dir())
for name in ("real/camelhead", "real/lilium", "real/bump-domain", "real/meg-helmet", "real/spot-top", "real/cortex-lh",
             "real/lidar-ground"):
    s = make_surface(name)
    print(name, s.n_points, len(s.faces), len(s.boundary_loops))
"""

# points, faces, boundary loops (the LiDAR tile: its points and their reference triangulation)
EXPECTED_COUNTS = {"real/camelhead": (11381, 22704, 1), "real/lilium": (3389, 6590, 1),
                   "real/bump-domain": (4172, 8058, 1), "real/meg-helmet": (2044, 3987, 1),
                   "real/spot-top": (2089, 4112, 1), "real/cortex-lh": (12226, 23999, 1),
                   "real/lidar-ground": (9808, 19322, 2)}


def _clean_env(pythonpath: Path) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in ("PARAMBENCH_REAL_DATA", "PYTHONPATH")}
    env["PYTHONPATH"] = str(pythonpath)
    return env


def _load_in_subprocess(pythonpath: Path, cwd: Path) -> list[str]:
    done = subprocess.run([sys.executable, "-c", LOAD_SCRIPT], cwd=cwd, env=_clean_env(pythonpath),
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    return done.stdout.splitlines()


def _check_loaded(lines: list[str], tree: Path, data_dir_expected: Path) -> None:
    module_file, data_dir, *rows = lines
    # The interpreter must have imported the copy, not the project this test runs from.
    assert Path(module_file).resolve().is_relative_to(tree.resolve())
    assert Path(data_dir).resolve() == data_dir_expected.resolve()
    loaded = {row.split()[0]: tuple(int(x) for x in row.split()[1:]) for row in rows}
    assert loaded == EXPECTED_COUNTS


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    """Build the project's wheel once (build isolation fetches setuptools>=77 when needed)."""
    out = tmp_path_factory.mktemp("wheel")
    # From a copy without build/ (setuptools reuses a stale build/lib: files no longer listed
    # would slip into the wheel) or any other local state.
    src = tmp_path_factory.mktemp("src") / "parambench"
    shutil.copytree(ROOT, src, ignore=shutil.ignore_patterns(".venv", ".git", "__pycache__", "*.egg-info", "build",
                                                             "dist", ".pytest_cache", ".benchmarks", "test-artifacts"))
    cmd = [sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(out), str(src)]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    (whl,) = out.glob("parambench-*.whl")
    return whl


@pytest.mark.slow
def test_wheel_ships_the_real_meshes_their_sources_and_the_licence(wheel):
    names = set(zipfile.ZipFile(wheel).namelist())
    for filename in (*SHIPPED, "SOURCES.md"):
        assert f"{DATA_IN_WHEEL}/{filename}" in names
    assert any(n.endswith(".dist-info/licenses/LICENSE") for n in names)
    # Byte-for-byte the files of the source tree, so the wheel loads the same meshes.
    with zipfile.ZipFile(wheel) as zf:
        for filename in SHIPPED:
            assert zf.read(f"{DATA_IN_WHEEL}/{filename}") == (ROOT / DATA_IN_PACKAGE / filename).read_bytes()


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
    _check_loaded(_load_in_subprocess(site, elsewhere), site, site / DATA_IN_WHEEL)


@pytest.mark.slow
def test_real_datasets_load_from_a_copy_of_the_project_without_shared_beside_it(tmp_path):
    copy = tmp_path / "clone" / "parambench"
    shutil.copytree(ROOT, copy, ignore=shutil.ignore_patterns(".venv", ".git", "__pycache__", "*.egg-info",
                                                              "build", "dist", ".pytest_cache", ".benchmarks"))
    assert not (copy.parent / "shared").exists()
    elsewhere = tmp_path / "cwd"
    elsewhere.mkdir()
    # The copy imported as the package it installs as: parambench -> the copied folders.
    shim = tmp_path / "shim"
    shim.mkdir()
    (shim / "parambench").symlink_to(copy, target_is_directory=True)
    _check_loaded(_load_in_subprocess(shim, elsewhere), copy, copy / DATA_IN_PACKAGE)


def test_sources_file_credits_every_shipped_mesh():
    text = (ROOT / DATA_IN_PACKAGE / "SOURCES.md").read_text()
    for filename in SHIPPED:
        assert f"`{filename}`" in text
    assert "libigl-tutorial-data" in text and "Sorkine" in text
    # The two meshes taken from PyPI packages: package, version, licence, authors, and the cut.
    assert "bfieldtools-0.11.3-py3-none-any.whl" in text and "BSD-3-Clause" in text
    assert "Redistributions in binary form must reproduce the above copyright" in text  # BSD-3 asks for it
    assert "potpourri3d-1.4.0.tar.gz" in text and "Keenan Crane" in text and "public domain" in text
    assert "y >= -0.23" in text
    assert "pycortex-1.4.0.tar.gz" in text and "BSD-2-Clause" in text and "targetfacenum=24000" in text
    # The LiDAR tile: package, file, its hash, the licence's notice, and what was kept.
    assert "laspy-2.7.0.tar.gz" in text and "file_with_both_wkt_and_geotiff_vlrs.las" in text
    assert "58bc14d3268eecf5f286d463b2de4d99e1d045bb6e0f626827d9c2f0ee6053c8" in text
    assert "Copyright (c) 2020, Thomas Montaigu" in text and "classification 2 (ground)" in text


def test_every_shipped_mesh_file_is_listed_and_small():
    folder = ROOT / DATA_IN_PACKAGE
    meshes = sorted(p.name for p in folder.iterdir() if p.name != "SOURCES.md")
    assert meshes == sorted(SHIPPED)
    assert all((folder / name).stat().st_size <= 1_500_000 for name in SHIPPED)
    from parambench.datasets_gen.real import REAL_DATASETS

    assert sorted(d.filename for d in REAL_DATASETS.values() if d.location == "package") == sorted(SHIPPED)


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
    package_dir = config["tool"]["setuptools"]["package-dir"]
    for package, patterns in config["tool"]["setuptools"]["package-data"].items():
        top = max((name for name in package_dir if package == name or package.startswith(name + ".")), key=len)
        base = ROOT / package_dir[top] / Path(*package[len(top) + 1:].split(".")) if package != top else ROOT / package_dir[top]
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


def _source_packages() -> set[str]:
    """Every package folder of the four top-level folders (and data folder), as its installed dotted name."""
    names = set()
    for top in TOP_FOLDERS:
        for init in (ROOT / top).rglob("__init__.py"):
            rel = init.parent.relative_to(ROOT)
            if rel.parts[:2] != ("bench", "benchmarks") and "__pycache__" not in rel.parts:
                names.add("parambench." + ".".join(rel.parts))
    # Data-only folders ship as packages of their own (the real meshes).
    for folder in (ROOT / "datasets_gen" / "data").iterdir():
        if folder.is_dir() and folder.name != "__pycache__":
            names.add(f"parambench.datasets_gen.data.{folder.name}")
    return names


def test_setuptools_lists_every_package_folder_under_the_parambench_namespace():
    tomllib = pytest.importorskip("tomllib")
    setuptools = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    assert set(setuptools["packages"]) == _source_packages()
    assert setuptools["package-dir"] == {f"parambench.{top}": top for top in TOP_FOLDERS}


@pytest.mark.slow
def test_wheel_holds_only_the_parambench_namespace_without_the_benchmarks(wheel):
    names = zipfile.ZipFile(wheel).namelist()
    tops = {n.split("/")[0] for n in names if not n.split("/")[0].endswith(".dist-info")}
    assert tops == {"parambench"}
    assert not any(n.startswith("parambench/bench/benchmarks/") for n in names)
    # No __init__.py at parambench/: an implicit namespace package, as the source tree has none.
    assert "parambench/__init__.py" not in names
    with zipfile.ZipFile(wheel) as zf:
        (ep,) = [n for n in names if n.endswith(".dist-info/entry_points.txt")]
        assert "parambench = parambench.bench.cli:main" in zf.read(ep).decode()


# Imports every module of the installed package with the test-only extras made unimportable,
# then checks that the bare top-level names of the source folders are not importable.
IMPORT_ALL_SCRIPT = """
import importlib, importlib.abc, pkgutil, sys

class NoTestExtras(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in ("pytest", "pytest_benchmark", "selenium", "_pytest"):
            raise ImportError(f"test-only dependency {name} imported")
        return None

sys.meta_path.insert(0, NoTestExtras())
import parambench
count = 0
for info in pkgutil.walk_packages(parambench.__path__, "parambench."):
    importlib.import_module(info.name)
    count += 1
print(count)
for bare in ("methods", "bench", "reports", "datasets_gen"):
    try:
        importlib.import_module(bare)
    except ModuleNotFoundError:
        print("absent", bare)
"""


@pytest.mark.slow
def test_installed_package_imports_without_test_extras_and_has_no_bare_top_level_names(wheel, tmp_path):
    site = tmp_path / "site"
    zipfile.ZipFile(wheel).extractall(site)
    elsewhere = tmp_path / "cwd"
    elsewhere.mkdir()
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["PYTHONPATH"] = str(site)
    done = subprocess.run([sys.executable, "-c", IMPORT_ALL_SCRIPT], cwd=elsewhere, env=env, capture_output=True,
                          text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    count, *absent = done.stdout.split("\n")[:5]
    n_modules = sum(1 for top in TOP_FOLDERS for f in (ROOT / top).rglob("*.py")
                    if "benchmarks" not in f.parts and "__pycache__" not in f.parts)
    assert int(count) == n_modules
    assert absent == [f"absent {bare}" for bare in ("methods", "bench", "reports", "datasets_gen")]


def test_no_module_imports_a_bare_top_level_folder():
    # `from methods...` would work from the repository folder and break once installed.
    bare = re.compile(r"^\s*(?:from|import)\s+(?:methods|bench|reports|datasets_gen)\b", re.M)
    offenders = [str(f.relative_to(ROOT)) for folder in (*TOP_FOLDERS, "tests") for f in (ROOT / folder).rglob("*.py")
                 if bare.search(f.read_text(encoding="utf-8"))]
    assert offenders == []


# A third-party plugin: a module and the dist-info that declares it in the entry-point group.
THIRD_PARTY_PLUGIN = '''
import numpy as np
from parambench.methods import Method, MethodOutput

class ProjectXY(Method):
    """Drops z: exact on a plane."""
    name = "project-xy"
    description = "orthogonal projection to the xy plane"
    needs_faces = False
    defaults = {}
    param_grid = {}

    def solve(self, surface, params, timer):
        with timer("solve"):
            return MethodOutput(np.asarray(surface.points)[:, :2].copy())
'''

USE_PLUGIN_SCRIPT = """
import numpy as np
from parambench.methods import get_method, method_names
from parambench.datasets_gen.surface import Surface
assert "project-xy" in method_names(), method_names()
u, v = np.meshgrid(np.linspace(0, 1, 12), np.linspace(0, 2, 12))
pts = np.column_stack([u.ravel(), v.ravel(), np.zeros(u.size)])
result = get_method("project-xy")(Surface(pts))
from scipy.spatial.distance import pdist
# uv comes back in input units, up to a rigid motion of the plane (the unit-pose round trip).
print(result.method, result.uv.shape[0], float(np.abs(pdist(result.uv) - pdist(pts[:, :2])).max()), sorted(result.timings))
"""


def test_a_third_party_method_registers_through_the_entry_point_group(tmp_path):
    site = tmp_path / "site"
    site.mkdir()
    (site / "xy_plugin.py").write_text(THIRD_PARTY_PLUGIN)
    dist = site / "xy_plugin-0.1.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: xy-plugin\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text("[parambench.methods]\nproject-xy = xy_plugin:ProjectXY\n")
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(site), env.get("PYTHONPATH", "")])
    done = subprocess.run([sys.executable, "-c", USE_PLUGIN_SCRIPT], cwd=tmp_path, env=env, capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    name, n, err, stages = done.stdout.split(" ", 3)
    assert name == "project-xy" and int(n) == 144
    # An isometry of the plane: same distances in the same row order.
    assert float(err) < 1e-9
    assert "'solve'" in stages and "'total'" in stages
