"""strength-batch: isometric strength over a grid of cases, in parallel, resumable.

A grid file (TOML) has ``[defaults]`` (parameters of every case), ``[grid]`` (lists whose
Cartesian product makes the cases) and optional ``[[cases]]`` (explicit extra cases, merged
onto the defaults). Case parameters (CASE_DEFAULTS): direction, strength_scale,
min_activation, p, include_passive, level (thoracic landmarks carrying the sagittal load),
shoulder ("model" | "acromion"), lumbar_flexion_deg (total lumbar flexion, spread equally
over the five levels, or along the rhythm), sweep, step, dofs ("spine3d", "sagittal", "rhythm").

Runs on trunk_drake.parallel's worker pool: local processes or an existing Dask distributed
cluster (``cluster="tcp://host:8786"``), each worker building its model once. Workers receive
parameter dicts and return plain rows. Each finished case is appended to
``<out>/results.jsonl`` at once; a rerun skips cases already there (``retry_failed`` reruns
the failed ones); a failing case records its error and the batch goes on.
``<out>/results.csv`` is rewritten from all rows at the end.
"""

from __future__ import annotations

import csv
import hashlib
import itertools
import json
import os
import socket
import time
import tomllib
from pathlib import Path

import numpy as np

from trunk_drake.metadata import json_default
from trunk_drake.model.levels import LEVELS
from trunk_drake.model.plant import DOFS
from trunk_drake.parallel import WorkerLost, WorkerPool, caused_by_interrupt

CASE_DEFAULTS = {
    "direction": "extension", "strength_scale": 1.0, "min_activation": 0.01, "p": 2.0, "include_passive": True,
    "level": ["T6", "T7"], "shoulder": "model", "lumbar_flexion_deg": 0.0, "sweep": False, "step": 10.0, "dofs": "spine3d",
}
RESULTS = "results.jsonl"


# ---------------------------------------------------------------------------- cases

def case_id(params: dict) -> str:
    """Stable identifier of a case: hash of its parameters."""
    return hashlib.sha1(json.dumps(params, sort_keys=True).encode()).hexdigest()[:12]


def _case(params: dict, where: str) -> dict:
    _check_keys(params, where)
    case = {**CASE_DEFAULTS, **params}
    if case["dofs"] not in DOFS:
        raise ValueError(f"{where}: dofs = {case['dofs']!r}; expected one of {DOFS}")
    return {"case_id": case_id(case), **case}


def _check_keys(params: dict, where: str) -> None:
    unknown = set(params) - set(CASE_DEFAULTS)
    if unknown:
        raise ValueError(f"{where}: unknown case parameter(s) {sorted(unknown)}; known: {sorted(CASE_DEFAULTS)}")


def load_grid(path) -> list[dict]:
    """The cases of a grid file, in a stable order, each with its ``case_id``."""
    path = Path(path)
    if not path.is_file():
        raise (ValueError if path.exists() else FileNotFoundError)(
            f"grid {path} is {'not a file' if path.exists() else 'missing'}: give a grid file (TOML), "
            "e.g. models/strength_grid_example.toml")
    try:
        spec = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as err:
        raise ValueError(f"{path} is not valid TOML: {err}") from None
    unknown = set(spec) - {"defaults", "grid", "cases"}
    if unknown:
        raise ValueError(f"{path}: unknown section(s) {sorted(unknown)}; expected [defaults], [grid], [[cases]]")
    defaults = spec.get("defaults", {})
    grid = spec.get("grid", {})
    _check_keys(defaults, f"{path} [defaults]")
    _check_keys(grid, f"{path} [grid]")
    for key, values in grid.items():
        if not isinstance(values, list) or not values:
            raise ValueError(f"{path}: [grid] {key} must be a non-empty list, got {values!r}")
    cases = [_case({**defaults, **dict(zip(grid, combo))}, str(path)) for combo in itertools.product(*grid.values())] if grid else []
    cases += [_case({**defaults, **extra}, f"{path} [[cases]] #{i + 1}") for i, extra in enumerate(spec.get("cases", []))]
    if not cases:
        raise ValueError(f"{path} defines no cases: add a [grid] table or [[cases]]")
    ids = [c["case_id"] for c in cases]
    if len(set(ids)) != len(ids):
        raise ValueError(f"{path}: some cases are identical; each case must differ in at least one parameter")
    return cases


# ------------------------------------------------------------------------ worker side

