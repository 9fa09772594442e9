"""Make ``import parambench.*`` load the source tree these tests sit in.

The four top-level folders install as ``parambench.methods``, ``parambench.bench``, ... via
setuptools' package-dir mapping; in the source tree there is no ``parambench`` folder. A
temporary folder holding one symlink, ``parambench -> <project root>``, goes first on
``sys.path`` (and on ``PYTHONPATH`` for subprocesses), so ``parambench.methods`` is
``<root>/methods`` whether or not (and however) the project is installed: the tests always test
the code beside them, including in a helper's git worktree. ``parambench`` stays an implicit
namespace package, as in the wheel. ``tests/test_packaging.py`` tests the installed layout.
"""

from __future__ import annotations

import atexit
import os
import shutil
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def put_source_tree_first() -> Path:
    """Create the symlink folder, put it first on ``sys.path`` and ``PYTHONPATH``; return it.

    Raises
    ------
    RuntimeError
        ``parambench`` was already imported from somewhere else (too late to redirect).
    """
    for entry in sys.path:  # already done (tests/ and bench/benchmarks/ both call this)
        link = Path(entry or ".") / "parambench"
        if link.is_symlink() and link.resolve() == ROOT:
            return Path(entry)
    shim = Path(tempfile.mkdtemp(prefix="parambench-src-"))
    atexit.register(shutil.rmtree, shim, True)
    (shim / "parambench").symlink_to(ROOT, target_is_directory=True)
    sys.path.insert(0, str(shim))
    os.environ["PYTHONPATH"] = os.pathsep.join(p for p in (str(shim), os.environ.get("PYTHONPATH")) if p)
    loaded = sys.modules.get("parambench")
    if loaded is not None and str(shim) not in str(getattr(loaded, "__path__", "")):
        raise RuntimeError(f"parambench was imported before the test set-up, from {loaded.__path__}")
    return shim
