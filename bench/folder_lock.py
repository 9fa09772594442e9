"""One sweep per results folder: an exclusive ``fcntl.flock`` held for the sweep's lifetime.

The kernel drops a ``flock`` when its file descriptor is closed, which includes the
process dying (killed, out of memory), so a crashed sweep never leaves a stale lock. The
lock file itself is never deleted: unlinking it while another process waits on the old
inode would let two sweeps hold "the" lock at once. The holder writes its pid, host and
start time into the file only so that a refused sweep can name it.
"""

from __future__ import annotations

import errno
import fcntl
import os
import socket
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Callable, Iterator

from parambench.datasets_gen.errors import ResultsInUseError

__all__ = ["LOCK_NAME", "hold_folder"]

#: Lock file inside the results folder (hidden; the report never reads it).
LOCK_NAME = ".parambench.lock"


def _holder(fd: int) -> str:
    try:
        text = os.pread(fd, 200, 0).decode(errors="replace").strip()
    except OSError:
        text = ""
    return text or "another process"


@contextmanager
def hold_folder(root: str | os.PathLike, *, wait: bool = False,
                on_wait: Callable[[str], None] | None = None) -> Iterator[Path]:
    """Hold the results folder ``root`` exclusively for the duration of the ``with`` block.

    Parameters
    ----------
    root : str or path-like
        An existing results folder; the lock file ``root/.parambench.lock`` is created if
        missing.
    wait : bool
        False: refuse at once when another sweep holds the folder. True: block until it
        is released.
    on_wait : callable(str), optional
        Called once with the holder's description before blocking (only when ``wait``).

    Yields
    ------
    pathlib.Path
        The lock file.

    Raises
    ------
    ResultsInUseError
        Another process holds the folder and ``wait`` is False.
    """
    path = Path(root) / LOCK_NAME
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            if exc.errno not in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                raise
            holder = _holder(fd)
            if not wait:
                raise ResultsInUseError(
                    f"results folder {str(root)!r} is in use by another sweep ({holder}); wait for it to "
                    f"finish, pass --wait to queue behind it, or choose another --out.") from None
            if on_wait is not None:
                on_wait(holder)
            fcntl.flock(fd, fcntl.LOCK_EX)
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"pid {os.getpid()} on {socket.gethostname()}, started "
                      f"{time.strftime('%Y-%m-%d %H:%M:%S')}\n".encode(), 0)
        yield path
    finally:
        os.close(fd)  # releases the flock
