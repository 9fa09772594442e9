"""The test log's header lists the resolved version of every declared dependency."""

from __future__ import annotations

import subprocess
import sys
from importlib import metadata
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_header_names_each_declared_dependency_with_its_installed_version():
    # Collect-only on one small file: the header is printed before collection (not with -q).
    done = subprocess.run([sys.executable, "-m", "pytest", "--collect-only", "-p", "no:cacheprovider",
                           "tests/test_report_header.py"], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stdout + done.stderr
    (line,) = [ln for ln in done.stdout.splitlines() if "dependencies: " in ln]
    listed = dict(item.split("==") for item in line.split("dependencies: ", 1)[1].split(", ") if "==" in item)
    for name in ("numpy", "scipy", "numba", "libigl", "pymeshlab", "pytest"):
        assert listed[name] == metadata.version(name)
