"""Where numba keeps its on-disk cache of compiled kernels, decided once at import.

numba's ``cache=True`` looks for a writable ``__pycache__`` beside the source file, then
for ``~/.cache/numba``; when neither can be written (a read-only install used by an account
without a writable home: CI runners, containers, ``nobody``) it raises ``RuntimeError`` at
decoration time, so even ``parambench list`` would fail on import. This module keeps numba's
own choice when it works, otherwise points ``NUMBA_CACHE_DIR`` at a per-user folder under
the system temporary folder, and when nothing is writable turns caching off (kernels then
compile afresh in every process instead of failing).

A module with kernels calls :func:`configure_numba_cache` once with its own folder and
decorates them with ``@numba.njit(cache=<the returned flag>)`` (``parambench.methods.pointset.dem``).
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numba.core.config
from numba.misc.appdirs import AppDirs

__all__ = ["configure_numba_cache", "can_write", "cached_on_disk"]

ENV_VAR = "NUMBA_CACHE_DIR"


def can_write(folder: Path) -> bool:
    """True when ``folder`` exists or can be created, and a file can be written in it.

    Mirrors numba's own test (``os.makedirs`` then a temporary file), which also holds for
    root, for whom permission bits say nothing.
    """
    try:
        os.makedirs(folder, exist_ok=True)
        tempfile.TemporaryFile(dir=folder).close()
    except OSError:
        return False
    return True


def _numba_user_cache_dir() -> Path:
    """numba's user-wide cache folder on this platform (``~/.cache/numba`` on Linux)."""
    return Path(AppDirs(appname="numba", appauthor=False).user_cache_dir)


def _fallback_dir() -> Path:
    """A cache folder of this user's own under the system temporary folder."""
    # Named per user so two accounts never share (or fight over) one folder.
    who = str(os.getuid()) if hasattr(os, "getuid") else (os.environ.get("USERNAME") or "user")
    return Path(tempfile.gettempdir()) / f"parambench-numba-cache-{who}"


def _owned_by_me(folder: Path) -> bool:
    # A folder someone else created first in a shared /tmp could feed us their cache files.
    return not hasattr(os, "getuid") or folder.stat().st_uid == os.getuid()


def configure_numba_cache(source_dir: Path) -> tuple[bool, str | None]:
    """Choose the cache for kernels defined in ``source_dir`` and tell numba.

    Parameters
    ----------
    source_dir : pathlib.Path
        Folder of the module whose kernels are cached (numba's in-tree cache goes in its
        ``__pycache__``).

    Returns
    -------
    enabled : bool
        Pass as ``cache=`` to ``numba.njit``.
    cache_dir : str or None
        The folder set in ``NUMBA_CACHE_DIR`` (the user's own value, or the fallback), or
        None when numba's default locations are used or caching is off.

    Notes
    -----
    On fallback sets ``numba.core.config.CACHE_DIR`` (read when a function is decorated) and
    ``os.environ["NUMBA_CACHE_DIR"]`` (so worker processes inherit it). Never raises: a
    failing cache must not stop a command.
    """
    user_choice = os.environ.get(ENV_VAR)
    if user_choice:
        return can_write(Path(user_choice)), user_choice
    if can_write(source_dir / "__pycache__") or can_write(_numba_user_cache_dir()):
        return True, None
    fallback = _fallback_dir()
    if not (can_write(fallback) and _owned_by_me(fallback)):
        return False, None
    # numba read its environment when it was imported: tell its config directly as well.
    os.environ[ENV_VAR] = str(fallback)
    numba.core.config.CACHE_DIR = str(fallback)
    return True, str(fallback)


def cached_on_disk(kernel) -> bool | None:
    """Whether numba's on-disk cache holds compiled code of ``kernel`` (a ``numba.njit`` function).

    A fresh install compiles its kernels on first use and caches them: ``parambench
    flatten`` on 10k points took 44.6 s the first time against 2.0 s after (2 cores),
    which without a word looks like a hang.

    Returns
    -------
    bool or None
        Whether the kernel's cache index file exists where numba looks for it; None when
        that is not known (caching off, or a numba whose cache is laid out otherwise).
    """
    try:
        index = kernel._cache._cache_file._index_path
    except AttributeError:
        return None
    return os.path.exists(index)
