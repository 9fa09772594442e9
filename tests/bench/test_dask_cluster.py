"""Sweeps on a real Dask cluster on loopback: same table as serial, survives a dead worker."""

from __future__ import annotations

import os
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pandas as pd
import pytest

from parambench.bench.suites import Suite
from parambench.bench.sweep import run_sweep

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[2]
SUITE = Suite(name="dask", datasets=("plane", "saddle", "bump", "cap"), sizes=(1500,), samplings=("jittered",),
              seeds=(0, 1), methods=("scp-igl", "lscm-igl"))
COMPARE = ["cell_id", "status", "n_points", "qc_mean", "qc_p95", "foldovers", "area_distortion", "exact_error"]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _dask_bin() -> str:
    exe = Path(sys.executable).parent / "dask"
    return str(exe) if exe.exists() else shutil.which("dask")


@pytest.fixture
def cluster():
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    common = dict(cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    sched = subprocess.Popen([_dask_bin(), "scheduler", "--host", "127.0.0.1", "--port", str(port),
                              "--no-dashboard"], **common)
    workers = [subprocess.Popen([_dask_bin(), "worker", address, "--nthreads", "1", "--nworkers", "1",
                                 "--no-dashboard", "--host", "127.0.0.1", "--name", f"w{i}"], **common)
               for i in range(2)]
    from distributed import Client

    deadline = time.time() + 60
    while True:
        try:
            with Client(address, timeout=5) as c:
                if len(c.scheduler_info()["workers"]) == 2:
                    break
        except OSError:
            pass
        if time.time() > deadline:
            raise RuntimeError("local dask cluster did not start within 60 s")
        time.sleep(0.5)
    yield address, workers
    for proc in [*workers, sched]:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()


def test_cluster_sweep_survives_worker_loss_and_matches_serial(cluster, tmp_path):
    address, workers = cluster
    out = tmp_path / "cluster"
    result = {}

    def sweep():
        result["table"] = run_sweep(SUITE, str(out), scheduler=address, progress=False)

    thread = threading.Thread(target=sweep)
    thread.start()
    deadline = time.time() + 120
    while time.time() < deadline and len(list((out / "cells").glob("*.json"))) < 3:
        time.sleep(0.05)
    os.killpg(workers[0].pid, signal.SIGKILL)  # one worker dies half-way
    thread.join(timeout=600)
    assert not thread.is_alive(), "cluster sweep did not finish after losing a worker"
    table = result["table"]
    n_cells = 4 * 2 * 2
    assert len(table) == n_cells and table.cell_id.is_unique and set(table.status) == {"ok"}
    assert len(list((out / "cells").glob("*.json"))) == n_cells

    serial = run_sweep(SUITE, str(tmp_path / "serial"), progress=False)
    pd.testing.assert_frame_equal(table[COMPARE].reset_index(drop=True), serial[COMPARE].reset_index(drop=True))
