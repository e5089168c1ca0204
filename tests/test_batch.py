"""strength-batch: grid parsing, local process pool, failure rows, resume, Dask."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from trunk_drake.batch import CASE_DEFAULTS, RESULTS, _case, load_grid, read_rows, run_batch

EXAMPLE = Path(__file__).resolve().parents[1] / "models" / "strength_grid_example.toml"
FAILING = _case({"direction": "sideways"}, "test")  # deliberately failing case


def test_example_grid_has_at_least_20_distinct_cases():
    cases = load_grid(EXAMPLE)
    assert len(cases) >= 20 and len({c["case_id"] for c in cases}) == len(cases)
    assert all(set(c) == set(CASE_DEFAULTS) | {"case_id"} for c in cases)


def test_grid_errors_are_clear(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('[grid]\ndirection = ["extension"]\nstrenght_scale = [1.0]\n')
    with pytest.raises(ValueError, match="strenght_scale"):
        load_grid(bad)
    bad.write_text('[grid]\ndirection = "extension"\n')
    with pytest.raises(ValueError, match="non-empty list"):
        load_grid(bad)


def test_local_batch_survives_a_failure_and_resumes(tmp_path):
    cases = load_grid(EXAMPLE) + [FAILING]
    counts = run_batch(cases, tmp_path, workers=2, progress=False)
    assert counts["ran"] == len(cases) and counts["failed"] >= 1
    rows = read_rows(tmp_path)
    assert sorted(r["case_id"] for r in rows) == sorted(c["case_id"] for c in cases)
    failed = next(r for r in rows if r["case_id"] == FAILING["case_id"])
    assert failed["status"] == "error" and "sideways" in failed["error"]
    ok = [r for r in rows if r["status"] == "ok"]
    assert len(ok) >= 20 and all(r["max_force_N"] > 0 for r in ok)
    assert (tmp_path / "results.csv").read_text().count("\n") == len(cases) + 1

    # an interrupted run: 10 rows and a torn line survive; the rerun does only the rest
    lines = (tmp_path / RESULTS).read_text().splitlines()
    (tmp_path / RESULTS).write_text("\n".join(lines[:10]) + "\n" + lines[10][:40])
    again = run_batch(cases, tmp_path, workers=2, progress=False)
    assert again["already_done"] == 10 and again["ran"] == len(cases) - 10
    assert sorted(r["case_id"] for r in read_rows(tmp_path)) == sorted(c["case_id"] for c in cases)
    assert run_batch(cases, tmp_path, progress=False)["ran"] == 0
    assert run_batch(cases, tmp_path, progress=False, retry_failed=True)["ran"] == counts["failed"]


def test_cli_batch_interrupted_then_resumed(tmp_path):
    grid = tmp_path / "grid.toml"
    grid.write_text('[defaults]\nsweep = true\n[grid]\ndirection = ["extension", "lateral"]\n'
                    'strength_scale = [1.0, 1.1, 1.2, 1.3, 1.4, 1.5]\n')
    out = tmp_path / "out"
    command = [sys.executable, "-m", "trunk_drake.cli", "strength-batch", str(grid), "--out", str(out), "--workers", "1", "--no-progress"]
    # a terminal's Ctrl-C; the child must not inherit an ignored SIGINT (as under `nohup ... &`)
    proc = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, start_new_session=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    results = out / RESULTS
    deadline = time.time() + 60
    while time.time() < deadline and (not results.exists() or results.read_text().count("\n") < 2):
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGINT)  # Ctrl-C: the main process and its worker
    proc.communicate(timeout=60)
    partial = read_rows(out)
    assert 2 <= len(partial) < 12, "the batch should have been interrupted part-way"
    done = subprocess.run(command, capture_output=True, text=True, timeout=120, check=True)
    counts = json.loads(done.stdout)
    assert counts["already_done"] == len(partial) and counts["ran"] == 12 - len(partial)
    rows = read_rows(out)
    assert len(rows) == 12 and len({r["case_id"] for r in rows}) == 12
    assert all(r["status"] == "ok" and r["sweep_parity"] for r in rows)


def test_dask_local_cluster(tmp_path):
    distributed = pytest.importorskip("dask.distributed")
    cases = load_grid(EXAMPLE)[:6] + [FAILING]
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False, dashboard_address=None) as cluster:
        counts = run_batch(cases, tmp_path, cluster=cluster.scheduler_address, progress=False)
    rows = {r["case_id"]: r for r in read_rows(tmp_path)}
    assert counts["ran"] == len(cases) and counts["failed"] == 1, [r["error"] for r in rows.values() if r["error"]]
    assert rows[FAILING["case_id"]]["status"] == "error"
    assert sum(r["status"] == "ok" for r in rows.values()) == 6


def test_strength_batch_command_on_a_dask_cluster(tmp_path, capsys, dask_cluster):
    """`trunk-drake strength-batch GRID --cluster ADDRESS`, the README's command-table form."""
    from trunk_drake.cli import main

    grid = tmp_path / "grid.toml"
    grid.write_text('[grid]\ndirection = ["extension", "flexion"]\n')
    assert main(["strength-batch", str(grid), "--cluster", dask_cluster.address, "--no-progress",
                 "--out", str(tmp_path / "out")]) == 0
    assert json.loads(capsys.readouterr().out)["ok"] == 2
