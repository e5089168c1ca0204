"""Shared test fixtures: the oracle files of ../shared (present in CI, maybe absent elsewhere), a Ctrl-C that
native code loses, and a Dask cluster for `--cluster`."""

import os
import signal
import time
from dataclasses import dataclass
from pathlib import Path

import pytest

SHARED = Path(__file__).resolve().parents[1].parent / "shared"
LUMBAR_C_210 = SHARED / "reference" / "lumbar_c_210" / "Lumbar_C_210.osim"


@pytest.fixture(scope="session")
def lumbar_c210_path():
    """Path of the original OpenSim lumbar model; skips when absent or opensim is missing."""
    pytest.importorskip("opensim", reason="OpenSim 4.6 (pip opensim) is needed for this oracle test")
    if not LUMBAR_C_210.exists():
        pytest.skip(f"oracle model not found at {LUMBAR_C_210} (the repository's ../shared folder)")
    return LUMBAR_C_210


@pytest.fixture
def ctrl_c_raises():
    """SIGINT raises KeyboardInterrupt while the test runs, as on a terminal (pytest run in the background ignores
    it); the caller's handler is put back after."""
    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, before)


@pytest.fixture
def lose_a_ctrl_c(ctrl_c_raises):
    """A call that receives a real Ctrl-C and loses it, as pybind11 converting an argument for Drake does, then raises
    TypeError(message)."""

    def lose(message: str = "incompatible function arguments"):
        lost = False
        try:
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(5.0)  # the handler runs here
        except KeyboardInterrupt:
            lost = True
        assert lost, "no SIGINT arrived"
        raise TypeError(message)

    return lose


@dataclass
class DaskCluster:
    address: str  # what `--cluster` takes
    scheduler: object

    def jobs_done(self) -> int:
        """How many worker-pool jobs (`trunk_drake.parallel._run`, Dask keys "_run-...") the cluster has finished."""
        prefix = self.scheduler.task_prefixes.get("run")
        return 0 if prefix is None else prefix.state_counts["memory"]


@pytest.fixture
def dask_cluster():
    """A Dask cluster in this process (one worker, one thread), for the commands' `--cluster ADDRESS`."""
    distributed = pytest.importorskip("dask.distributed")
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None) as cluster:
        yield DaskCluster(cluster.scheduler_address, cluster.scheduler)