def run_case(model, case: dict) -> dict:
    """Compute one case on `model` (of the case's dofs); never raises: a failure becomes an error row."""
    from trunk_drake.optim.strength import isometric_strength

    start = time.perf_counter()
    row = _row(case, worker=f"{socket.gethostname()}:{os.getpid()}")
    try:
        q = model.posture(np.radians(case["lumbar_flexion_deg"]))
        result = isometric_strength(
            model, (case["direction"],), q=q, level=tuple(case["level"]), shoulder=case["shoulder"], sweep=case["sweep"],
            step=case["step"], p=case["p"], min_activation=case["min_activation"],
            strength_scale=case["strength_scale"], include_passive=case["include_passive"],
        )[case["direction"]]
        row.update(status="ok", error=None, max_force_N=result.max_force, min_feasible_force_N=result.min_force,
                   limiting_coordinate=result.limiting_coordinate,
                   muscles_at_upper_bound=len(result.muscles_at_upper_bound), sweep_last_feasible_N=result.sweep_force,
                   sweep_solves=result.sweep_solves, sweep_parity=result.parity)
    except Exception as err:  # noqa: BLE001 - any failure is recorded and the batch goes on
        if caused_by_interrupt(err):  # a Ctrl-C that native code turned into another error: no failure to record
            raise KeyboardInterrupt from err
        row.update(status="error", error=f"{type(err).__name__}: {err}")
    row["time_s"] = time.perf_counter() - start
    return row


def _row(case: dict, **fields) -> dict:
    return {"case_id": case["case_id"], "params": {k: v for k, v in case.items() if k != "case_id"}, **fields}


# ------------------------------------------------------------------------ bookkeeping

def read_rows(out_dir) -> list[dict]:
    """Rows of ``results.jsonl``; a torn last line (interrupted write) is dropped from the file."""
    path = Path(out_dir) / RESULTS
    if not path.exists():
        return []
    rows, good = [], []
    for line in path.read_text().splitlines():
        try:
            rows.append(json.loads(line))
            good.append(line)
        except json.JSONDecodeError:
            continue
    path.write_text("".join(line + "\n" for line in good))
    return rows


def write_csv(rows: list[dict], out_dir) -> Path:
    """Flatten rows (params become columns) into ``results.csv``."""
    flat = [{**{k: v for k, v in r.items() if k != "params"}, **{f"param_{k}": json.dumps(v) if isinstance(v, list) else v
                                                                   for k, v in r.get("params", {}).items()}} for r in rows]
    fields = list(dict.fromkeys(k for r in flat for k in r))
    path = Path(out_dir) / "results.csv"
    with path.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=fields)
        writer.writeheader()
        writer.writerows(flat)
    return path


# ---------------------------------------------------------------------------- runner

def run_batch(cases: list[dict], out_dir, cluster: str | None = None, workers: int | None = None,
              progress: bool = True, retry_failed: bool = False) -> dict:
    """Run the cases not yet in ``<out_dir>/results.jsonl``; returns counts (``failed``: in this
    run, ``failed_total``: among all the cases' rows) and the output paths."""
    from tqdm import tqdm

    from trunk_drake.model.trunk_model import load_model

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rows = read_rows(out)
    if retry_failed:
        rows = [r for r in rows if r.get("status") == "ok"]
        (out / RESULTS).write_text("".join(json.dumps(r, default=json_default) + "\n" for r in rows))
    done = {r["case_id"] for r in rows}
    pending = [c for c in cases if c["case_id"] not in done]
    counts = {"cases": len(cases), "already_done": len(cases) - len(pending), "ran": 0, "ok": 0, "failed": 0}
    with (out / RESULTS).open("a") as sink, tqdm(total=len(pending), desc="strength-batch", disable=not progress) as bar:
        def record(row):
            sink.write(json.dumps(row, default=json_default) + "\n")
            sink.flush()
            rows.append(row)
            counts["ran"] += 1
            counts["ok" if row["status"] == "ok" else "failed"] += 1
            bar.update(1)

        for dofs in sorted({c["dofs"] for c in pending}):
            _run(load_model(dofs=dofs), [c for c in pending if c["dofs"] == dofs], record, cluster, workers)
    wanted = {c["case_id"] for c in cases}
    counts.update(failed_total=sum(r["status"] != "ok" for r in rows if r["case_id"] in wanted),
                  results=str(out / RESULTS), csv=str(write_csv(rows, out)))
    return counts


def _run(model, cases, record, cluster, workers) -> None:
    workers = workers or min(len(cases), os.cpu_count() or 1)
    try:
        with WorkerPool(model, workers, cluster) as pool:
            for i, row, error in pool.completed(run_case, cases):
                record(row if error is None else _row(cases[i], status="error",
                                                      error=f"worker lost: {type(error).__name__}: {error}"))
    except WorkerLost as err:
        raise RuntimeError(f"{err}; finished cases are saved: rerun to resume, with --workers 1 to find the case "
                           "if it recurs") from err
