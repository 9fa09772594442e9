"""Refuse, before the work starts, an input whose run would need more memory than the machine has.

A point set of several million points runs for minutes and then, past the machine's
memory, is killed by the operating system: no message, exit code 137, nothing written.
Methods that state their measured peak memory (``Method.peak_memory``, a
:class:`PeakMemory`) are checked against the memory available now: the smaller of the kernel's
``MemAvailable`` and a cgroup's limit less its usage (a container's or a job
scheduler's share), where those are readable. Elsewhere (no ``/proc``) nothing is
checked.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import NamedTuple

from parambench.datasets_gen.errors import ResourceLimitError

__all__ = ["available_bytes", "check_memory", "PeakMemory", "MEMORY_CHECK_ENV"]

#: Set this environment variable to ``0`` to skip the check (a machine whose swap or
#: memory accounting the check misreads).
MEMORY_CHECK_ENV = "PARAMBENCH_MEMORY_CHECK"

_GIB = 2.0**30


def _meminfo_available(path: Path = Path("/proc/meminfo")) -> int | None:
    try:
        for line in path.read_text().splitlines():
            if line.startswith("MemAvailable:"):
                return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        return None
    return None


def _read_int(path: Path) -> int | None:
    try:
        text = path.read_text().strip()
    except OSError:
        return None
    return int(text) if text.isdigit() else None  # "max": no limit


def _cgroup_room(root: Path = Path("/sys/fs/cgroup")) -> int | None:
    """The cgroup's memory limit less its usage (v2, then v1); None without a limit."""
    for limit_file, usage_file in (("memory.max", "memory.current"),
                                   ("memory/memory.limit_in_bytes", "memory/memory.usage_in_bytes")):
        limit = _read_int(root / limit_file)
        # v1 reports "no limit" as a huge number (about 2^63).
        if limit is not None and limit < 2**60:
            usage = _read_int(root / usage_file) or 0
            return max(limit - usage, 0)
    return None


def available_bytes(*, meminfo: Path = Path("/proc/meminfo"), cgroup: Path = Path("/sys/fs/cgroup")) -> int | None:
    """Memory this process can still take, in bytes; None where the system does not say.

    Parameters
    ----------
    meminfo, cgroup : pathlib.Path
        Where to read (the defaults are Linux's; tests point them elsewhere).

    Returns
    -------
    int or None
        The smaller of ``MemAvailable`` and the cgroup's limit less its usage.
    """
    known = [v for v in (_meminfo_available(meminfo), _cgroup_room(cgroup)) if v is not None]
    return min(known) if known else None


class PeakMemory(NamedTuple):
    """A method's measured peak resident memory and how it grows: ``bytes * (n / points) ** exponent``.

    Attributes
    ----------
    points : int
        The size it was measured at.
    bytes : float
        The peak resident memory of the process there, in bytes.
    exponent : float
        Growth with the number of points (measured between two sizes; 1 is linear).
    part : str
        What was measured when it is only part of the method's work (e.g. "the point-set
        front end"): the estimate is then a lower bound. Empty: the whole method.
    """

    points: int
    bytes: float
    exponent: float
    part: str = ""

    def at(self, n_points: int) -> float:
        """Estimated peak in bytes for ``n_points`` points."""
        return self.bytes * (float(n_points) / self.points) ** self.exponent

    def points_within(self, room: float) -> int:
        """The most points whose estimate stays within ``room`` bytes."""
        return int(self.points * (room / self.bytes) ** (1.0 / self.exponent))


def check_memory(method: str, n_points: int, peak: PeakMemory, *, available: int | None = None) -> None:
    """Raise when the estimated peak memory for ``n_points`` exceeds the memory available.

    Parameters
    ----------
    method : str
        The method's name, for the message.
    n_points : int
        Points (or mesh vertices) of the input.
    peak : PeakMemory
        The method's measured peak memory and its growth.
    available : int, optional
        Bytes available (default: :func:`available_bytes` now).

    Raises
    ------
    ResourceLimitError
        The estimate exceeds what is available. Not raised where the available memory is
        unknown or the environment variable :data:`MEMORY_CHECK_ENV` is ``0``.
    """
    if os.environ.get(MEMORY_CHECK_ENV, "1").strip() == "0":
        return
    room = available_bytes() if available is None else available
    need = peak.at(n_points)
    if room is None or need <= room:
        return
    fits = peak.points_within(room)
    what = (f"at least {need / _GIB:.1f} GiB of memory ({peak.part} alone, measured: " if peak.part
            else f"about {need / _GIB:.1f} GiB of memory at its peak (measured: ")
    raise ResourceLimitError(
        f"{method} on {n_points:,} points needs {what}"
        f"{peak.bytes / _GIB:.1f} GiB at {peak.points:,} points), and {room / _GIB:.1f} GiB is available: thin the "
        f"points to at most about {fits:,} (`parambench flatten --max-points {fits}` maps such a subsample and "
        f"extends its map to every point), or run it on a machine with more memory ({MEMORY_CHECK_ENV}=0 skips "
        "this check).")
