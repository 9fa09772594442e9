"""Benchmarks import ``parambench.*`` from the source tree they sit in (see tests/source_tree.py)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

_HELPER = Path(__file__).resolve().parents[2] / "tests" / "source_tree.py"
_spec = importlib.util.spec_from_file_location("_parambench_source_tree", _HELPER)
_module = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_module)
SOURCE_TREE_SHIM = _module.put_source_tree_first()
