"""A diagnosis' refit simulations written to disk as they finish, so that an interrupted diagnosis (Ctrl-C, the end
of a session, a lost worker) resumes where it stopped: rerun with the same inputs and code, it takes the logged
simulations instead of running them again, and goes on from there with what it would have done.

The file is a stream of pickles: a header (format and identity), then one record per batch of simulations (the
wall time the diagnosis had run when it was written, summed over its interrupted runs, and the keys and results
`TimeDomainFitter` caches). A record cut short by the interruption is dropped on loading. The identity hashes
everything the results depend on (code, model, data, settings); a log of another identity is started afresh."""

from __future__ import annotations

import hashlib
import pickle
import threading
import time
from pathlib import Path

import numpy as np

from trunk_drake.metadata import model_fingerprint, source_fingerprint

FORMAT = 2
LOG_NAME = "simulations.pickle"  # the log's name in a diagnosis' output folder (a benchmark case's: beside progress.log)


def diagnosis_identity(model, options, data, noise, outputs, candidates, settings) -> str:
    """SHA-256 (16 hex digits) of what a diagnosis' simulations depend on: the code, the model, the nominal options,
    the prepared trials (samples, platform, timing), the noise, the outputs, the candidates and the search settings."""
    h = hashlib.sha256()
    h.update(f"{source_fingerprint()}|{model_fingerprint(model)}|{list(outputs)}|{[c.name for c in candidates]}|{settings}".encode())
    h.update(pickle.dumps(options))
    h.update(np.asarray(noise, float).tobytes())
    for t in data:
        h.update(f"{t.name}|{t.fs}|{t.period}|{t.steady_start}".encode())
        for array in (t.time, t.platform, *t.outputs.values()):
            h.update(b"-" if array is None else np.ascontiguousarray(array, float).tobytes())
    return h.hexdigest()[:16]


class SimulationLog:
    """The simulations logged at `path` for the diagnosis `identity` (`entries`: key -> result, the records that were
    read whole), and the place the next ones are appended (`add`). `fresh_because`: why an existing file was not
    used (another identity, or unreadable), else None. `earlier_wall_s`: the wall time the interrupted runs had
    spent up to their last whole record (0 for a new log)."""

    def __init__(self, path, identity: str):
        self.path, self.identity = Path(path), identity
        self._lock = threading.Lock()  # the fits of a diagnosis run in threads (`WorkerPool.concurrently`)
        self._file, self._opened = None, time.perf_counter()
        self.entries, self.earlier_wall_s, self._end, self.fresh_because = self._read()

    def _read(self) -> tuple[dict, float, int, str | None]:
        """(entries, the wall time at the last whole record, the offset after it or 0 for a new file, why an existing
        file is not used)."""
        if not self.path.exists():
            return {}, 0.0, 0, None
        entries, wall, end = {}, 0.0, 0
        with self.path.open("rb") as f:
            try:
                header = pickle.load(f)
            except Exception:  # noqa: BLE001 - any unreadable start: not a log of this diagnosis
                header = None
            if header != {"format": FORMAT, "identity": self.identity}:
                return {}, 0.0, 0, "it was written by another diagnosis (other data, settings, model or code)"
            end = f.tell()
            while True:
                try:
                    wall, results = pickle.load(f)
                except Exception:  # noqa: BLE001 - the end, or a record cut short by the interruption
                    break
                entries.update(results)
                end = f.tell()
        return entries, wall, end, None

    def add(self, results: dict) -> None:
        """Append one record (key -> result, with the wall time so far) and flush it to the file."""
        with self._lock:
            if self._file is None:
                self.path.parent.mkdir(parents=True, exist_ok=True)
                if self._end:  # go on after the last whole record
                    self._file = self.path.open("r+b")
                    self._file.seek(self._end)
                    self._file.truncate()
                else:
                    self._file = self.path.open("wb")
                    pickle.dump({"format": FORMAT, "identity": self.identity}, self._file)
            wall = self.earlier_wall_s + time.perf_counter() - self._opened
            pickle.dump((wall, results), self._file, protocol=pickle.HIGHEST_PROTOCOL)
            self._file.flush()

    def take(self, keys) -> dict:
        """The logged results of those of `keys` that were logged, removed from `entries` (the caller keeps them)."""
        with self._lock:
            return {k: self.entries.pop(k) for k in keys if k in self.entries}

    def __enter__(self) -> "SimulationLog":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        with self._lock:
            if self._file is not None:
                self._file.close()
                self._file = None
