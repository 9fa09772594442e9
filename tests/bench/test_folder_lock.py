"""One sweep per results folder: refused or queued while held, released when the holder dies."""

from __future__ import annotations

import signal
import subprocess
import sys
from pathlib import Path

import pytest

from parambench.bench.folder_lock import LOCK_NAME, hold_folder
from parambench.datasets_gen.errors import ResultsInUseError

# A holder in another process: takes the lock, says so, then sleeps until killed or done.
_HOLDER = """
import sys, time
from parambench.bench.folder_lock import hold_folder
with hold_folder(sys.argv[1]):
    print("held", flush=True)
    time.sleep(float(sys.argv[2]))
"""


def _start_holder(folder, seconds):
    proc = subprocess.Popen([sys.executable, "-c", _HOLDER, str(folder), str(seconds)], stdout=subprocess.PIPE,
                            text=True, cwd=Path(__file__).resolve().parents[2])
    assert proc.stdout.readline().strip() == "held"
    return proc


def test_second_holder_is_refused_with_the_first_ones_pid(tmp_path):
    with hold_folder(tmp_path):
        with pytest.raises(ResultsInUseError, match=r"in use by another sweep \(pid \d+.*--wait"):
            with hold_folder(tmp_path):
                pass
    with hold_folder(tmp_path) as path:  # released on exit
        assert path == tmp_path / LOCK_NAME


def test_killed_holder_releases_the_folder(tmp_path):
    proc = _start_holder(tmp_path, 60)
    try:
        with pytest.raises(ResultsInUseError, match=f"pid {proc.pid}"):
            with hold_folder(tmp_path):
                pass
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    with hold_folder(tmp_path):  # no stale lock after a crash
        pass


def test_wait_queues_behind_the_holder(tmp_path):
    proc = _start_holder(tmp_path, 1.0)
    waited = []
    with hold_folder(tmp_path, wait=True, on_wait=waited.append):
        assert proc.wait(timeout=60) == 0  # we hold it only once the holder has let go
    assert len(waited) == 1 and f"pid {proc.pid}" in waited[0]
