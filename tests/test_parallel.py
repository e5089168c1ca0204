"""The one worker pool: models rebuilt in the workers, results in order, errors and Ctrl-C."""

from __future__ import annotations

import multiprocessing
import os
import time

import numpy as np
import pytest

from trunk_drake.model.trunk_model import load_model
from trunk_drake.parallel import WorkerPool, caused_by_interrupt, still_running


@pytest.fixture(scope="module")
def sagittal():
    return load_model("sagittal")


def _lengths(model, q):
    return os.getpid(), model.muscle_lengths(np.asarray(q))


def _fails(model, job):
    raise ValueError(f"job {job} failed")


def _sleeps(model, seconds):
    time.sleep(seconds)
    return os.getpid()


def test_workers_rebuild_the_model_and_keep_the_order(sagittal):
    poses = [np.full(len(sagittal.coordinates), 0.01 * k) * (np.arange(len(sagittal.coordinates)) > 0) for k in range(6)]
    with WorkerPool(sagittal, workers=2) as pool:
        results = pool.map(_lengths, poses)
    assert {pid for pid, _ in results} - {os.getpid()}, "the jobs ran in worker processes"
    for q, (_, lengths) in zip(poses, results):
        assert np.allclose(lengths, sagittal.muscle_lengths(q), rtol=0, atol=1e-12)
    with WorkerPool(sagittal, workers=1) as pool:  # in this process, on the caller's model
        assert {pid for pid, _ in pool.map(_lengths, poses[:2])} == {os.getpid()}


def test_a_pool_runs_as_many_jobs_at_once_as_it_has_workers_or_the_cluster_has_threads(sagittal):
    """`WorkerPool.capacity`: how the fits split a Jacobian's points into jobs (`optim.fit.point_jobs`)."""
    assert WorkerPool(sagittal, workers=1).capacity == 1 and WorkerPool(sagittal, workers=3).capacity == 3
    distributed = pytest.importorskip("dask.distributed")
    with distributed.LocalCluster(n_workers=3, threads_per_worker=1, processes=False, dashboard_address=None) as cluster:
        with WorkerPool(sagittal, workers=1, cluster=cluster.scheduler_address) as pool:
            assert pool.parallel and pool.capacity == 3


@pytest.mark.parametrize("workers", [1, 2])
def test_a_job_error_reaches_the_caller(sagittal, workers):
    with WorkerPool(sagittal, workers=workers) as pool:
        outcomes = sorted(pool.completed(_fails, [1, 2]), key=lambda o: o[0])
        assert [str(error) for _, _, error in outcomes] == ["job 1 failed", "job 2 failed"]
        with pytest.raises(ValueError, match="job 1 failed"):
            pool.map(_fails, [1])


def _interval(model, seconds):
    start = time.time()
    time.sleep(seconds)
    return start, time.time()


def test_concurrent_searches_share_the_workers(sagittal):
    """`concurrently`: independent callers, each mapping one job at a time, keep both workers busy at once;
    results in order, the first error raised; without workers one after another in this process."""
    with WorkerPool(sagittal, workers=2) as pool:
        (a0, a1), (b0, b1) = pool.concurrently([lambda: pool.map(_interval, [1.0])[0], lambda: pool.map(_interval, [1.0])[0]])
        assert a0 < b1 and b0 < a1, "the two jobs ran at the same time"
        with pytest.raises(ValueError, match="job 2 failed"):
            pool.concurrently([lambda: pool.map(_lengths, [np.zeros(len(sagittal.coordinates))]), lambda: pool.map(_fails, [2])])
    with WorkerPool(sagittal, workers=1) as pool:
        order = []
        assert pool.concurrently([lambda: order.append(1) or "a", lambda: order.append(2) or "b"]) == ["a", "b"]
        assert order == [1, 2]


def test_leaving_the_pool_by_an_exception_ends_running_jobs_at_once(sagittal):
    start = time.perf_counter()
    with pytest.raises(KeyboardInterrupt):
        with WorkerPool(sagittal, workers=2) as pool:
            for _ in pool.completed(_sleeps, [0.1, 60.0]):
                processes = list(pool._executor._processes.values())
                raise KeyboardInterrupt  # as a Ctrl-C in the parent would
    assert time.perf_counter() - start < 30.0  # model builds included; the 60 s job did not run out
    assert not still_running(processes, timeout=0.0)  # exited (is_alive can race the executor's reaping)


