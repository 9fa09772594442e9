"""Which threading layer numba's parallel kernels use, decided before the first launch.

numba tries TBB first. pymeshlab ships its own, older ``libtbb.so.12``; once pymeshlab is
loaded in a process (every mesh file read through it), numba finds that library, refuses
it and prints a ``NumbaWarning`` on stderr before falling back to OpenMP. The warning
breaks the command line's one-line messages and says nothing a user can act on. OpenMP is
what numba ends up with anyway, so this module asks for it first.

A user's own ``NUMBA_THREADING_LAYER`` or ``NUMBA_THREADING_LAYER_PRIORITY`` is kept.
"""

from __future__ import annotations

import os
import sys

__all__ = ["PRIORITY", "prefer_openmp"]

#: numba's layers in the order tried: OpenMP, then numba's own work queue, TBB last.
PRIORITY = ("omp", "workqueue", "tbb")

_USER_CHOICES = ("NUMBA_THREADING_LAYER", "NUMBA_THREADING_LAYER_PRIORITY")


def prefer_openmp() -> bool:
    """Put OpenMP first in numba's threading-layer priority unless the user chose one.

    Sets the environment variable (read when numba is imported, and by child processes)
    and, when numba is already imported, its live config as well. Has no effect once a
    parallel kernel has run: numba picks its layer at the first launch.

    Returns
    -------
    bool
        True when the priority was set here, False when the user's choice was kept.
    """
    if any(name in os.environ for name in _USER_CHOICES):
        return False
    os.environ["NUMBA_THREADING_LAYER_PRIORITY"] = " ".join(PRIORITY)
    config = sys.modules.get("numba.core.config")
    if config is not None:
        config.THREADING_LAYER_PRIORITY = list(PRIORITY)
    return True
