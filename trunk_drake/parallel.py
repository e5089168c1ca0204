"""The one worker pool: jobs on local processes or a Dask cluster, the model rebuilt once per worker.

Drake objects cannot be pickled, so a worker receives the model's recipe (`ModelRecipe`: spec
and `load_model` options) and builds the model once; a job is a module-level function
``fn(model, job)`` with a picklable job and result. With one worker (and no cluster) the jobs run
in this process on the caller's model.

Ctrl-C is the parent's business: local workers ignore SIGINT (a terminal sends it to the whole
process group), and a pool left by an exception (KeyboardInterrupt included) terminates its
workers at once instead of letting them finish their jobs; a Ctrl-C while the pool closes, after
its last job, also stops and reaps every worker.
"""

from __future__ import annotations

import contextlib
import hashlib
import multiprocessing
import pickle
import signal
import threading
import time
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from multiprocessing.connection import wait as connection_wait

_MODELS: dict = {}  # per worker process: recipe key -> TrunkModel
_SIGINTS: list[int] = []  # the Ctrl-Cs noted in this process (`noting_interrupts`)
_LOCK = threading.Lock()  # threads of one worker (Dask processes=False) run jobs one at a time


class WorkerLost(RuntimeError):
    """A worker died while running a job (out of memory, a crash in native code)."""


@dataclass(frozen=True)
class ModelRecipe:
    """What a worker needs to rebuild a TrunkModel: its spec and `load_options`."""

    spec: object
    options: dict
    key: str  # hash of both: workers cache their models by it

    @classmethod
    def of(cls, model) -> "ModelRecipe":
        parts = (model.spec, model.load_options)
        return cls(*parts, hashlib.sha256(pickle.dumps(parts)).hexdigest()[:16])

    def build(self):
        from trunk_drake.model.trunk_model import load_model

        return load_model(spec=self.spec, **self.options)


def worker_model(recipe: ModelRecipe):
    """The model of `recipe`, built once per worker process."""
    key = recipe.key
    if key not in _MODELS:
        _MODELS[key] = recipe.build()
    return _MODELS[key]


def _init_local(recipe: ModelRecipe) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    worker_model(recipe)


def _run(fn, recipe: ModelRecipe, job):
    with _LOCK:  # pybind11, under pydrake, is not thread-safe everywhere
        return fn(worker_model(recipe), job)


def caused_by_interrupt(error: BaseException | None) -> bool:
    """True for a Ctrl-C, also when native code (numba, a Drake callback) re-raised it as another
    exception (SystemError "returned a result with an exception set") with the KeyboardInterrupt as cause, and for
    any error after a Ctrl-C that `noting_interrupts` noted: one landing while pybind11 converts an argument for
    Drake is lost there and comes out as an unrelated error (TypeError "incompatible function arguments")."""
    if _SIGINTS:
        return True
    seen = set()
    while error is not None and id(error) not in seen:
        if isinstance(error, KeyboardInterrupt):
            return True
        seen.add(id(error))
        error = error.__cause__ or error.__context__
    return False


def _note_sigint(signum, frame):
    _SIGINTS.append(signum)
    signal.default_int_handler(signum, frame)  # KeyboardInterrupt, as Python's own handler


def _own_sigint_handler():
    """The SIGINT handler this thread may replace: None outside the main thread (only it can set one) or where SIGINT
    is ignored (a background job's stays ignored)."""
    if threading.current_thread() is not threading.main_thread():
        return None
    handler = signal.getsignal(signal.SIGINT)
    return None if handler in (None, signal.SIG_IGN) else handler


@contextlib.contextmanager
def noting_interrupts():
    """Inside, every Ctrl-C is noted before it raises KeyboardInterrupt, for `caused_by_interrupt`; the notes are
    forgotten on leaving. Yields whether it listens: only the main thread can, and an ignored SIGINT (a background
    job's) stays ignored."""
    previous = _own_sigint_handler()
    listening, start = previous is not None, len(_SIGINTS)
    try:
        if listening:
            signal.signal(signal.SIGINT, _note_sigint)
        yield listening
    finally:
        if listening:
            signal.signal(signal.SIGINT, previous)
            del _SIGINTS[start:]