def test_a_ctrl_c_while_the_pool_closes_leaves_no_worker_behind(sagittal):
    """The last job done, the pool shuts its workers down; a Ctrl-C then (seen in CI: a `reproduce` sweep
    interrupted at its end left a sleeping worker, or two unreaped ones) still stops and reaps them all."""
    with pytest.raises(KeyboardInterrupt):
        with WorkerPool(sagittal, workers=2) as pool:
            pool.map(_sleeps, [0.0, 0.0])
            processes = list(pool._executor._processes.values())

            def interrupted(*args, **kwargs):
                raise KeyboardInterrupt  # as a Ctrl-C in the shutdown's wait would, the workers not yet told to exit
            pool._executor.shutdown = interrupted
    assert not still_running(processes, timeout=0.0), "the workers were stopped"
    assert not _active_children_after(5.0)
    for process in processes:  # reaped: no zombie left to the machine's init
        with pytest.raises(ChildProcessError):
            os.waitpid(process.pid, os.WNOHANG)


def _active_children_after(timeout: float) -> list:
    """`multiprocessing.active_children()` once it is empty, or after `timeout` s: a child the executor's own thread
    is reaping counts as alive between its `waitpid` and the return code's assignment (CI, 4b1016f: one such
    ForkProcess listed right after the pool had stopped and reaped every worker)."""
    deadline = time.monotonic() + timeout
    while (children := multiprocessing.active_children()) and time.monotonic() < deadline:
        time.sleep(0.05)
    return children


def _raised_from(cause: BaseException) -> BaseException:
    try:
        try:
            raise cause
        except BaseException as inner:
            raise SystemError("returned a result with an exception set") from inner
    except SystemError as outer:
        return outer


def test_a_ctrl_c_rewrapped_by_native_code_is_still_an_interrupt():
    assert caused_by_interrupt(KeyboardInterrupt())
    assert caused_by_interrupt(_raised_from(KeyboardInterrupt()))  # as numba re-raises it inside a kernel call
    assert not caused_by_interrupt(_raised_from(ValueError("bad input")))
    assert not caused_by_interrupt(None)


def test_an_unraisable_interrupt_is_quiet_and_other_errors_are_reported():
    from types import SimpleNamespace

    from trunk_drake.cli import _quiet_interrupts

    reported = []
    for error in (KeyboardInterrupt(), _raised_from(KeyboardInterrupt()), _raised_from(ValueError("bad input"))):
        _quiet_interrupts(SimpleNamespace(exc_type=type(error), exc_value=error), report=reported.append)
    assert [str(u.exc_value) for u in reported] == ["returned a result with an exception set"]


def test_a_serial_pool_stops_on_a_ctrl_c_that_a_job_lost(sagittal, lose_a_ctrl_c):
    """With one worker a job's error is returned like a worker's; after a noted Ctrl-C it is the interruption."""
    from trunk_drake.parallel import noting_interrupts

    def job(model, _):
        lose_a_ctrl_c()

    with noting_interrupts(), WorkerPool(sagittal, workers=1) as pool:
        with pytest.raises(KeyboardInterrupt):
            pool.map(job, [None])
    with WorkerPool(sagittal, workers=1) as pool:  # outside, a job's TypeError is its own
        with pytest.raises(TypeError):
            pool.map(job, [None])


def test_a_ctrl_c_another_thread_receives_while_the_workers_fork_waits_until_the_pool_knows_them(
        sagittal, monkeypatch, ctrl_c_raises):
    """SIGINT is blocked in the main thread while the pool forks its workers, but another thread of the process can
    receive it, and Python then raises KeyboardInterrupt in the main thread at its next bytecode, possibly between a
    worker's fork and the pool's record of it (CI: a worker left running after `reproduce` was interrupted on a loaded
    machine). The Ctrl-C is held until every job is submitted, then raised; no worker is left behind."""
    import signal
    import threading
    from concurrent.futures import ProcessPoolExecutor

    submitted, real_submit = [], ProcessPoolExecutor.submit

    def submit(executor, *args, **kwargs):
        if not submitted:  # a Ctrl-C reaches another thread while the first job's workers are being started
            sender = threading.Thread(target=os.kill, args=(os.getpid(), signal.SIGINT))
            sender.start()
            sender.join()
            time.sleep(0.05)  # bytecodes run here: Python's handler would raise now
        future = real_submit(executor, *args, **kwargs)
        submitted.append(True)
        return future

    monkeypatch.setattr(ProcessPoolExecutor, "submit", submit)
    with pytest.raises(KeyboardInterrupt):
        with WorkerPool(sagittal, workers=2) as pool:
            pool.map(_sleeps, [0.0, 0.0])
    assert submitted == [True, True], "the Ctrl-C waited until both jobs were submitted"
    assert not _active_children_after(5.0)
