"""numba's parallel kernels run without a TBB warning after pymeshlab is loaded."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

_KERNEL = """
import warnings
import pymeshlab  # noqa: F401 - loads its bundled libtbb first, as a mesh read does
{setup}
import numba, numpy as np
from numba.core.errors import NumbaWarning
warnings.simplefilter("error", NumbaWarning)  # only numba's: other libraries' warnings are not this test's

@numba.njit(parallel=True)
def total(x):
    s = 0.0
    for i in numba.prange(x.size):
        s += x[i]
    return s

assert total(np.ones(64)) == 64.0
print(numba.threading_layer())
"""


def _run(setup: str, **env_overrides: str) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_THREADING")}
    env.update(env_overrides)
    return subprocess.run(
        [sys.executable, "-c", _KERNEL.format(setup=setup)], capture_output=True, text=True, env=env, timeout=300
    )


def _tbb_refused(proc: subprocess.CompletedProcess) -> bool:
    return proc.returncode != 0 and "TBB" in proc.stderr


def test_parambench_import_keeps_the_kernels_quiet():
    proc = _run("import parambench.methods")
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() in ("omp", "workqueue")


def test_without_the_priority_pymeshlab_tbb_would_warn():
    # The situation the module exists for; if numba or pymeshlab stop disagreeing over TBB
    # this skips rather than passing for the wrong reason.
    proc = _run("")
    if proc.returncode == 0:
        pytest.skip(f"numba accepted the loaded TBB or never tried it here (layer {proc.stdout.strip()})")
    assert _tbb_refused(proc)


def test_a_users_own_choice_is_kept():
    from parambench.methods.numba_threading import prefer_openmp

    saved = os.environ.get("NUMBA_THREADING_LAYER")
    os.environ["NUMBA_THREADING_LAYER"] = "workqueue"
    try:
        assert prefer_openmp() is False
    finally:
        if saved is None:
            del os.environ["NUMBA_THREADING_LAYER"]
        else:
            os.environ["NUMBA_THREADING_LAYER"] = saved
    proc = _run("import parambench.methods", NUMBA_THREADING_LAYER="workqueue")
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "workqueue"