class WorkerPool:
    """Runs ``fn(model, job)`` for many jobs: in this process (workers <= 1), on `workers` local
    processes, or on the Dask cluster at `cluster` (e.g. "tcp://host:8786"). Use as a context
    manager; the workers start on the first job."""

    def __init__(self, model, workers: int = 2, cluster: str | None = None):
        self.model, self.workers, self.cluster = model, workers, cluster
        self.recipe = ModelRecipe.of(model)
        self._executor = self._client = self._recipe_future = None
        self._starting = threading.Lock()  # `concurrently`'s threads may start the workers together

    @property
    def parallel(self) -> bool:
        return bool(self.cluster) or self.workers > 1

    @property
    def capacity(self) -> int:
        """How many jobs run at once: the local workers (1: in this process), or the cluster's worker threads."""
        if self.cluster:
            return max(1, sum(self._connect().nthreads().values()))
        return max(1, self.workers)

    def _connect(self):
        """The Dask client, connected (and the recipe sent to every worker) on first use."""
        from dask.distributed import Client

        with self._starting:
            if self._client is None:
                self._client = Client(self.cluster)
                self._recipe_future = self._client.scatter(self.recipe, broadcast=True)
        return self._client

    def __enter__(self) -> "WorkerPool":
        return self

    def __exit__(self, kind, error, tb) -> None:
        try:
            self.close(terminate=kind is not None)
        except BaseException as stopped:  # e.g. a Ctrl-C while the workers shut down after the last job
            error = stopped
            raise
        finally:
            if caused_by_interrupt(error):  # Ctrl-C: no child process may outlive us, running or exited
                _stop(multiprocessing.active_children())

    def concurrently(self, calls) -> list:
        """The results of the zero-argument `calls`, in order, each run in its own thread of this process while
        they map jobs to this pool: independent sequential searches (each waiting on its few jobs at a time)
        then keep every worker busy. Without workers (or a cluster) one after another: the jobs run in this
        process, and Drake's objects are not thread-safe. The first exception is raised here."""
        calls = list(calls)
        if not self.parallel or len(calls) < 2:
            return [call() for call in calls]
        from concurrent.futures import ThreadPoolExecutor

        threads = ThreadPoolExecutor(len(calls), thread_name_prefix="concurrently")
        try:
            futures = [threads.submit(call) for call in calls]
            return [future.result() for future in futures]
        finally:  # on an error (Ctrl-C too) the others are not awaited: the pool's exit stops their jobs
            threads.shutdown(wait=False, cancel_futures=True)

    def map(self, fn, jobs) -> list:
        """Results of all jobs, in order; a worker's exception is raised here."""
        jobs = list(jobs)
        results = [None] * len(jobs)
        for i, result, error in self.completed(fn, jobs):
            if error is not None:
                raise error
            results[i] = result
        return results

    def completed(self, fn, jobs):
        """Yields (index, result, None) as jobs finish, or (index, None, error) for a job that
        raised (on Dask also for a job whose worker died); a broken local pool raises `WorkerLost`."""
        jobs = list(jobs)
        if not self.parallel:
            for i, job in enumerate(jobs):
                try:
                    result = fn(self.model, job)
                except Exception as err:  # noqa: BLE001 - as from a worker
                    if caused_by_interrupt(err):  # a Ctrl-C that native code turned into another error
                        raise KeyboardInterrupt from err
                    yield i, None, err
                else:
                    yield i, result, None
        elif self.cluster:
            yield from self._dask(fn, jobs)
        else:
            yield from self._local(fn, jobs)

    def _local(self, fn, jobs):
        with self._starting:
            if self._executor is None:
                self._executor = ProcessPoolExecutor(self.workers, mp_context=multiprocessing.get_context("fork"),
                                                     initializer=_init_local, initargs=(self.recipe,))
        key = self.recipe.key
        # SIGINT is blocked while the workers are forked: the workers, which inherit the mask, ignore it before
        # unblocking it; and a Ctrl-C that another thread of this process receives meanwhile is held back until
        # the workers are known to the pool (`_held_sigint`), so none is left behind unstopped
        previous = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
        try:
            with _held_sigint():
                futures = {self._executor.submit(_run_local, fn, key, job): i for i, job in enumerate(jobs)}
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, previous)
        pending = set(futures)
        while pending:
            done, pending = wait(pending, return_when=FIRST_COMPLETED)
            for future in done:
                try:
                    yield futures[future], future.result(), None
                except BrokenProcessPool as err:
                    raise WorkerLost("a worker process died (out of memory or a crash in native code)") from err
                except Exception as err:  # noqa: BLE001 - the job's own error goes to the caller
                    yield futures[future], None, err

    def _dask(self, fn, jobs):
        from dask.distributed import as_completed

        futures = self._connect().map(_run, [fn] * len(jobs), [self._recipe_future] * len(jobs), jobs, pure=False)
        index = {f.key: i for i, f in enumerate(futures)}
        for future in as_completed(futures):
            try:
                yield index[future.key], future.result(), None
            except Exception as err:  # noqa: BLE001 - the job's error, or the worker running it died
                yield index[future.key], None, err

    def close(self, terminate: bool = False) -> None:
        """Stop the workers; `terminate` kills running jobs instead of waiting for them."""
        if self._executor is not None:
            processes = list((self._executor._processes or {}).values())
            self._executor.shutdown(wait=not terminate, cancel_futures=True)
            if terminate:
                _stop(processes)
            self._executor = None
        if self._client is not None:
            self._client.close()
            self._client = None


@contextlib.contextmanager
def _held_sigint():
    """Inside (main thread only), a Ctrl-C is held back and raised on leaving. Blocking SIGINT in one thread does not
    keep Python's handler out of it: a signal another thread receives still raises KeyboardInterrupt in the main
    thread at its next bytecode, which could fall between a worker's fork and the pool's record of it (a worker
    left running after `reproduce` was interrupted, on a loaded machine)."""
    if not callable(_own_sigint_handler()):  # none to defer (SIG_DFL ends the process at once, as it would)
        yield
        return
    held = []
    previous = signal.signal(signal.SIGINT, lambda signum, frame: held.append((signum, frame)))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        if held:
            previous(*held[0])


def _stop(processes) -> None:
    """Terminate `processes`, wait until they have exited and reap them; one still running 2 s after
    SIGTERM (a loaded machine) is killed. Exit is read from each process's sentinel: `is_alive` reports a
    process as alive when the executor's own thread has just reaped it."""
    processes = list(processes)
    for process in processes:
        process.terminate()
    for process in still_running(processes, timeout=2.0):
        process.kill()
    left = still_running(processes, timeout=5.0)
    for process in processes:  # reap: a zombie left to init keeps the process group alive until init waits for it
        if process not in left:
            process.join(timeout=1.0)


def still_running(processes, timeout: float) -> list:
    """Those of `processes` that have not exited within `timeout` seconds."""
    left = {process.sentinel: process for process in processes}
    deadline = time.monotonic() + timeout
    while left:
        for sentinel in connection_wait(list(left), max(deadline - time.monotonic(), 0.0)):
            del left[sentinel]
        if time.monotonic() >= deadline:
            break
    return list(left.values())


def _run_local(fn, key, job):
    return fn(_MODELS[key], job)
