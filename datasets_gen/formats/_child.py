"""Running a native decoder in a child process capped in memory (LAS/LAZ, E57).

Native decoders (lazrs, libE57Format) abort the process or allocate without bound on some
damaged files. They run here in a child process (``sys.executable -c CODE PATH OUT LIMIT [ARGS]``)
whose address space is capped (``RLIMIT_AS``) and whose BLAS pools are held to one thread;
the child saves its arrays to an ``.npz`` and writes one line on stderr when it fails. Any
failure, a crash, the cap reached or the time limit, is an InputFileError naming the file.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from ._common import file_error

__all__ = ["CHILD_MEMORY_BASE", "CHILD_PRELUDE", "CHILD_EPILOGUE", "decode_in_child"]

#: Address space of a decoding child besides its data (bytes): Python, numpy and the
#: decoder take about 0.4 GB of it (their thread pools held to one thread there).
CHILD_MEMORY_BASE = 2 << 30

#: BLAS thread pools reserve address space per core; the child needs none of them.
_ONE_THREAD = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}

#: First lines of every child's code: the memory cap (argv[3]) before anything is imported.
CHILD_PRELUDE = """
import sys
try:
    import resource
    resource.setrlimit(resource.RLIMIT_AS, (int(sys.argv[3]), int(sys.argv[3])))
except (ImportError, ValueError, OSError):
    pass
import numpy as np
"""

#: Last lines of every child's code: a failure of its ``decode()`` as one line on stderr,
#: the first of the exception's message (libE57Format's go on with debug lines).
CHILD_EPILOGUE = """
try:
    decode()
except MemoryError:
    sys.stderr.write("the decoder ran out of memory\\n")
    sys.exit(3)
except Exception as exc:
    first = next((line for line in str(exc).splitlines() if line.strip()), "")
    sys.stderr.write(f"{type(exc).__name__}: {first}\\n")
    sys.exit(3)
"""


def decode_in_child(path: Path, code: str, limit: int, timeout: float, kind: str, todo: str,
                    args: tuple[str, ...] = ()) -> dict[str, np.ndarray]:
    """Run ``code`` in a child process capped in memory and return the arrays it saved.

    Parameters
    ----------
    path : pathlib.Path
        The file; the child gets it as ``sys.argv[1]``.
    code : str
        Python source run with ``sys.executable -c``; it saves its arrays with
        ``np.savez(sys.argv[2], ...)`` and caps itself to ``sys.argv[3]`` bytes (start it
        with :data:`CHILD_PRELUDE`).
    limit : int
        The child's address-space cap in bytes.
    timeout : float
        Seconds before the child is killed.
    kind : str
        The format's name for messages (``"LAS/LAZ"``).
    todo : str
        What the user should do when the file cannot be read.
    args : tuple of str
        More arguments for the child, from ``sys.argv[4]`` on.

    Returns
    -------
    dict of str to numpy.ndarray
        The arrays of the child's ``.npz``, loaded into memory.

    Raises
    ------
    InputFileError
        The child timed out, exited non-zero (its last line of stderr, or a line saying
        that a memory allocation failed, goes into the message) or saved nothing.
    """
    with tempfile.TemporaryDirectory(prefix="parambench-decode-") as tmp:
        out = Path(tmp) / "points.npz"
        try:
            done = subprocess.run([sys.executable, "-c", code, str(path), str(out), str(int(limit)), *args],
                                  capture_output=True, text=True, timeout=timeout,
                                  env={**os.environ, **_ONE_THREAD})
        except subprocess.TimeoutExpired:
            raise file_error(path, None, "its decoder did not finish", "pass an undamaged copy of the file") from None
        if done.returncode != 0 or not out.exists():
            said = (done.stderr.strip().splitlines() or [f"exit status {done.returncode}"])
            reason = next((line for line in said if "memory allocation" in line), said[-1])
            raise file_error(path, None, f"not a readable {kind} file (its decoder failed: {reason[:200]})", todo)
        with np.load(out) as arrays:
            return {name: arrays[name] for name in arrays.files}
