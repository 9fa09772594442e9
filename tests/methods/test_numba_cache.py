"""Commands work for an account whose home folder cannot be written (numba's cache falls back).

The subprocess tests copy the project, block numba's in-tree cache folder (a file named
``__pycache__`` where the folder would go: as a read-only install does, and unlike permission
bits this also holds for root) and give the process ``HOME=/proc/nonexistent``, a folder
nobody can create. Without :mod:`parambench.methods.numba_cache` numba raises at import.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numba.core.config
import numpy as np
import pytest

from parambench.methods.numba_cache import can_write, configure_numba_cache

ROOT = Path(__file__).resolve().parents[2]
UNWRITABLE = Path("/proc/nonexistent")  # /proc refuses new entries, even to root


def _blocked_copy(dest: Path) -> Path:
    """The project's packages in ``dest/parambench`` (the installed layout), with numba's
    in-tree cache impossible to create."""
    for package in ("methods", "datasets_gen", "bench", "reports"):
        shutil.copytree(ROOT / package, dest / "parambench" / package, ignore=shutil.ignore_patterns("__pycache__"))
    (dest / "parambench" / "methods" / "pointset" / "__pycache__").write_text("not a folder\n")
    return dest


def _run_cli(tree: Path, tmpdir: Path, *argv: str, stderr=None) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "XDG_CACHE_HOME", "PYTHONPATH")}
    env.update(HOME=str(UNWRITABLE), TMPDIR=str(tmpdir), PYTHONPATH=str(tree))
    # The console script's entry point (parambench.bench.cli:main), so the copy is what runs.
    code = f"import sys; from parambench.bench.cli import main; sys.exit(main({list(argv)!r}))"
    pipes = {"capture_output": True} if stderr is None else {"stdout": subprocess.PIPE, "stderr": stderr}
    return subprocess.run([sys.executable, "-c", code], cwd=tmpdir, env=env, text=True, timeout=300, **pipes)


def _run_python(tree: Path, tmpdir: Path, code: str) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env.update(PYTHONPATH=str(tree))
    return subprocess.run([sys.executable, "-c", code], cwd=tmpdir, env=env, capture_output=True, text=True,
                          timeout=120)


@pytest.fixture(scope="module")
def blocked(tmp_path_factory):
    root = tmp_path_factory.mktemp("nohome")
    tmpdir = root / "tmp"
    tmpdir.mkdir()
    return _blocked_copy(root / "tree"), tmpdir


@pytest.mark.skipif(not hasattr(os, "getuid"), reason="POSIX home and /proc")
def test_list_runs_without_a_writable_home(blocked):
    tree, tmpdir = blocked
    assert not can_write(UNWRITABLE / ".cache" / "numba")
    done = _run_cli(tree, tmpdir, "list")
    assert done.returncode == 0, done.stderr
    # The copy ran, not an installed parambench (its numba kernels are what the test blocks).
    where = _run_python(tree, tmpdir, "import parambench.methods as m; print(m.__file__)")
    assert Path(where.stdout.strip()).is_relative_to(tree), where.stderr
    assert "ocp" in done.stdout and "real/camelhead" in done.stdout


@pytest.mark.skipif(not hasattr(os, "getuid"), reason="POSIX home and /proc")
def test_flatten_points_caches_kernels_under_the_temporary_folder(blocked):
    tree, tmpdir = blocked
    u, v = np.meshgrid(np.linspace(0, 1, 15), np.linspace(0, 1, 15))
    pts = np.column_stack([u.ravel(), v.ravel(), 0.1 * np.sin(3 * u.ravel()) * v.ravel()])
    src = tmpdir / "patch.xyz"
    np.savetxt(src, pts)
    out = tmpdir / "patch.csv"
    done = _run_cli(tree, tmpdir, "flatten", str(src), "--method", "lem", "-o", str(out))
    assert done.returncode == 0, done.stderr
    assert len(out.read_text().splitlines()) == 1 + len(pts)  # header u,v and one row per point
    # The kernels were cached in the per-user fallback, not dropped or written elsewhere.
    cache = tmpdir / f"parambench-numba-cache-{os.getuid()}"
    assert any(p.suffix == ".nbi" for p in cache.rglob("*"))
    # Piped (as here) stderr gets no note: a script reading it gets its one error line.
    assert "numba compiles" not in done.stderr


@pytest.mark.skipif(not hasattr(os, "getuid"), reason="POSIX home, /proc and terminals")
def test_a_terminal_is_told_when_the_kernels_compile(blocked, tmp_path):
    import pty

    tree, tmpdir = blocked[0], tmp_path  # a temporary folder of its own: an empty kernel cache
    src = tmpdir / "patch.xyz"
    u, v = np.meshgrid(np.linspace(0, 1, 15), np.linspace(0, 1, 15))
    np.savetxt(src, np.column_stack([u.ravel(), v.ravel(), 0.1 * u.ravel() * v.ravel()]))

    def stderr_on_a_terminal() -> str:
        main_fd, terminal_fd = pty.openpty()
        try:
            done = _run_cli(tree, tmpdir, "flatten", str(src), "--method", "lem", "-o", str(tmpdir / "o.csv"),
                            stderr=terminal_fd)
            assert done.returncode == 0
            os.close(terminal_fd)
            chunks = []
            while True:
                try:
                    chunk = os.read(main_fd, 4096)
                except OSError:  # the terminal's other end closed: all read
                    break
                if not chunk:
                    break
                chunks.append(chunk)
            return b"".join(chunks).decode()
        finally:
            os.close(main_fd)

    # The first run compiles (44.6 s for ocp on 10k points, 2.0 s once cached): it says so,
    # or it looks like a hang; the next loads the cached kernels and says nothing.
    assert "numba compiles the point-set kernels now" in stderr_on_a_terminal()
    assert "numba compiles" not in stderr_on_a_terminal()


def test_user_setting_wins_and_an_unwritable_one_turns_caching_off(tmp_path, monkeypatch):
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "mine"))
    assert configure_numba_cache(tmp_path / "src") == (True, str(tmp_path / "mine"))
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(UNWRITABLE / "cache"))
    assert configure_numba_cache(tmp_path / "src") == (False, str(UNWRITABLE / "cache"))


def test_writable_source_folder_keeps_numbas_default(tmp_path, monkeypatch):
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    assert configure_numba_cache(tmp_path / "src") == (True, None)
    assert (tmp_path / "src" / "__pycache__").is_dir()


def test_fallback_and_disabling_when_source_and_home_are_unwritable(tmp_path, monkeypatch):
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    monkeypatch.setenv("HOME", str(UNWRITABLE))
    monkeypatch.delenv("XDG_CACHE_HOME", raising=False)
    monkeypatch.setattr("tempfile.tempdir", str(tmp_path))
    monkeypatch.setattr(numba.core.config, "CACHE_DIR", numba.core.config.CACHE_DIR)
    src = tmp_path / "src"
    src.mkdir()
    (src / "__pycache__").write_text("")
    enabled, folder = configure_numba_cache(src)
    assert enabled and folder == str(tmp_path / f"parambench-numba-cache-{os.getuid()}")
    assert os.environ["NUMBA_CACHE_DIR"] == folder == numba.core.config.CACHE_DIR
    monkeypatch.delenv("NUMBA_CACHE_DIR")
    # Nothing writable at all: no cache rather than an error.
    monkeypatch.setattr("tempfile.tempdir", str(UNWRITABLE))
    assert configure_numba_cache(src) == (False, None)
