"""Suite-wide pytest set-up: the test log names the version of every declared dependency.

Numerical tolerances depend on numpy, scipy and friends; a failure on another machine is
only readable when the log says which releases were installed.
"""

from __future__ import annotations

import re
import sys
from importlib import metadata
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _load_source_tree_helper():
    # tests/ is not a package (pytest's importlib mode): load the helper by path.
    import importlib.util

    spec = importlib.util.spec_from_file_location("_parambench_source_tree", ROOT / "tests" / "source_tree.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


SOURCE_TREE_SHIM = _load_source_tree_helper().put_source_tree_first()


def _requirement_name(spec: str) -> str:
    """``"dask[distributed]>=2024.1; python_version<'3.13'"`` -> ``"dask"``."""
    return re.split(r"[\s\[<>=!~;@(]", spec.strip(), maxsplit=1)[0]


def declared_requirements() -> list[str]:
    """Distribution names the project declares: runtime dependencies, then every extra's.

    Read from the installed parambench metadata when it is installed, otherwise from
    ``pyproject.toml`` beside the tests (a bare ``PYTHONPATH`` checkout).

    Returns
    -------
    list of str
        Names in declaration order, without duplicates, versions or extras.
    """
    try:
        specs = metadata.requires("parambench") or []
    except metadata.PackageNotFoundError:
        specs = []
    if not specs:
        import tomllib  # Python >= 3.11; 3.10 without an install prints no dependency list

        project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
        specs = list(project.get("dependencies", []))
        for extra in project.get("optional-dependencies", {}).values():
            specs += extra
    names = [_requirement_name(s) for s in specs]
    return list(dict.fromkeys(n for n in names if n))


def resolved_versions(names: list[str]) -> list[str]:
    """``name==version`` for each installed distribution, ``name (not installed)`` otherwise."""
    out = []
    for name in names:
        try:
            out.append(f"{name}=={metadata.version(name)}")
        except metadata.PackageNotFoundError:
            out.append(f"{name} (not installed)")
    return out


def pytest_report_header(config):
    try:
        names = declared_requirements()
    except (ImportError, OSError, KeyError) as err:  # never let the header stop the run
        return [f"dependencies: not listed ({err})"]
    return [f"python {sys.version.split()[0]}; dependencies: " + ", ".join(resolved_versions(names))]
